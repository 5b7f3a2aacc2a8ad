"""scipy's adaptive integrators (RK45, DOP853, Radau, BDF, LSODA) over the whole window.

The motion alternates between contact and free flight; each phase is one ``solve_ivp`` call
that ends on an event (penetration falling to zero ends a contact, rising through zero starts
one), so no integrator steps across the kink of the contact force. The implicit methods get
the analytic Jacobian. Tolerances: ``rtol`` and, per state, ``atol = rtol * scale`` with the
scale of each state from the impulse of an elastic impact (so every state is controlled
relative to its own size). Every step is kept for cubic Hermite sampling; each contact's peak
force is read from the integrator's dense output.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from tail_beam_sim.errors import InputError, require_range
from tail_beam_sim.physics.contact import hertz_elastic_impact
from tail_beam_sim.physics.solvers.dynamics import FloatDynamics
from tail_beam_sim.physics.solvers.problem import (
    ContactRecord,
    ContactSegment,
    FreeSegment,
    ImpactProblem,
    OdeSegment,
    SolverError,
    Trajectory,
)
from tail_beam_sim.physics.solvers.pulse import parabolic_peak

METHODS = ("RK45", "DOP853", "Radau", "BDF", "LSODA")
IMPLICIT = ("Radau", "BDF", "LSODA")
PEAK_SAMPLES = 400  # dense-output samples per contact to read its peak force
MAX_PHASES = 1000


def solve(problem: ImpactProblem, method: str = "Radau", rtol: float = 1e-8) -> Trajectory:
    """Integrate ``problem`` with ``scipy.integrate.solve_ivp(method=...)`` (module docstring)."""
    if method not in METHODS:
        raise InputError("method", method, f"must be one of {', '.join(METHODS)}")
    rtol = require_range("rtol", rtol, 1e-14, 1e-1)
    if problem.crushing is not None:
        raise SolverError(
            method,
            "the crushing contact depends on its history: use hybrid or a fixed-step solver",
        )
    dynamics = FloatDynamics(problem)
    n = dynamics.n
    approach0 = problem.impact_speed_mps - float(problem.contact_shape @ problem.qd0)
    atol = rtol * _state_scale(problem, approach0)
    window = problem.window_s
    y = np.concatenate([problem.q0, problem.qd0, [0.0, -problem.impact_speed_mps]]).astype(float)
    segments: list[ContactSegment | FreeSegment | OdeSegment] = [
        FreeSegment(-math.inf, 0.0, 0.0, y[:n].copy(), y[n : 2 * n].copy(), 0.0, y[-1])
    ]
    contacts: list[ContactRecord] = []
    t, in_contact = 0.0, True
    evaluations = 0
    for _ in range(MAX_PHASES):
        if t >= window:
            break
        approach = max(dynamics.penetration(y.tolist())[1], 1e-12) if in_contact else 1.0

        def rhs(_t: float, state: np.ndarray, approach: float = approach) -> np.ndarray:
            return np.array(dynamics.derivative(state.tolist(), approach, 0.0)[0])

        def jacobian(_t: float, state: np.ndarray, approach: float = approach) -> np.ndarray:
            return _jacobian(problem, dynamics, state, approach)

        def boundary(_t: float, state: np.ndarray) -> float:
            return dynamics.penetration(state.tolist())[0]

        boundary.terminal = True  # type: ignore[attr-defined]
        boundary.direction = -1.0 if in_contact else 1.0  # type: ignore[attr-defined]
        options = {"jac": jacobian} if method in IMPLICIT else {}
        first = (
            hertz_elastic_impact(problem.hertz_stiffness, problem.mass_kg, max(approach0, 1e-3))[
                "duration_s"
            ]
            / 100
        )
        sol = solve_ivp(
            rhs,
            (t, window),
            y,
            method=method,
            rtol=rtol,
            atol=atol,
            events=boundary,
            dense_output=True,
            first_step=first if in_contact else None,
            **options,
        )
        if sol.status < 0:
            raise SolverError(method, f"solve_ivp failed at t = {sol.t[-1]:.6g} s: {sol.message}")
        evaluations += sol.nfev
        times, states = sol.t, sol.y
        if sol.t_events[0].size:
            times = np.append(times[times < sol.t_events[0][0]], sol.t_events[0][0])
            states = np.column_stack([states[:, : times.size - 1], sol.y_events[0][0]])
        if in_contact:
            segment = _segment(dynamics, times, states, approach)
            dense = sol.sol(np.linspace(times[0], times[-1], PEAK_SAMPLES))
            peak = parabolic_peak(
                np.array(
                    [dynamics.derivative(list(column), approach, 0.0)[1] for column in dense.T]
                )
            )
            contacts.append(
                ContactRecord(
                    t,
                    float(times[-1]),
                    approach,
                    float(states[-1, -1]),
                    max(peak, float(segment.force_n.max())),
                )
            )
            segments.append(segment)
        else:
            segments.append(OdeSegment(times, sol.sol))
        t, y = float(times[-1]), states[:, -1].copy()
        if not sol.t_events[0].size:
            break
        in_contact = not in_contact
    else:
        raise SolverError(
            method, f"more than {MAX_PHASES} contact phases: the particle chatters on the plate"
        )
    q, qd = y[:n], y[n : 2 * n]
    # Beyond the window the beam rings freely and the particle flies (or rests, if still in
    # contact).
    segments.append(FreeSegment(t, math.inf, t, q, qd, float(y[-2]), float(y[-1])))
    # The integrator holds each step's local error within rtol (atol scaled to each state's size).
    return Trajectory(
        problem,
        segments,
        contacts,
        method,
        rtol,
        particle_at_rest=in_contact and t >= window,
        stats={"rhs_evaluations": evaluations, "rtol": rtol},
    )


def _segment(
    dynamics: FloatDynamics, times: np.ndarray, states: np.ndarray, approach: float
) -> ContactSegment:
    """A dense segment from integrator steps, with the accelerations and forces at each."""
    n = dynamics.n
    derivatives, forces = zip(
        *(dynamics.derivative(list(column), approach, 0.0) for column in states.T)
    )
    accel = np.array(derivatives).T
    return ContactSegment(
        t_s=times,
        q=states[:n],
        qd=states[n : 2 * n],
        qdd=accel[n : 2 * n],
        z_m=states[2 * n],
        zd_mps=states[2 * n + 1],
        force_n=np.array(forces),
    )


def _state_scale(problem: ImpactProblem, approach: float) -> np.ndarray:
    """Typical size of each state over an impact: an elastic impulse's beam response, the
    contact."""
    structure = problem.structure
    impulse = 2.0 * problem.mass_kg * approach
    velocity = np.abs(structure.inv_mass @ problem.contact_shape) * impulse
    slowest = max(float(structure.natural_frequencies_hz().min(initial=1.0)), 1e-3) * 2 * math.pi
    penetration = hertz_elastic_impact(
        problem.hertz_stiffness, problem.mass_kg, max(approach, 1e-3)
    )["max_penetration_m"]
    return np.concatenate(
        [velocity / slowest + 1e-300, velocity + 1e-300, [penetration, approach]]
    )


def _jacobian(
    problem: ImpactProblem, dynamics: FloatDynamics, state: np.ndarray, approach: float
) -> np.ndarray:
    """d(dy/dt)/dy of the contact equations (Hertz with hysteresis)."""
    n = dynamics.n
    structure = problem.structure
    b = problem.contact_shape
    jac = np.zeros((2 * n + 2, 2 * n + 2))
    jac[:n, n : 2 * n] = np.eye(n)
    jac[n : 2 * n, :n] = -structure.inv_mass @ structure.stiffness
    jac[n : 2 * n, n : 2 * n] = -structure.inv_mass @ structure.damping
    jac[2 * n, 2 * n + 1] = 1.0
    delta, rate = dynamics.penetration(state.tolist())
    if delta > 0.0:
        factor = 1.0 + problem.damping_factor * rate / approach
        if factor > 0.0:
            d_delta = 1.5 * problem.hertz_stiffness * math.sqrt(delta) * factor
            d_rate = problem.hertz_stiffness * delta**1.5 * problem.damping_factor / approach
            grad = np.concatenate([-d_delta * b, -d_rate * b, [-d_delta, -d_rate]])
            response = np.concatenate([structure.inv_mass @ b, [1.0 / problem.mass_kg]])
            jac[n : 2 * n] += np.outer(response[:n], grad)
            jac[2 * n + 1] += response[n] * grad
    return jac
