"""Normal contact between a sphere and the flat plate: Hertz stiffness and hysteresis laws.

Force for penetration ``delta_m > 0``:  F = K delta^1.5 (1 + chi * rate / v_in), never
negative, where ``v_in`` is the approach speed at the start of that contact and ``chi`` is
set by the law from the requested coefficient of restitution e.

Because F/(K delta^1.5) depends only on rate / v_in, the restitution a law delivers on a
rigid wall is a function of chi alone; :func:`delivered_restitution` computes it, and the
``calibrated`` law inverts it so that it delivers e exactly over the whole range.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import lru_cache

import numpy as np

from tail_beam_sim.errors import InputError
from tail_beam_sim.materials import Material


def effective_modulus_pa(a: Material, b: Material) -> float:
    """Contact modulus E* of two bodies, Pa: 1/E* = (1-nu1^2)/E1 + (1-nu2^2)/E2."""
    return 1.0 / ((1 - a.poisson_ratio**2) / a.youngs_modulus_pa + (1 - b.poisson_ratio**2) / b.youngs_modulus_pa)


def hertz_stiffness(particle: Material, plate: Material, radius_m: float) -> float:
    """Hertz constant K of a sphere of ``radius_m`` on a flat plate, N/m^1.5."""
    return 4.0 / 3.0 * effective_modulus_pa(particle, plate) * math.sqrt(radius_m)


def hertz_elastic_impact(stiffness: float, mass_kg: float, speed_mps: float) -> dict[str, float]:
    """Closed-form elastic Hertz impact of a mass on a rigid wall (Johnson, Contact Mechanics).

    Returns the maximum penetration (m), peak force (N) and contact duration (s).
    """
    delta_max = (5.0 * mass_kg * speed_mps**2 / (4.0 * stiffness)) ** 0.4
    # Duration = 2 delta_max / v * integral_0^1 du / sqrt(1 - u^2.5) = 2.94320 delta_max / v.
    return {
        "max_penetration_m": delta_max,
        "peak_force_n": stiffness * delta_max**1.5,
        "duration_s": 2.943195 * delta_max / speed_mps,
    }


# Published hysteresis laws: chi as a function of the requested restitution e.
_PUBLISHED_LAWS: dict[str, Callable[[float], float]] = {
    "hertz": lambda e: 0.0,
    "lankarani_nikravesh": lambda e: 3.0 * (1.0 - e * e) / 4.0,
    "hunt_crossley": lambda e: 3.0 * (1.0 - e) / 2.0,
    "flores": lambda e: 8.0 * (1.0 - e) / (5.0 * e),
    "gonthier": lambda e: (1.0 - e * e) / e,
}
CONTACT_LAWS = (*_PUBLISHED_LAWS, "calibrated")
DEFAULT_CONTACT_LAW = "calibrated"


def damping_factor(law: str, restitution: float) -> float:
    """The dimensionless hysteresis factor chi of ``law`` for restitution e."""
    if law == "calibrated":
        return calibrated_chi(restitution)
    try:
        return _PUBLISHED_LAWS[law](restitution)
    except KeyError:
        raise InputError("contact_model", law, f"must be one of {', '.join(CONTACT_LAWS)}") from None


def _dimensionless_rebound(chi: np.ndarray, steps: int = 3000, span: float = 30.0) -> np.ndarray:
    """Restitution delivered on a rigid wall for each chi, by vectorised RK4.

    Dimensionless units (m = K = v_in = 1): u'' = -max(0, u^1.5 (1 + chi u')), from u = 0,
    u' = 1 until u returns to zero (about 3.2 time units elastic, longer when over-damped).
    """
    chi = np.asarray(chi, dtype=float)
    u = np.zeros_like(chi)
    v = np.ones_like(chi)
    out = np.full_like(chi, np.nan)
    dt = span / steps
    done = np.zeros(chi.shape, dtype=bool)

    def acc(uu: np.ndarray, vv: np.ndarray) -> np.ndarray:
        up = np.maximum(uu, 0.0)
        return -np.maximum(0.0, up**1.5 * (1.0 + chi * vv))

    for _ in range(steps):
        k1u, k1v = v, acc(u, v)
        k2u, k2v = v + 0.5 * dt * k1v, acc(u + 0.5 * dt * k1u, v + 0.5 * dt * k1v)
        k3u, k3v = v + 0.5 * dt * k2v, acc(u + 0.5 * dt * k2u, v + 0.5 * dt * k2v)
        k4u, k4v = v + dt * k3v, acc(u + dt * k3u, v + dt * k3v)
        u_new = u + dt / 6.0 * (k1u + 2 * k2u + 2 * k3u + k4u)
        v_new = v + dt / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v)
        crossed = (~done) & (u_new <= 0.0) & (u > 0.0)
        # Once out of contact the motion is force-free, so the exit speed is v_new.
        out[crossed] = -v_new[crossed]
        done |= crossed
        u, v = np.where(done, u, u_new), np.where(done, v, v_new)
        if done.all():
            break
    return out


@lru_cache(maxsize=1)
def _restitution_table() -> tuple[np.ndarray, np.ndarray]:
    """Delivered restitution on a grid of chi (monotone decreasing), computed once."""
    chi = np.concatenate([np.linspace(0.0, 2.0, 101)[:-1], np.geomspace(2.0, 40.0, 60)])
    e = _dimensionless_rebound(chi)
    return chi, e


def delivered_restitution(chi: float) -> float:
    """Restitution that hysteresis factor ``chi`` delivers on a rigid wall."""
    return float(_dimensionless_rebound(np.array([chi]))[0])


def calibrated_chi(restitution: float) -> float:
    """The chi that delivers ``restitution`` exactly (table lookup, then one secant polish)."""
    if not 0.0 < restitution <= 1.0:
        raise InputError("restitution", restitution, "must be in (0, 1]")
    if restitution == 1.0:
        return 0.0
    chi_grid, e_grid = _restitution_table()
    if restitution < e_grid[-1]:
        raise InputError("restitution", restitution, f"must be >= {e_grid[-1]:.3f} for the calibrated law")
    # e_grid decreases with chi: interpolate chi against e in increasing order.
    return float(np.interp(restitution, e_grid[::-1], chi_grid[::-1]))
