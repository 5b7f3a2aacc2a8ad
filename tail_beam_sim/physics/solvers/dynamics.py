"""The coupled equations of motion of an impact in plain Python floats.

State y = [q_1..q_n, qd_1..qd_n, z, zd] (structure coordinates, particle position and
velocity). The structure has a handful of coordinates, so scalar float arithmetic is several
times faster than numpy, whose per-call overhead dominates for arrays this small; every
stepping solver (hybrid, fixed-step) shares this one right-hand side.
"""

from __future__ import annotations

import numpy as np

from tail_beam_sim.physics.solvers.problem import ImpactProblem


class FloatDynamics:
    """Right-hand side and contact force of ``problem`` for list states (see module docstring)."""

    def __init__(self, problem: ImpactProblem) -> None:
        structure = problem.structure
        self.n = structure.size
        self.shape = [float(v) for v in problem.contact_shape]
        self.stiffness_rows = (structure.inv_mass @ structure.stiffness).tolist()
        self.damping_rows = (structure.inv_mass @ structure.damping).tolist()
        self.load = (structure.inv_mass @ problem.contact_shape).tolist()
        self.mass_kg = problem.mass_kg
        self.gravity_mps2 = problem.gravity_mps2
        self.hertz = problem.hertz_stiffness
        self.chi = problem.damping_factor
        self.crushing = problem.crushing

    def penetration(self, y: list[float]) -> tuple[float, float]:
        """Penetration (m) and its rate (m/s): delta = -(b . q) - z."""
        n, b = self.n, self.shape
        return (
            -sum(bi * qi for bi, qi in zip(b, y[:n])) - y[2 * n],
            -sum(bi * vi for bi, vi in zip(b, y[n : 2 * n])) - y[2 * n + 1],
        )

    def force(
        self, delta_m: float, rate_mps: float, approach_mps: float, peak_penetration_m: float
    ) -> float:
        """Contact force, N: Hertz with hysteresis, or the crushing law when the problem has
        one."""
        if delta_m <= 0.0:
            return 0.0
        if self.crushing is not None:
            return self.crushing.force(delta_m, peak_penetration_m)
        value = self.hertz * delta_m**1.5 * (1.0 + self.chi * rate_mps / approach_mps)
        return value if value > 0.0 else 0.0

    def derivative(
        self, y: list[float], approach_mps: float, peak_penetration_m: float
    ) -> tuple[list[float], float]:
        """(dy/dt, contact force N) at state ``y``."""
        n = self.n
        q, qd = y[:n], y[n : 2 * n]
        delta, rate = self.penetration(y)
        force = self.force(delta, rate, approach_mps, peak_penetration_m) if delta > 0.0 else 0.0
        acc = [
            li * force - sum(k * a for k, a in zip(krow, q)) - sum(c * v for c, v in zip(crow, qd))
            for li, krow, crow in zip(self.load, self.stiffness_rows, self.damping_rows)
        ]
        return [*qd, *acc, y[2 * n + 1], force / self.mass_kg - self.gravity_mps2], force

    def state(self, q: np.ndarray, qd: np.ndarray, z_m: float, zd_mps: float) -> list[float]:
        """A list state from arrays."""
        return [*map(float, q), *map(float, qd), float(z_m), float(zd_mps)]


def rk4_step(
    dynamics: FloatDynamics,
    y: list[float],
    h: float,
    k1: list[float],
    approach: float,
    peak: float,
) -> list[float]:
    """One classical RK4 step of length ``h`` from ``y``, whose derivative ``k1`` is known."""
    half = 0.5 * h
    k2, _ = dynamics.derivative([a + half * d for a, d in zip(y, k1)], approach, peak)
    k3, _ = dynamics.derivative([a + half * d for a, d in zip(y, k2)], approach, peak)
    k4, _ = dynamics.derivative([a + h * d for a, d in zip(y, k3)], approach, peak)
    sixth = h / 6.0
    return [
        a + sixth * (d1 + 2.0 * d2 + 2.0 * d3 + d4) for a, d1, d2, d3, d4 in zip(y, k1, k2, k3, k4)
    ]
