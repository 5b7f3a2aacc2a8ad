"""The default solver: each short nonlinear contact on its own, exact free motion between.

A contact lasts 0.1-1 ms while the beam's modes are tens to a few thousand Hz, so almost all
the window is linear and unforced: it is propagated in closed form (eigen-decomposition).
Each contact is solved in one of two ways (option ``contact``):

* ``pulse``: the pre-integrated universal contact pulse of
:mod:`~tail_beam_sim.physics.solvers.pulse`,
  scaled to the impact, drives the structure exactly. It neglects the plate's spring and
  damping forces and gravity during the contact and estimates what that costs;
* ``rk4``: the coupled equations integrated with a fixed number of RK4 steps scaled to the
  Hertz duration of that contact, in plain floats (:mod:`~tail_beam_sim.physics.solvers.dynamics`);
  the end of contact is located inside the last step by cubic Hermite interpolation and
  reached with one partial step. Always used for the crushing contact.

``auto`` (default) takes the pulse when its own error estimate is under ``pulse_tolerance``
and integrates otherwise (large soft particles, particles settling on the plate). The next contact,
if the beam can catch the particle again at all (a bound on the
plate's speed decides), is found by scanning the gap on a grid finer than the fastest mode
and refining the root.

A contact that gains energy (the particle leaving faster, relative to the plate, than it
came) is refined with twice the steps, up to ``MAX_REFINEMENTS`` times, then refused.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from tail_beam_sim.errors import InputError, require_int
from tail_beam_sim.physics.contact import hertz_elastic_impact
from tail_beam_sim.physics.solvers.dynamics import FloatDynamics, rk4_step
from tail_beam_sim.physics.solvers.lazy import lazy
from tail_beam_sim.physics.solvers.problem import (
    ContactRecord,
    ContactSegment,
    FreeSegment,
    ImpactProblem,
    SolverError,
    Trajectory,
)
from tail_beam_sim.physics.solvers.pulse import (
    Pulse,
    contact_pulse,
    max_chi,
    parabolic_peak,
    structure_response,
)

DEFAULT_STEPS_PER_CONTACT = 48
REST_SPEED_MPS = (
    1e-4  # relative approach speed below which a particle is taken to lie on the plate
)
MAX_CONTACTS = 500
MAX_REFINEMENTS = 3
ENERGY_GAIN_TOLERANCE = (
    0.01  # relative: separation faster than approach by more than this is a failure
)
# relative error estimate (conservative) the pulse may cost before a contact is integrated
DEFAULT_PULSE_TOLERANCE = 5e-3
CONTACT_METHODS = ("auto", "pulse", "rk4")
# Relative error bound of a contact integrated by RK4: measured in test_solvers.py (Hertz with
# hysteresis, 48 steps) and test_fidelity.py (crushing, the brittle tier's 192 steps).
RK4_CONTACT_ERROR = 1e-4


def solve(
    problem: ImpactProblem,
    steps_per_contact: int = DEFAULT_STEPS_PER_CONTACT,
    contact: str = "auto",
    pulse_tolerance: float = DEFAULT_PULSE_TOLERANCE,
) -> Trajectory:
    """Solve ``problem`` over its window; see the module docstring for the methods.

    ``error_estimate``: the largest relative error estimate of the contacts taken as pulses,
    and at least RK4_CONTACT_ERROR if a contact was integrated. ``stats``: ``pulse_contacts``,
    ``rk4_contacts``, ``rk4_steps`` and ``pulse_error_estimate`` (0 if no pulse).
    """
    require_int("steps_per_contact", steps_per_contact, 4)
    if contact not in CONTACT_METHODS:
        raise InputError("contact", contact, f"must be one of {', '.join(CONTACT_METHODS)}")
    pulse_ok = problem.crushing is None and problem.damping_factor <= max_chi()
    if contact == "pulse" and not pulse_ok:
        raise SolverError(
            "hybrid",
            "contact='pulse' covers Hertz contacts with hysteresis factor <= 40 only; use "
            "contact='rk4'",
        )
    structure = problem.structure
    dynamics: FloatDynamics | None = None  # built on the first integrated contact
    b = problem.contact_shape
    g = problem.gravity_mps2
    q, qd = problem.q0.astype(float), problem.qd0.astype(float)
    z, zd = 0.0, -problem.impact_speed_mps
    segments: list[ContactSegment | PulseSegment | FreeSegment] = [
        FreeSegment(-math.inf, 0.0, 0.0, q, qd, z, zd)
    ]
    contacts: list[ContactRecord] = []
    t = 0.0
    at_rest = False
    stats = {"pulse_contacts": 0, "rk4_contacts": 0, "rk4_steps": 0, "pulse_error_estimate": 0.0}
    while True:
        segment, record, estimate = None, None, math.inf
        if pulse_ok and contact != "rk4":
            segment, record, estimate = pulse_contact(problem, t, q, qd, z, zd)
        if contact == "pulse" or estimate <= pulse_tolerance:
            stats["pulse_contacts"] += 1
            stats["pulse_error_estimate"] = max(stats["pulse_error_estimate"], estimate)
        else:
            dynamics = dynamics or FloatDynamics(problem)
            segment, record = contact_phase(
                problem, dynamics, t, dynamics.state(q, qd, z, zd), steps_per_contact
            )
            stats["rk4_contacts"] += 1
            stats["rk4_steps"] += segment.t_s.size - 1
        segments.append(segment)
        contacts.append(record)
        t = record.end_s
        modal = None
        if isinstance(segment, PulseSegment):
            q, qd, z, zd = segment.end_state
            modal = segment.end_modal
        else:
            q, qd = segment.q[:, -1].copy(), segment.qd[:, -1].copy()
            z, zd = float(segment.z_m[-1]), float(segment.zd_mps[-1])
        if problem.crushing is not None:
            z = -float(
                np.dot(b, q)
            )  # the crushed cap breaks away: the particle's new lowest point is on the surface
        separating = zd + float(np.dot(b, qd))
        if separating < REST_SPEED_MPS or len(contacts) >= MAX_CONTACTS:
            at_rest = True
            segments.append(FreeSegment(t, math.inf, t, q, qd, z, zd))
            break
        next_contact = next_contact_time(problem, t, q, qd, z, zd, modal)
        if next_contact is None:
            segments.append(FreeSegment(t, math.inf, t, q, qd, z, zd))
            break
        segments.append(FreeSegment(t, next_contact, t, q, qd, z, zd))
        dt = next_contact - t
        q, qd = structure.propagate(q, qd, dt)
        z, zd = z + zd * dt - 0.5 * g * dt * dt, zd - g * dt
        z = -float(np.dot(b, q))  # on the surface exactly at the root
        t = next_contact
    estimate = max(
        stats["pulse_error_estimate"], RK4_CONTACT_ERROR if stats["rk4_contacts"] else 0.0
    )
    return Trajectory(
        problem, segments, contacts, "hybrid", estimate, particle_at_rest=at_rest, stats=stats
    )


def pulse_contact(
    problem: ImpactProblem, t0: float, q0: np.ndarray, qd0: np.ndarray, z0: float, zd0: float
) -> tuple[PulseSegment, ContactRecord, float]:
    """One contact as the universal pulse driving the structure, with its relative error estimate.

    Only the state at the end of the contact is computed here (exactly, from the pulse's
    integral against each mode); the states through the contact wait until someone samples
    them (:class:`PulseSegment`). The estimate bounds the relative acceleration the pulse leaves
    out, gravity plus the plate's spring and damping forces, by g + sum_k |r_k| (|xi_k(0)| +
    |beta_k| J) (modes never grow), and turns it into relative errors of the separation speed
    (a T / v) and of the penetration (a T^2 / 2 delta_max).
    """
    structure = problem.structure
    b = problem.contact_shape
    n = structure.size
    eigenvalues, vectors, inverse = structure._eigen
    reduced_mass = problem.reduced_mass_kg
    approach = max(-zd0 - float(np.dot(b, qd0)), 1e-12)
    pulse = contact_pulse(problem.damping_factor, problem.hertz_stiffness, reduced_mass, approach)
    x0 = np.concatenate([q0, qd0])
    modal0 = np.dot(inverse, x0)
    beta = np.dot(structure.modal_input, b)
    duration = pulse.duration_s
    modal_end = np.exp(eigenvalues * duration) * (modal0 + beta * pulse.spectrum(eigenvalues))
    x_end = np.dot(vectors, modal_end).real
    q, qd = x_end[:n], x_end[n:]
    internal_rows = np.dot(b, structure.modal_internal)
    impulse = reduced_mass * (approach + pulse.separation_mps)
    neglected = abs(problem.gravity_mps2) + float(
        np.dot(np.abs(internal_rows), np.abs(modal0) + np.abs(beta) * impulse)
    )
    estimate = neglected * max(
        duration / approach, duration * duration / (2.0 * pulse.max_penetration_m)
    )
    t_end = t0 + duration
    segment = PulseSegment(problem, t0, x0, pulse)
    zd_end = -float(np.dot(b, qd)) + pulse.separation_mps
    record = ContactRecord(t0, t_end, approach, zd_end, pulse.peak_force_n)
    segment.end_state = (q, qd, -float(np.dot(b, q)), zd_end)
    segment.end_modal = modal_end
    return segment, record, estimate


class PulseSegment:
    """The states through a contact taken as a pulse, computed when first sampled: the same
    attributes as :class:`ContactSegment` (``t_s``, ``q``, ``qd``, ``qdd``, ``z_m``, ``zd_mps``,
    ``force_n``), from the exact response of the structure to the piecewise-linear pulse."""

    end_state: tuple[
        np.ndarray, np.ndarray, float, float
    ]  # q, qd, z (m), zd (m/s) as the contact ends
    end_modal: np.ndarray  # the same state in the structure's modal coordinates

    def __init__(self, problem: ImpactProblem, t0: float, x0: np.ndarray, pulse: Pulse) -> None:
        self.problem, self.x0, self.pulse = problem, x0, pulse
        self.start_s = t0

    @lazy
    def t_s(self) -> np.ndarray:
        return self.pulse.t_s + self.start_s

    @property
    def force_n(self) -> np.ndarray:
        return self.pulse.force_n

    @lazy
    def _states(self) -> tuple[np.ndarray, ...]:
        """The structure's q, q' and q'' at the pulse's samples."""
        structure = self.problem.structure
        n = structure.size
        load = self.problem.contact_load
        x = structure_response(structure._eigen, load, self.x0, self.t_s, self.pulse.force_n)
        q, qd = x[:n], x[n:]
        qdd = load[:, None] * self.pulse.force_n - np.dot(
            structure.inv_mass, np.dot(structure.damping, qd) + np.dot(structure.stiffness, q)
        )
        return q, qd, qdd

    @lazy
    def _particle(self) -> tuple[np.ndarray, np.ndarray]:
        """The particle's position (m) and velocity (m/s) at the pulse's samples: apart from the
        structure's, which sensors read without them."""
        b = self.problem.contact_shape
        q, qd, _ = self._states
        return -np.dot(b, q) - self.pulse.penetration_m, -np.dot(b, qd) - self.pulse.rate_mps

    q = property(lambda self: self._states[0])
    qd = property(lambda self: self._states[1])
    qdd = property(lambda self: self._states[2])
    z_m = property(lambda self: self._particle[0])
    zd_mps = property(lambda self: self._particle[1])


def contact_phase(
    problem: ImpactProblem, dynamics: FloatDynamics, t0: float, y0: list[float], steps: int
) -> tuple[ContactSegment, ContactRecord]:
    """One contact from first touch until the particle leaves, refined if it gains energy."""
    approach = max(dynamics.penetration(y0)[1], 1e-12)
    for _ in range(MAX_REFINEMENTS + 1):
        segment, record = _integrate_contact(problem, dynamics, t0, y0, steps, approach)
        if not math.isfinite(record.separation_speed_mps):
            gained = math.inf
        else:
            final = [
                float(v)
                for v in (
                    *segment.q[:, -1],
                    *segment.qd[:, -1],
                    segment.z_m[-1],
                    segment.zd_mps[-1],
                )
            ]
            gained = -dynamics.penetration(final)[1] / approach - 1.0
        if gained <= ENERGY_GAIN_TOLERANCE:
            return segment, record
        steps *= 2
    raise SolverError(
        "hybrid",
        f"contact at t = {t0:.6g} s gained energy (leaves {100 * gained:.1f} % faster than it "
        "came) even with "
        f"{steps // 2} RK4 steps: the contact law or the problem is ill-posed",
    )


def _integrate_contact(
    problem: ImpactProblem,
    dynamics: FloatDynamics,
    t0: float,
    y0: list[float],
    steps: int,
    approach: float,
) -> tuple[ContactSegment, ContactRecord]:
    """Fixed-step RK4 through one contact (``steps`` per elastic Hertz duration)."""
    n = dynamics.n
    crushing = dynamics.crushing
    duration = hertz_elastic_impact(problem.hertz_stiffness, problem.mass_kg, approach)[
        "duration_s"
    ]
    dt = duration / steps
    t_end = problem.window_s
    peak = 0.0
    offset = 0.0
    y, t = y0, t0
    k1, force = dynamics.derivative(y, approach, peak)
    times, states, derivs, forces = [t0], [y0], [k1], [force]
    for _ in range(int(math.ceil((t_end - t0) / dt)) + steps + 2):
        y_new = rk4_step(dynamics, y, dt, k1, approach, peak)
        delta_new, rate_new = dynamics.penetration(y_new)
        left = delta_new <= offset and t > t0
        if left:
            delta_old, rate_old = dynamics.penetration(y)
            theta = _crossing_fraction(
                (delta_old - offset, rate_old), (delta_new - offset, rate_new), dt
            )
            y_new = rk4_step(dynamics, y, theta * dt, k1, approach, peak)
            t_new = t + theta * dt
        else:
            t_new = t + dt
            if delta_new > peak:
                peak = delta_new
                if crushing is not None:
                    offset = crushing.unloading_curve(peak)[1]
        k1, force = dynamics.derivative(y_new, approach, peak)
        times.append(t_new)
        states.append(y_new)
        derivs.append(k1)
        forces.append(force)
        y, t = y_new, t_new
        if left or t >= t_end or not math.isfinite(delta_new):
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
        peak_force_n=parabolic_peak(np.array(forces[:-1])),
    )
    return segment, record


def _crossing_fraction(before: tuple[float, float], after: tuple[float, float], h: float) -> float:
    """Fraction of a step at which the cubic Hermite interpolant of delta reaches zero."""
    (d0, r0), (d1, r1) = before, after
    if d0 <= 0.0:
        return 1e-9

    def cubic(s: float) -> float:
        return (
            (2 * s**3 - 3 * s**2 + 1) * d0
            + (s**3 - 2 * s**2 + s) * h * r0
            + (-2 * s**3 + 3 * s**2) * d1
            + (s**3 - s**2) * h * r1
        )

    if cubic(1.0) > 0.0:
        return 1.0
    return float(brentq(cubic, 0.0, 1.0, xtol=1e-13))


def plate_speed_bound_mps(
    problem: ImpactProblem, q0: np.ndarray, qd0: np.ndarray, modal: np.ndarray | None = None
) -> float:
    """An upper bound on the plate's speed at the contact point for all later free motion, m/s.

    The free response is a sum of decaying modes, b . qd(t) = Re sum_k r_k exp(lambda_k t) xi_k,
    so sum |r_k xi_k| bounds it for all t >= 0 (``modal``: the xi of (q0, qd0), if known).
    """
    eigenvalues, vectors, inverse = problem.structure._eigen
    n = problem.structure.size
    if modal is None:
        modal = inverse @ np.concatenate([q0, qd0])
    rows = problem.contact_shape @ vectors[n:]
    return float(np.abs(rows * modal).sum())


def next_contact_time(
    problem: ImpactProblem,
    t0: float,
    q0: np.ndarray,
    qd0: np.ndarray,
    z0: float,
    zd0: float,
    modal: np.ndarray | None = None,
) -> float | None:
    """First time in (t0, window] at which the free particle meets the moving plate, or None."""
    t_end = problem.window_s
    if t0 >= t_end:
        return None
    g = problem.gravity_mps2
    # gap' >= zd0 - V - g (t - t0), so the gap stays open over the window if this holds:
    if zd0 - plate_speed_bound_mps(problem, q0, qd0, modal) > 0.5 * g * (t_end - t0):
        return None
    structure = problem.structure
    b = problem.contact_shape
    frequencies = structure.natural_frequencies_hz()
    fastest = float(frequencies.max()) if frequencies.size else 1.0
    separating = max(zd0 + float(np.dot(b, qd0)), REST_SPEED_MPS)
    # finer than the fastest mode and than the particle's own flight back to the plate (2 u / g)
    spacing = min(1.0 / (32.0 * fastest), (t_end - t0) / 8.0, separating / max(g, 1e-9))
    grid = np.linspace(t0, t_end, int(math.ceil((t_end - t0) / spacing)) + 1)

    def gap(times: np.ndarray) -> np.ndarray:
        dt = times - t0
        q, _ = structure.propagate(q0, qd0, dt)
        return z0 + zd0 * dt - 0.5 * g * dt * dt + b @ q

    values = gap(grid)
    below = np.nonzero(values[1:] <= 0.0)[0]
    if below.size == 0:
        return None
    i = int(below[0]) + 1
    low = float(grid[i - 1])
    if i == 1:
        # the gap starts at zero (to rounding): step off the surface until it is open
        low = next(
            (
                t0 + d
                for d in np.geomspace(1e-10, grid[1] - t0, 24)
                if gap(np.array([t0 + d]))[0] > 0.0
            ),
            None,
        )
        if low is None:
            return float(grid[1])
    return float(brentq(lambda s: float(gap(np.array([s]))[0]), low, float(grid[i]), xtol=1e-14))
