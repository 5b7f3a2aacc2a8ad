"""The default solver: RK4 through each short nonlinear contact, exact free motion between.

A contact lasts 0.1-1 ms while the beam's modes are tens to hundreds of Hz, so almost all the
window is linear and unforced: it is propagated in closed form (eigen-decomposition), and only
the contact is integrated, with a fixed number of RK4 steps scaled to the Hertz duration of
that contact. The end of contact is located inside the last step by cubic Hermite
interpolation and reached with one partial RK4 step; the next contact, if the beam catches the
particle again, is found by scanning the gap on a grid finer than the fastest mode and
refining the root.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from tail_beam_sim.contact import hertz_elastic_impact
from tail_beam_sim.solvers.problem import ContactRecord, ContactSegment, FreeSegment, ImpactProblem, Trajectory

DEFAULT_STEPS_PER_CONTACT = 200
REST_SPEED_MPS = 1e-4  # relative approach speed below which a particle is taken to lie on the plate
MAX_CONTACTS = 500


def solve(problem: ImpactProblem, steps_per_contact: int = DEFAULT_STEPS_PER_CONTACT) -> Trajectory:
    """Solve ``problem`` over its window; see the module docstring for the method."""
    if steps_per_contact < 4:
        raise ValueError(f"steps_per_contact = {steps_per_contact}: must be >= 4")
    structure = problem.structure
    b = problem.contact_shape
    g = problem.gravity_mps2
    q, qd = problem.q0.astype(float), problem.qd0.astype(float)
    z, zd = 0.0, -problem.impact_speed_mps
    segments: list[ContactSegment | FreeSegment] = [FreeSegment(-math.inf, 0.0, 0.0, q, qd, z, zd)]
    contacts: list[ContactRecord] = []
    t = 0.0
    at_rest = False
    rk4_steps = 0
    while True:
        segment, record = _contact_phase(problem, t, q, qd, z, zd, steps_per_contact)
        rk4_steps += segment.t_s.size - 1
        segments.append(segment)
        contacts.append(record)
        t = record.end_s
        q, qd = segment.q[:, -1].copy(), segment.qd[:, -1].copy()
        z, zd = float(segment.z_m[-1]), float(segment.zd_mps[-1])
        separating = zd + float(b @ qd)
        if separating < REST_SPEED_MPS or len(contacts) >= MAX_CONTACTS:
            at_rest = True
            segments.append(FreeSegment(t, math.inf, t, q, qd, z, zd))
            break
        next_contact = _next_contact(problem, t, q, qd, z, zd)
        if next_contact is None:
            segments.append(FreeSegment(t, math.inf, t, q, qd, z, zd))
            break
        segments.append(FreeSegment(t, next_contact, t, q, qd, z, zd))
        dt = next_contact - t
        q, qd = structure.propagate(q, qd, dt)
        z, zd = z + zd * dt - 0.5 * g * dt * dt, zd - g * dt
        z = -float(b @ q)  # on the surface exactly at the root
        t = next_contact
    return Trajectory(problem, segments, contacts, "hybrid", {"rk4_steps": rk4_steps}, at_rest)


def _contact_phase(
    problem: ImpactProblem, t0: float, q0: np.ndarray, qd0: np.ndarray, z0: float, zd0: float, steps: int
) -> tuple[ContactSegment, ContactRecord]:
    """Integrate one contact from its first touch until the penetration returns to zero."""
    structure = problem.structure
    b = problem.contact_shape
    n = structure.size
    inv_mass, damping, stiffness = structure.inv_mass, structure.damping, structure.stiffness
    mass, g, k_hertz, chi = problem.mass_kg, problem.gravity_mps2, problem.hertz_stiffness, problem.damping_factor
    approach = max(-float(b @ qd0) - zd0, 1e-12)
    duration = hertz_elastic_impact(k_hertz, mass, approach)["duration_s"]
    dt = duration / steps
    t_end = problem.window_s

    def rhs(y: np.ndarray) -> tuple[np.ndarray, float]:
        q, qd, z, zd = y[:n], y[n : 2 * n], y[2 * n], y[2 * n + 1]
        delta = -float(b @ q) - z
        force = 0.0
        if delta > 0.0:
            rate = -float(b @ qd) - zd
            force = k_hertz * delta**1.5 * (1.0 + chi * rate / approach)
            force = force if force > 0.0 else 0.0
        out = np.empty_like(y)
        out[:n] = qd
        out[n : 2 * n] = inv_mass @ (b * force - damping @ qd - stiffness @ q)
        out[2 * n] = zd
        out[2 * n + 1] = -g + force / mass
        return out, force

    def rk4(y: np.ndarray, h: float) -> np.ndarray:
        k1, _ = rhs(y)
        k2, _ = rhs(y + 0.5 * h * k1)
        k3, _ = rhs(y + 0.5 * h * k2)
        k4, _ = rhs(y + h * k3)
        return y + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)

    def penetration(y: np.ndarray) -> tuple[float, float]:
        return -float(b @ y[:n]) - y[2 * n], -float(b @ y[n : 2 * n]) - y[2 * n + 1]

    y = np.concatenate([q0, qd0, [z0, zd0]])
    times, states, derivs, forces = [t0], [y], [], []
    d0, _ = rhs(y)
    derivs.append(d0)
    forces.append(0.0)
    t = t0
    max_steps = int(1e6)
    for _ in range(max_steps):
        y_new = rk4(y, dt)
        delta_new, _ = penetration(y_new)
        if delta_new <= 0.0 and t > t0:
            theta = _crossing_fraction(penetration(y), penetration(y_new), dt)
            y_new = rk4(y, theta * dt)
            t_new = t + theta * dt
        else:
            t_new = t + dt
        deriv, force = rhs(y_new)
        times.append(t_new)
        states.append(y_new)
        derivs.append(deriv)
        forces.append(force)
        y, t = y_new, t_new
        if (delta_new <= 0.0 and t > t0) or t >= t_end + duration:
            break
    ys = np.array(states).T
    ds = np.array(derivs).T
    segment = ContactSegment(
        t_s=np.array(times),
        q=ys[:n],
        qd=ys[n : 2 * n],
        qdd=ds[n : 2 * n],
        z_m=ys[2 * n],
        zd_mps=ys[2 * n + 1],
        force_n=np.array(forces),
    )
    record = ContactRecord(
        start_s=t0,
        end_s=float(times[-1]),
        approach_speed_mps=approach,
        separation_speed_mps=float(ys[2 * n + 1, -1]),
        peak_force_n=float(np.max(forces)),
    )
    return segment, record


def _crossing_fraction(before: tuple[float, float], after: tuple[float, float], h: float) -> float:
    """Fraction of a step at which the cubic Hermite interpolant of delta reaches zero."""
    (d0, r0), (d1, r1) = before, after
    if d0 <= 0.0:
        return 1e-9

    def cubic(s: float) -> float:
        return (2 * s**3 - 3 * s**2 + 1) * d0 + (s**3 - 2 * s**2 + s) * h * r0 + (-2 * s**3 + 3 * s**2) * d1 + (s**3 - s**2) * h * r1

    if cubic(1.0) > 0.0:
        return 1.0
    return float(brentq(cubic, 0.0, 1.0, xtol=1e-13))


def _next_contact(problem: ImpactProblem, t0: float, q0: np.ndarray, qd0: np.ndarray, z0: float, zd0: float) -> float | None:
    """First time in (t0, window] at which the free particle meets the moving plate, or None."""
    t_end = problem.window_s
    if t0 >= t_end:
        return None
    structure = problem.structure
    b = problem.contact_shape
    g = problem.gravity_mps2
    frequencies = structure.natural_frequencies_hz()
    fastest = float(frequencies.max()) if frequencies.size else 1.0
    spacing = min(1.0 / (32.0 * fastest), (t_end - t0) / 8.0)
    grid = np.linspace(t0, t_end, int(math.ceil((t_end - t0) / spacing)) + 1)

    def gap(times: np.ndarray) -> np.ndarray:
        dt = times - t0
        q, _ = structure.propagate(q0, qd0, dt)
        return z0 + zd0 * dt - 0.5 * g * dt * dt + b @ q

    values = gap(grid)
    values[0] = abs(values[0]) + 1e-15
    below = np.nonzero(values[1:] <= 0.0)[0]
    if below.size == 0:
        return None
    i = int(below[0]) + 1
    return float(brentq(lambda s: float(gap(np.array([s]))[0]), grid[i - 1], grid[i], xtol=1e-14))
