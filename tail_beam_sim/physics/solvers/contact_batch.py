"""The hybrid solver's RK4 contact (:func:`~tail_beam_sim.physics.solvers.hybrid.contact_phase`)
of many impacts at once, each from the structure at rest: the same steps in lockstep over the
impacts, one array operation per term instead of one float operation per impact.

Each impact keeps its own step (its elastic Hertz duration over ``steps``), leaves the plate
inside a step located by the same cubic Hermite root, and is then frozen while the others go
on. An impact that gains energy (the solver would refine it), lasts past the window or goes
non-finite is marked not ``ok``: the caller solves it one by one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tail_beam_sim.physics.solvers.hybrid import ENERGY_GAIN_TOLERANCE, _crossing_fraction
from tail_beam_sim.physics.solvers.problem import ImpactProblem
from tail_beam_sim.physics.solvers.pulse import parabolic_peak


@dataclass
class BatchContacts:
    """The contact of every impact: per impact its steps' instants (s from first contact),
    states [q, qd, z, zd] (steps, 2n + 2), derivatives (steps, 2n + 2) and forces (N), the
    approach speed (m/s), peak force (N) and whether it is ``ok``."""

    t_s: list[np.ndarray]
    states: list[np.ndarray]
    derivatives: list[np.ndarray]
    force_n: list[np.ndarray]
    approach_mps: np.ndarray
    peak_force_n: np.ndarray
    ok: np.ndarray


class _Dynamics:
    """The coupled equations of motion (``dynamics.FloatDynamics``) of many impacts on one
    structure, Hertz contact with hysteresis, arrays over impacts."""

    def __init__(self, problems: list[ImpactProblem]) -> None:
        structure = problems[0].structure
        self.n = structure.size
        self.shape = np.array([p.contact_shape for p in problems]).reshape(-1, self.n)
        self.load = self.shape @ structure.inv_mass.T
        self.stiffness_t = (structure.inv_mass @ structure.stiffness).T
        self.damping_t = (structure.inv_mass @ structure.damping).T
        self.hertz = np.array([p.hertz_stiffness for p in problems])
        self.chi = np.array([p.damping_factor for p in problems])
        self.mass = np.array([p.mass_kg for p in problems])
        self.gravity = problems[0].gravity_mps2
        # one coordinate: the shape and load as columns, stiffness and damping as numbers
        self._shape0 = np.ascontiguousarray(self.shape[:, 0])
        self._minus_shape0 = -self._shape0  # -(b y) is (-b) y, exactly
        self._load0 = np.ascontiguousarray(self.load[:, 0])
        self._stiffness0 = float(self.stiffness_t[0, 0])
        self._damping0 = float(self.damping_t[0, 0])

    def penetration(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = self.n
        if n == 1:  # one coordinate: each sum is its one product
            shape = self._minus_shape0
            return shape * y[:, 0] - y[:, 2], shape * y[:, 1] - y[:, 3]
        delta = -(self.shape * y[:, :n]).sum(axis=1) - y[:, 2 * n]
        rate = -(self.shape * y[:, n : 2 * n]).sum(axis=1) - y[:, 2 * n + 1]
        return delta, rate

    def derivative(
        self,
        y: np.ndarray,
        approach: np.ndarray,
        penetration: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(dy/dt, contact force N) at states ``y``; ``penetration``: :meth:`penetration` of
        ``y`` when already known."""
        n = self.n
        q, v = y[:, :n], y[:, n : 2 * n]
        delta, rate = penetration or self.penetration(y)
        force = self.hertz * np.maximum(delta, 0.0) ** 1.5 * (1.0 + self.chi * rate / approach)
        # zero where the plate is not penetrated (there the force is a zero or not finite) and
        # where the damping term makes it pull
        force = np.where(force > 0.0, force, 0.0)
        out = np.empty_like(y)
        out[:, :n] = v
        if n == 1:  # the products over one coordinate, element by element
            acceleration = self._load0 * force
            acceleration -= y[:, 0] * self._stiffness0
            np.subtract(acceleration, y[:, 1] * self._damping0, out=out[:, 1])
        else:
            out[:, n : 2 * n] = (
                self.load * force[:, None] - q @ self.stiffness_t - v @ self.damping_t
            )
        out[:, 2 * n] = y[:, 2 * n + 1]
        np.subtract(force / self.mass, self.gravity, out=out[:, 2 * n + 1])
        return out, force

    def step(
        self,
        y: np.ndarray,
        h: np.ndarray,
        k1: np.ndarray,
        approach: np.ndarray,
        fractions: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    ) -> np.ndarray:
        """One RK4 step of length ``h`` (per impact) from ``y`` whose derivative is ``k1``;
        ``fractions``: :func:`_fractions` of ``h`` when already known."""
        half, whole, sixth = fractions or _fractions(h)
        k2, _ = self.derivative(y + half * k1, approach)
        k3, _ = self.derivative(y + half * k2, approach)
        k4, _ = self.derivative(y + whole * k3, approach)
        return y + sixth * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def _fractions(h: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An RK4 step's h / 2, h and h / 6 as columns."""
    return (0.5 * h)[:, None], h[:, None], (h / 6.0)[:, None]


def integrate_contacts(problems: list[ImpactProblem], steps: int) -> BatchContacts:
    """The first contact of every problem (all on one structure, at rest, no crushing),
    integrated as ``hybrid._integrate_contact`` does with ``steps`` per elastic duration."""
    dynamics = _Dynamics(problems)
    n = dynamics.n
    count = len(problems)
    y = np.zeros((count, 2 * n + 2))
    y[:, 2 * n + 1] = -np.array([p.impact_speed_mps for p in problems])
    approach = np.maximum(dynamics.penetration(y)[1], 1e-12)
    # hertz_elastic_impact's duration of each impact
    delta_max = (5.0 * dynamics.mass * approach**2 / (4.0 * dynamics.hertz)) ** 0.4
    dt = 2.943195 * delta_max / approach / steps
    window = np.array([p.window_s for p in problems])
    limit = int(np.max(np.ceil(window / dt))) + steps + 2
    k1, force = dynamics.derivative(y, approach)
    t = np.zeros(count)
    times, states, derivatives, forces = [t], [y], [k1], [force]
    active = np.ones(count, dtype=bool)
    last = np.zeros(count, dtype=np.int64)
    full = _fractions(dt)
    # with every step positive, every instant is past the first contact's from the first step
    # on (a frozen impact keeps one): only the first step's test needs t > 0
    positive_steps = bool((dt > 0.0).all())
    for iteration in range(1, limit + 1):
        y_new = dynamics.step(y, dt, k1, approach, full)
        delta_new, rate_new = dynamics.penetration(y_new)
        if iteration > 1 and positive_steps:
            left = active & (delta_new <= 0.0)
        else:
            left = active & (delta_new <= 0.0) & (t > 0.0)
        t_new = t + dt
        crossed = bool(left.any())
        if crossed:
            delta_old, rate_old = dynamics.penetration(y)
            where = np.flatnonzero(left)
            theta = np.array(
                [
                    _crossing_fraction(
                        (float(delta_old[i]), float(rate_old[i])),
                        (float(delta_new[i]), float(rate_new[i])),
                        float(dt[i]),
                    )
                    for i in where
                ]
            )
            # the partial step (every impact's arithmetic is its own: the others' are dropped)
            h = dt.copy()
            h[where] = theta * dt[where]
            y_new[where] = dynamics.step(y, h, k1, approach)[where]
            t_new[where] = t[where] + h[where]
        k1_new, force_new = dynamics.derivative(
            y_new, approach, None if crossed else (delta_new, rate_new)
        )
        # impacts that left earlier keep their last state
        if not active.all():
            frozen = ~active
            y_new[frozen], t_new[frozen] = y[frozen], t[frozen]
            k1_new[frozen], force_new[frozen] = k1[frozen], force[frozen]
        times.append(t_new)
        states.append(y_new)
        derivatives.append(k1_new)
        forces.append(force_new)
        last[active] = iteration
        y, t, k1, force = y_new, t_new, k1_new, force_new
        active &= ~(left | (t >= window) | ~np.isfinite(delta_new))
        if not active.any():
            break
    all_t = np.array(times)
    all_states = np.array(states)
    all_derivatives = np.array(derivatives)
    all_forces = np.array(forces)
    final = all_states[last, np.arange(count)]
    gained = -dynamics.penetration(final)[1] / approach - 1.0
    ok = ~active & (gained <= ENERGY_GAIN_TOLERANCE) & (t < window) & np.isfinite(gained)
    out = BatchContacts([], [], [], [], approach, np.zeros(count), ok)
    for i in range(count):
        k = int(last[i]) + 1
        out.t_s.append(all_t[:k, i])
        out.states.append(all_states[:k, i])
        out.derivatives.append(all_derivatives[:k, i])
        out.force_n.append(all_forces[:k, i])
        out.peak_force_n[i] = parabolic_peak(all_forces[: k - 1, i]) if k > 1 else math.nan
    return out
