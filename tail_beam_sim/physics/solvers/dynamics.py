"""The coupled equations of motion of an impact in plain Python floats.

State y = [q_1..q_n, qd_1..qd_n, z, zd] (structure coordinates, particle position and
velocity). The structure has a handful of coordinates, so scalar float arithmetic is several
times faster than numpy, whose per-call overhead dominates for arrays this small; every
stepping solver (hybrid, fixed-step) shares this one right-hand side.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from typing import Any

import numpy as np

from tail_beam_sim.physics.solvers.problem import ImpactProblem


class FloatDynamics:
    """Right-hand side and contact force of ``problem`` for list states (see module docstring).

    ``penetration(y)`` and ``derivative(y, approach_mps, peak_penetration_m)`` are functions
    written out for the structure's size (:func:`_unrolled`): every product and sum in the
    order of the plain loops, so the same floats, without their per-term interpreter work."""

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
        self.penetration, self.derivative = _unrolled(self.n)(
            self.shape,
            self.stiffness_rows,
            self.damping_rows,
            self.load,
            float(self.hertz),
            float(self.chi),
            float(self.mass_kg),
            float(self.gravity_mps2),
            None if self.crushing is None else self.crushing.force,
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

    def state(self, q: np.ndarray, qd: np.ndarray, z_m: float, zd_mps: float) -> list[float]:
        """A list state from arrays."""
        return [*map(float, q), *map(float, qd), float(z_m), float(zd_mps)]


@lru_cache(maxsize=None)
def _unrolled(n: int) -> Callable[..., tuple[Callable, Callable]]:
    """A factory of (penetration, derivative) for ``n`` structure coordinates, written out term
    by term. penetration(y) = (delta m, its rate m/s), delta = -(b . q) - z; derivative(y,
    approach, peak) = (dy/dt, contact force N) with q'' = load F - (K' q) - (C' qd) row by row
    (K' = M^-1 K, C' = M^-1 C) and z'' = F / m - g. Each dot product sums left to right as
    ``sum()`` does, whose leading 0 adds nothing, so the floats are those of the loops."""
    q = [f"q{i}" for i in range(n)]
    v = [f"v{i}" for i in range(n)]

    def dot(coefficients: list[str], values: list[str]) -> str:
        return " + ".join(f"{c} * {x}" for c, x in zip(coefficients, values)) or "0.0"

    b = [f"b{i}" for i in range(n)]
    rows = []
    for i in range(n):
        k = [f"k{i}_{j}" for j in range(n)]
        c = [f"c{i}_{j}" for j in range(n)]
        rows.append(f"l{i} * force - ({dot(k, q)}) - ({dot(c, v)})")
    constants = "\n".join(
        [f"    {', '.join(b)}, = shape" if n else ""]
        + [f"    {', '.join(f'k{i}_{j}' for j in range(n))}, = stiffness[{i}]" for i in range(n)]
        + [f"    {', '.join(f'c{i}_{j}' for j in range(n))}, = damping[{i}]" for i in range(n)]
        + ([f"    {', '.join(f'l{i}' for i in range(n))}, = load"] if n else [])
    )
    unpack = ", ".join([*q, *v, "z", "zd"])
    source = f"""
def factory(shape, stiffness, damping, load, hertz, chi, mass, g, crushing_force):
{constants}
    def penetration(y):
        {unpack}, = y
        return -({dot(b, q)}) - z, -({dot(b, v)}) - zd

    def derivative(y, approach, peak):
        {unpack}, = y
        delta = -({dot(b, q)}) - z
        if delta > 0.0:
            if crushing_force is not None:
                force = crushing_force(delta, peak)
            else:
                rate = -({dot(b, v)}) - zd
                force = hertz * delta**1.5 * (1.0 + chi * rate / approach)
                if not force > 0.0:
                    force = 0.0
        else:
            force = 0.0
        return [{", ".join([*v, *rows, "zd", "force / mass - g"])}], force

    return penetration, derivative
"""
    namespace: dict[str, Any] = {}
    exec(compile(source, f"<FloatDynamics n={n}>", "exec"), namespace)  # noqa: S102
    return namespace["factory"]


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
