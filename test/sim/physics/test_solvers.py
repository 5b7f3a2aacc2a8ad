"""Every solver against a converged reference, and the pieces of the fast hybrid against
independent calculations (closed-form Hertz, a separate restitution integration, scipy on
the linear structure)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

from tail_beam_sim.config import deep_merge, load_parameters
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.benchmark import errors, measure
from tail_beam_sim.physics.contact import delivered_restitution
from tail_beam_sim.physics.fidelity import TIERS, shipped_settings, structure_for
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.simulate import build_problem
from tail_beam_sim.physics.solvers import SOLVERS, SolverError, solve
from tail_beam_sim.physics.solvers.hybrid import RK4_CONTACT_ERROR
from tail_beam_sim.physics.solvers.pulse import pulse_table, structure_response

IMU_RATE_HZ = 2000.0


def _problem(params, tier: str = "rigid", **overrides):
    scene = Scene.from_params(params, overrides)
    structure = structure_for(TIERS[tier], scene.support, shipped_settings().modes)
    return build_problem(
        scene.support, scene.impact, scene.contact_model, scene.window_s, structure=structure
    )


@pytest.fixture(scope="module")
def rigid_reference(params):
    """Radau at rtol 1e-10, converged: the same at 1e-9 agrees to better than 1e-6 (refinement
    check)."""
    problem = _problem(params)
    reference = measure(solve(problem, "Radau", rtol=1e-10), IMU_RATE_HZ)
    coarser = measure(solve(problem, "Radau", rtol=1e-9), IMU_RATE_HZ)
    assert max(errors(coarser, reference).values()) < 1e-6
    return problem, reference


# (solver, options, bound on the relative error of rebound, peak force, peak pressure, IMU
# waveform)
CASES = [
    ("hybrid", {}, 1e-3),
    ("hybrid", {"contact": "rk4"}, RK4_CONTACT_ERROR),
    ("impulse", {}, 1e-3),
    ("RK45", {"rtol": 1e-8}, 1e-5),
    ("DOP853", {"rtol": 1e-8}, 1e-5),
    ("LSODA", {"rtol": 1e-8}, 1e-5),
    ("BDF", {"rtol": 1e-8}, 1e-5),
    ("rk4", {"dt_s": 1e-5}, 5e-3),
    ("verlet", {"dt_s": 1e-5}, 3e-2),
]


@pytest.mark.parametrize(
    "name, options, bound",
    CASES,
    ids=[f"{c[0]}-{'-'.join(map(str, c[1].values()))}" for c in CASES],
)
def test_solver_agrees_with_converged_reference(rigid_reference, name, options, bound):
    """Each solver's rebound, peak force, peak pressure and IMU waveform are within its stated
    bound of converged Radau, with one contact."""
    problem, reference = rigid_reference
    trajectory = solve(problem, name, **options)
    measured = errors(measure(trajectory, IMU_RATE_HZ), reference)
    assert max(measured.values()) < bound, measured
    assert len(trajectory.contacts) == 1


def test_default_solver_meets_the_issue_targets_on_accuracy(rigid_reference):
    """Within 1 % of the converged reference on rebound and peak jack pressure change (the
    speed target is shown by `tail-beam bench`, never asserted on time)."""
    problem, reference = rigid_reference
    measured = errors(measure(solve(problem), IMU_RATE_HZ), reference)
    assert measured["rebound"] < 0.01 and measured["peak_pressure"] < 0.01


def test_pulse_contact_matches_integrated_contact_with_bending_modes(params):
    """The pulse (decoupled contact, exact structure) against RK4 through the coupled contact,
    with the 2.2 kHz mode ringing during it: they agree within the pulse's own error estimate,
    which is therefore not optimistic."""
    problem = _problem(params, "modal")
    pulse = solve(problem, "hybrid", contact="pulse")
    integrated = solve(problem, "hybrid", contact="rk4", steps_per_contact=192)
    estimate = pulse.stats["pulse_error_estimate"]
    assert 0 < estimate < 0.01
    rebound_error = abs(pulse.rebound_velocity_mps / integrated.rebound_velocity_mps - 1)
    assert rebound_error < estimate
    times = np.linspace(0.0, problem.window_s, 2001)
    a, b = pulse.sample(times), integrated.sample(times)
    assert np.linalg.norm(a.qd - b.qd) / np.linalg.norm(b.qd) < estimate


def test_hybrid_rk4_contact_converges_and_says_how_fast(params):
    """Halving RK4's step through the contact cuts the rebound error by more than 2^1.5. Not by
    2^4: the Hertz force ~ delta^1.5 has an unbounded second derivative where contact starts
    and ends, which lowers the observed order (measured about 1.9) below the method's four."""
    problem = _problem(params)
    fine = solve(problem, "hybrid", contact="rk4", steps_per_contact=800).rebound_velocity_mps
    coarse, finer = (
        abs(
            solve(problem, "hybrid", contact="rk4", steps_per_contact=s).rebound_velocity_mps
            - fine
        )
        for s in (16, 32)
    )
    assert coarse / finer > 2**1.5


def test_pulse_table_elastic_row_is_the_closed_form_hertz_impact():
    """chi = 0: rebound = impact speed; in units m = K = v = 1, delta* = (5/4)^(2/5),
    F* = delta*^1.5, duration = 2 delta* int_0^1 du / sqrt(1 - u^2.5) (Johnson 11.2)."""
    table = pulse_table()
    assert table.chi[0] == 0.0
    delta_star = 1.25**0.4
    integral, _ = quad(lambda u: 1.0 / math.sqrt(1.0 - u**2.5), 0.0, 1.0)
    assert table.restitution[0] == pytest.approx(1.0, abs=1e-6)
    assert table.duration[0] == pytest.approx(2 * delta_star * integral, rel=1e-5)
    assert table.peak_force[0] == pytest.approx(delta_star**1.5, rel=1e-5)
    assert table.rows[0, 0].max() == pytest.approx(
        delta_star, rel=1e-3
    )  # sampled at 1/64 of the duration


@pytest.mark.parametrize("chi", [0.1, 0.7, 3.0, 15.0])
def test_pulse_table_restitution_matches_the_contact_modules_integration(chi):
    """Two separate integrations of the same dimensionless contact (contact.py's and the
    table's)."""
    table = pulse_table()
    i = int(np.argmin(np.abs(table.chi - chi)))
    assert table.restitution[i] == pytest.approx(
        delivered_restitution(float(table.chi[i])), abs=2e-4
    )


def test_structure_response_is_exact_for_a_piecewise_linear_force(params):
    """The modal closed form against scipy's DOP853 at rtol 1e-12 on the linear structure."""
    scene = Scene.from_params(params)
    structure = structure_for(TIERS["modal"], scene.support, shipped_settings().modes)
    load = structure.inv_mass @ structure.contact_shape(1.0)
    times = np.linspace(0.0, 3e-4, 65)
    force = 1e4 * np.sin(np.pi * times / times[-1])
    x0 = np.concatenate([np.zeros(structure.size), 1e-3 * np.ones(structure.size)])
    exact = structure_response(structure._eigen, load, x0, times, force)
    n = structure.size

    def rhs(t, x):
        f = np.interp(t, times, force)
        return np.concatenate(
            [
                x[n:],
                structure.inv_mass
                @ (
                    structure.contact_shape(1.0) * f
                    - structure.damping @ x[n:]
                    - structure.stiffness @ x[:n]
                ),
            ]
        )

    reference = solve_ivp(
        rhs,
        (0, times[-1]),
        x0,
        t_eval=times,
        method="DOP853",
        rtol=1e-12,
        atol=1e-18,
        max_step=times[1],
    ).y
    assert np.max(np.abs(exact - reference)) < 1e-7 * np.max(np.abs(reference))


def test_trajectory_is_continuous_and_defined_everywhere(params):
    """Sampling before, through, after the contact and beyond the window, for each solver
    family."""
    problem = _problem(params)
    for name, options in (
        ("hybrid", {}),
        ("impulse", {}),
        ("LSODA", {"rtol": 1e-8}),
        ("rk4", {"dt_s": 1e-5}),
    ):
        trajectory = solve(problem, name, **options)
        times = np.linspace(-0.01, 0.2, 4001)
        state = trajectory.sample(times)
        assert np.all(np.isfinite(state.q)) and np.all(np.isfinite(state.zd_mps))
        boundaries = [c.end_s for c in trajectory.contacts] + [problem.window_s]
        for t in boundaries:
            left, right = trajectory.sample(np.array([t - 1e-9, t + 1e-9])).q[0]
            assert abs(left - right) < 1e-6 * np.max(np.abs(state.q[0])), (name, t)


def test_unknown_solver_and_bad_options_name_the_field(params):
    """An unknown solver, an option out of range or one the solver does not take is an
    InputError naming it (bad input, not a failed solve)."""
    problem = _problem(params)
    with pytest.raises(InputError, match="solver = 'nope'"):
        solve(problem, "nope")
    with pytest.raises(InputError, match="rtol"):
        solve(problem, "Radau", rtol=2.0)
    with pytest.raises(InputError, match="not all accepted by RK45"):
        solve(problem, "RK45", dt_s=1e-6)
    with pytest.raises(InputError, match="steps_per_contact"):
        solve(problem, "hybrid", steps_per_contact=2)
    assert {
        "hybrid",
        "impulse",
        "euler",
        "verlet",
        "rk4",
        "RK45",
        "DOP853",
        "Radau",
        "BDF",
        "LSODA",
    } <= set(SOLVERS)


def test_scipy_methods_refuse_the_history_dependent_crushing_contact(params):
    """scipy's methods refuse the crushing contact (its force depends on the peak so far) with a
    SolverError saying why."""
    from tail_beam_sim.physics.simulate import crushing_contact

    scene = Scene.from_params(deep_merge(load_parameters(), {}))
    crushing = crushing_contact(scene.support, scene.impact, 3.0)
    problem = build_problem(
        scene.support, scene.impact, scene.contact_model, scene.window_s, crushing=crushing
    )
    with pytest.raises(SolverError, match="crushing"):
        solve(problem, "Radau")
