"""Stability where methods fail, and the extremes a user will hit.

Explicit steps beyond the contact's stability limit gain energy; the simulator refuses them
before integrating and refuses a result that gained energy after. The default solver is
checked against a Radau reference at the extremes: microsecond contacts, a particle as heavy
as part of the beam, impacts at the hinge and the tip, a few-millimetre drop and a chain of
re-contacts. Every tier agrees with the next one up where the scene says the lower suffices.
"""

from __future__ import annotations

import numpy as np
import pytest

from tail_beam_sim.physics.batch import ImpactBatch, contacts
from tail_beam_sim.physics.contact import damping_factor
from tail_beam_sim.physics.fidelity import TIERS, Needs, plan, shipped_settings, structure_for
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.simulate import build_problem, simulate
from tail_beam_sim.physics.solvers import SolverError, fixed_step, solve


def _problem(params, **overrides):
    scene = Scene.from_params(params, overrides)
    return build_problem(scene.support, scene.impact, scene.contact_model, scene.window_s)


@pytest.mark.parametrize("method", ["euler", "verlet", "rk4"])
def test_explicit_step_beyond_the_stability_limit_fails_and_is_refused(params, method):
    """At 1.5 times the limit the unguarded integrator returns nonsense: velocity Verlet a rebound
    several times faster than the impact (energy from nowhere), RK4 a particle passing through
    the plate, semi-implicit Euler six times the peak force and a tenth of the rebound. Guarded,
    the step is refused with a message naming dt_s, the limit and what to do."""
    problem = _problem(params)
    truth = solve(problem, "hybrid").rebound_velocity_mps
    limit = fixed_step.stability_limit_s(problem, method)
    assert 5e-5 < limit < 5e-4  # set by the contact: omega_c = sqrt(1.5 K delta_max^0.5 / m)
    wild = solve(problem, method, dt_s=1.5 * limit, guard=False)
    rebound = wild.contacts[0].separation_speed_mps
    assert not np.isfinite(rebound) or abs(rebound - truth) > 0.5 * truth
    if method == "verlet":
        assert rebound > problem.impact_speed_mps
    with pytest.raises(SolverError, match=r"dt_s = .*beyond the stability limit.*use dt_s <="):
        solve(problem, method, dt_s=1.5 * limit)


def test_result_that_gained_energy_is_refused_even_when_the_step_looked_stable(
    params, monkeypatch
):
    """With the a-priori check fooled, the a-posteriori check still refuses the diverged result."""
    problem = _problem(params)
    limit = fixed_step.stability_limit_s(problem, "verlet")
    monkeypatch.setattr(fixed_step, "stability_limit_s", lambda *_: np.inf)
    with pytest.raises(SolverError, match="gained energy|ran away|finite"):
        solve(problem, "verlet", dt_s=1.5 * limit)


def test_lankarani_nikravesh_error_grows_as_restitution_falls_while_the_default_law_holds(params):
    """The requested e against what each law delivers, over 0.3-0.9 (vectorised pulse table, a
    different path from the lead's single-impact test): L-N's error grows monotonically as e
    falls and passes 40 % at e = 0.3; the calibrated law stays within 0.1 %."""
    scene = Scene.from_params(params)
    requested = np.linspace(0.3, 0.9, 13)
    n = requested.size
    batch = ImpactBatch.from_arrays(
        scene.support,
        scene.materials,
        ["coal"] * n,
        np.full(n, 0.025),
        np.full(n, 8.0),
        np.full(n, 1.0),
        requested,
    )
    structure = structure_for(TIERS["rigid"], scene.support, ())
    errors = {}
    for law in ("lankarani_nikravesh", "calibrated"):
        delivered = contacts(structure, batch, law).relative_restitution
        errors[law] = (delivered - requested) / requested
    ln = errors["lankarani_nikravesh"]
    assert np.all(np.diff(ln) < 0) and ln[0] > 0.4 and ln[-1] < 0.03
    assert np.max(np.abs(errors["calibrated"])) < 1e-3
    assert np.all(
        damping_factor("calibrated", requested) > damping_factor("lankarani_nikravesh", requested)
    )


EXTREMES = {
    "tiny stiff particle, contact of a few microseconds": {
        "material": "marble",
        "radius_m": 0.001,
        "impact_speed_mps": 8.0,
    },
    "large soft particle, 150 kg of coal": {
        "material": "coal",
        "radius_m": 0.3,
        "impact_speed_mps": 3.0,
    },
    "at the hinge, where the beam barely moves": {"position_m": 0.02},
    "at the tip": {"position_m": 1.6},
    "a drop of 3 mm": {"drop_height_m": 0.003},
}


@pytest.mark.parametrize("overrides", EXTREMES.values(), ids=EXTREMES.keys())
def test_default_solver_at_the_extremes_agrees_with_radau(params, overrides):
    """At the extremes of size, position and drop, the hybrid's contacts match Radau's in
    number, rebound, peak force and duration."""
    problem = _problem(params, **overrides)
    hybrid = solve(problem)
    reference = solve(problem, "Radau", rtol=1e-9)
    assert len(hybrid.contacts) == len(reference.contacts)
    for mine, theirs in zip(hybrid.contacts, reference.contacts):
        assert mine.separation_speed_mps == pytest.approx(
            theirs.separation_speed_mps, rel=1e-3, abs=1e-4
        )
        assert mine.peak_force_n == pytest.approx(theirs.peak_force_n, rel=2e-3)
        assert mine.duration_s == pytest.approx(theirs.duration_s, rel=2e-3)
    if overrides.get("radius_m") == 0.001:
        assert hybrid.contacts[0].duration_s < 1e-5
    if overrides.get("radius_m") == 0.3:
        assert hybrid.stats["rk4_contacts"] == 1  # too heavy for the pulse: integrated instead


def test_chain_of_re_contacts_until_the_particle_settles(params):
    """Half a millimetre near the tip (the floor for commands, 1 mm, lowered here): the particle
    bounces seven times and comes to rest on the plate; every contact's start and speeds agree with
    Radau."""
    tiny = {
        **params,
        "support": {**params["support"], "drop_height_min_m": 1e-4},
    }  # below the commands' 1 mm floor
    problem = _problem(tiny, drop_height_m=0.0005, position_m=1.5)
    hybrid = solve(problem)
    reference = solve(problem, "Radau", rtol=1e-9)
    assert len(hybrid.contacts) == len(reference.contacts) >= 5
    assert hybrid.particle_at_rest and reference.particle_at_rest
    for mine, theirs in zip(hybrid.contacts, reference.contacts):
        assert mine.start_s == pytest.approx(theirs.start_s, abs=2e-6)
        assert mine.approach_speed_mps == pytest.approx(
            theirs.approach_speed_mps, rel=2e-3, abs=2e-4
        )


SCENES = [
    {},
    {"material": "marble"},
    {"drop_height_m": 0.003},
    {"radius_m": 0.05, "position_m": 0.5},
    {"radius_m": 0.05, "position_m": 1.2, "impact_speed_mps": 8.368},
]
NEEDS = [
    Needs.of(["rebound"], 0.01),
    Needs.of(["rebound", "contact"], 0.005),
    Needs.of(["pressure"], 0.05),
    Needs.of(["pressure", "rebound"], 0.05),
]


@pytest.mark.parametrize("overrides", SCENES, ids=[str(s) for s in SCENES])
def test_every_tier_agrees_with_the_next_one_up_where_the_scene_says_it_suffices(
    params, overrides
):
    """For each scene and each statement of needs, the automatic tier's results differ from the
    next tier up by no more than the tolerance, on every output the scene asked for."""
    scene = Scene.from_params(params, overrides)
    settings = shipped_settings()
    checked = 0
    for needs in NEEDS:
        chosen = plan(scene, "auto", needs, settings)
        if chosen.tier.name == "modal":
            continue
        summary = simulate(scene, tier="auto", needs=needs, settings=settings, check=True).summary
        differences = {k: v for k, v in summary["check"].items() if k != "against"}
        assert max(differences.values()) <= needs.tolerance, (chosen.tier.name, needs, differences)
        assert summary["error_estimate"] <= needs.tolerance
        checked += 1
    assert checked >= 2
