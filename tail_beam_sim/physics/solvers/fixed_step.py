"""Fixed-step explicit integrators over the whole window: semi-implicit Euler, velocity Verlet,
RK4.

The naive way to simulate an impact, kept as the baseline the other solvers are charted
against: one step size ``dt_s`` for the 0.1-1 ms contact and the 50 ms of ringing alike. A
contact starts and ends between steps (times interpolated linearly). Explicit steps have a
stability limit set by the stiffest thing they meet, the Hertz contact near its peak
(omega_c = sqrt(1.5 K delta_max^0.5 / m)) or the fastest bending mode: a step beyond
``STABILITY_BOUNDS[method] / omega`` is refused before integrating, and a result that gained
energy in a contact, ran away or stopped being finite is refused after (``guard=False`` skips
both checks, to show what happens without them).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from tail_beam_sim.errors import InputError, require_range
from tail_beam_sim.physics.contact import hertz_elastic_impact
from tail_beam_sim.physics.solvers.dynamics import FloatDynamics, rk4_step
from tail_beam_sim.physics.solvers.problem import (
    ContactRecord,
    ContactSegment,
    FreeSegment,
    ImpactProblem,
    SolverError,
    Trajectory,
)

# omega * dt bound of linear stability on an undamped oscillator (imaginary-axis reach).
STABILITY_BOUNDS = {"euler": 2.0, "verlet": 2.0, "rk4": 2.0 * math.sqrt(2.0)}
ENERGY_GAIN_TOLERANCE = (
    0.01  # relative separation speed above the approach speed that counts as a failure
)
RUNAWAY_FACTOR = 10.0  # penetration beyond this many elastic Hertz maxima counts as running away
MAX_STEPS = 5_000_000

Stepper = Callable[[FloatDynamics, list, float, float, float], list]


def stability_limit_s(problem: ImpactProblem, method: str) -> float:
    """Largest stable step of ``method`` for this impact, s (contact near its peak, fastest
    mode)."""
    approach = problem.impact_speed_mps - float(problem.contact_shape @ problem.qd0)
    delta_max = hertz_elastic_impact(
        problem.hertz_stiffness, problem.mass_kg, max(approach, 1e-3)
    )["max_penetration_m"]
    omega_contact = math.sqrt(
        1.5 * problem.hertz_stiffness * math.sqrt(delta_max) / problem.mass_kg
    )
    frequencies = problem.structure.natural_frequencies_hz()
    omega_structure = 2 * math.pi * float(frequencies.max()) if frequencies.size else 0.0
    return STABILITY_BOUNDS[method] / max(omega_contact, omega_structure)


def _euler(dyn: FloatDynamics, y: list, h: float, approach: float, peak: float) -> list:
    """Semi-implicit (symplectic) Euler: velocities first, positions with the new velocities."""
    n = dyn.n
    d, _ = dyn.derivative(y, approach, peak)
    vel = [v + h * a for v, a in zip(y[n : 2 * n], d[n : 2 * n])]
    zd = y[2 * n + 1] + h * d[2 * n + 1]
    return [x + h * v for x, v in zip(y[:n], vel)] + vel + [y[2 * n] + h * zd, zd]


def _verlet(dyn: FloatDynamics, y: list, h: float, approach: float, peak: float) -> list:
    """Velocity Verlet; the velocity-dependent force takes the half-step velocity."""
    n = dyn.n
    d, _ = dyn.derivative(y, approach, peak)
    half = [v + 0.5 * h * a for v, a in zip(y[n : 2 * n], d[n : 2 * n])] + [
        y[2 * n + 1] + 0.5 * h * d[2 * n + 1]
    ]
    pos = [x + h * v for x, v in zip(y[:n], half[:n])] + [y[2 * n] + h * half[n]]
    d_new, _ = dyn.derivative(pos[:n] + half[:n] + pos[n:] + half[n:], approach, peak)
    vel = [v + 0.5 * h * a for v, a in zip(half[:n], d_new[n : 2 * n])] + [
        half[n] + 0.5 * h * d_new[2 * n + 1]
    ]
    return pos[:n] + vel[:n] + [pos[n], vel[n]]


def _rk4(dyn: FloatDynamics, y: list, h: float, approach: float, peak: float) -> list:
    """Classical fourth-order Runge-Kutta."""
    return rk4_step(dyn, y, h, dyn.derivative(y, approach, peak)[0], approach, peak)


STEPPERS: dict[str, Stepper] = {"euler": _euler, "verlet": _verlet, "rk4": _rk4}


def solve(
    problem: ImpactProblem, method: str = "rk4", dt_s: float = 1e-6, guard: bool = True
) -> Trajectory:
    """Integrate the whole window with ``method`` ('euler', 'verlet', 'rk4') at step ``dt_s``."""
    if method not in STEPPERS:
        raise InputError("method", method, f"must be one of {', '.join(STEPPERS)}")
    dt_s = require_range("dt_s", dt_s, 0.0, problem.window_s, low_open=True, unit="s")
    steps = int(math.ceil(problem.window_s / dt_s - 1e-9))
    if steps > MAX_STEPS:
        raise InputError(
            "dt_s",
            dt_s,
            f"needs {steps} steps; at most {MAX_STEPS} (use a larger step or the hybrid)",
        )
    if guard:
        limit = stability_limit_s(problem, method)
        if dt_s > limit:
            raise SolverError(
                method,
                f"dt_s = {dt_s!r} is beyond the stability limit of {method} for this impact "
                f"({limit:.3g} s, set by the contact stiffness "
                f"or the fastest mode): use dt_s <= {0.5 * limit:.3g} s, or the hybrid solver",
            )
    step = STEPPERS[method]
    dyn = FloatDynamics(problem)
    n = dyn.n
    y = dyn.state(problem.q0, problem.qd0, 0.0, -problem.impact_speed_mps)
    approach = max(dyn.penetration(y)[1], 1e-12)
    peak = offset = 0.0
    crushing = dyn.crushing
    states, forces, derivs = [y], [], []
    contacts: list[ContactRecord] = []
    start, in_contact, contact_peak_force = 0.0, True, 0.0
    for k in range(steps):
        y_new = step(dyn, y, dt_s, approach, peak)
        delta_old, rate_old = dyn.penetration(y)
        delta, rate = dyn.penetration(y_new)
        t_new = (k + 1) * dt_s
        if in_contact:
            peak = max(peak, delta)
            if crushing is not None:
                offset = crushing.unloading_curve(peak)[1]
            if delta <= offset:
                frac = _fraction(delta_old - offset, delta - offset)
                zd_end = y[2 * n + 1] + frac * (y_new[2 * n + 1] - y[2 * n + 1])
                contacts.append(
                    ContactRecord(
                        start, t_new - (1 - frac) * dt_s, approach, zd_end, contact_peak_force
                    )
                )
                y_new[2 * n] += (
                    offset  # a crushed cap breaks away: the particle's lowest point moves up
                )
                in_contact, peak, offset, contact_peak_force = False, 0.0, 0.0, 0.0
        elif delta > 0.0:
            frac = _fraction(-delta_old, -delta)
            start = t_new - (1 - frac) * dt_s
            approach = max(rate_old + frac * (rate - rate_old), 1e-12)
            in_contact = True
        d, force = dyn.derivative(y_new, approach, peak)
        contact_peak_force = max(contact_peak_force, force)
        states.append(y_new)
        forces.append(force)
        derivs.append(d)
        y = y_new
        if not math.isfinite(delta):
            break
    if in_contact:
        contacts.append(
            ContactRecord(start, problem.window_s, approach, y[2 * n + 1], contact_peak_force)
        )
    d0, f0 = dyn.derivative(states[0], max(dyn.penetration(states[0])[1], 1e-12), 0.0)
    ys = np.array(states).T
    ds = np.array([d0, *derivs]).T
    times = np.arange(ys.shape[1]) * dt_s
    segment = ContactSegment(
        times,
        ys[:n],
        ys[n : 2 * n],
        ds[n : 2 * n],
        ys[2 * n],
        ys[2 * n + 1],
        np.array([f0, *forces]),
    )
    if guard:
        _check(problem, method, dt_s, segment, contacts)
    t_last = float(times[-1])
    segments = [
        FreeSegment(-math.inf, 0.0, 0.0, problem.q0, problem.qd0, 0.0, -problem.impact_speed_mps),
        segment,
        FreeSegment(
            t_last,
            math.inf,
            t_last,
            ys[:n, -1],
            ys[n : 2 * n, -1],
            float(ys[2 * n, -1]),
            float(ys[2 * n + 1, -1]),
        ),
    ]
    # No error control, so no estimate (nan): a guess from the step size would be just that.
    stats = {"steps": len(states) - 1, "dt_s": dt_s}
    return Trajectory(
        problem, segments, contacts, method, math.nan, particle_at_rest=in_contact, stats=stats
    )


def _fraction(before: float, after: float) -> float:
    """Where, as a fraction of the step, a quantity going from ``before`` > 0 to ``after`` <= 0
    crosses zero."""
    return before / (before - after) if before > after else 1.0


def _check(
    problem: ImpactProblem,
    method: str,
    dt_s: float,
    segment: ContactSegment,
    contacts: list[ContactRecord],
) -> None:
    """Refuse a result that is not finite, ran away or gained energy in a contact."""
    advice = f"use a smaller dt_s than {dt_s:g} s, or the hybrid solver"
    if not (np.all(np.isfinite(segment.q)) and np.all(np.isfinite(segment.zd_mps))):
        raise SolverError(method, f"the state stopped being finite (diverged): {advice}")
    elastic = hertz_elastic_impact(
        problem.hertz_stiffness, problem.mass_kg, max(problem.impact_speed_mps, 1e-3)
    )["max_penetration_m"]
    penetration = -(problem.contact_shape @ segment.q) - segment.z_m
    if penetration.max() > RUNAWAY_FACTOR * elastic:
        raise SolverError(
            method,
            f"penetration ran away to {penetration.max():.3g} m ({RUNAWAY_FACTOR:g} x the Hertz "
            f"maximum): {advice}",
        )
    for contact in contacts:
        k = min(int(round(contact.end_s / dt_s)), segment.t_s.size - 1)
        separation = contact.separation_speed_mps + float(problem.contact_shape @ segment.qd[:, k])
        if separation > contact.approach_speed_mps * (1 + ENERGY_GAIN_TOLERANCE):
            raise SolverError(
                method,
                f"the contact at t = {contact.start_s:.4g} s gained energy (leaves at "
                f"{separation:.3f} m/s, came at "
                f"{contact.approach_speed_mps:.3f} m/s): {advice}",
            )
