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
from typing import Any

import numpy as np

from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.materials import Material, Number


def effective_modulus_pa(a: Material, b: Material) -> float:
    """Contact modulus E* of two bodies, Pa: 1/E* = (1-nu1^2)/E1 + (1-nu2^2)/E2."""
    return 1.0 / (
        (1 - a.poisson_ratio**2) / a.youngs_modulus_pa
        + (1 - b.poisson_ratio**2) / b.youngs_modulus_pa
    )


def hertz_constant(effective_modulus_pa: Number, radius_m: Number) -> Number:
    """Hertz constant K = 4/3 E* sqrt(R) of a sphere of radius R (m) on a flat, N/m^1.5
    (floats, or arrays for a batch of particles)."""
    if type(radius_m) is float:  # one particle: math's sqrt, correctly rounded as numpy's
        return 4.0 / 3.0 * effective_modulus_pa * math.sqrt(radius_m)
    root = np.sqrt(radius_m)
    return 4.0 / 3.0 * effective_modulus_pa * (float(root) if np.ndim(root) == 0 else root)


def hertz_stiffness(particle: Material, plate: Material, radius_m: float) -> float:
    """Hertz constant K of a sphere of ``radius_m`` on a flat plate, N/m^1.5."""
    return hertz_constant(effective_modulus_pa(particle, plate), radius_m)


def hertz_elastic_impact(stiffness: Any, mass_kg: Any, speed_mps: Any) -> dict[str, Any]:
    """Closed-form elastic Hertz impact of a mass on a rigid wall (Johnson, Contact Mechanics).

    Returns the maximum penetration (m), peak force (N) and contact duration (s): floats, or
    arrays when given arrays (a batch of particles).
    """
    delta_max = (5.0 * mass_kg * speed_mps**2 / (4.0 * stiffness)) ** 0.4
    # Duration = 2 delta_max / v * integral_0^1 du / sqrt(1 - u^2.5) = 2.94320 delta_max / v.
    return {
        "max_penetration_m": delta_max,
        "peak_force_n": stiffness * delta_max**1.5,
        "duration_s": 2.943195 * delta_max / speed_mps,
    }


# Published hysteresis laws: chi as a function of the requested restitution e (a float, or an
# array of them: one impact and a batch go through the same formulas).
_PUBLISHED_LAWS: dict[str, Callable[[Any], Any]] = {
    "hertz": lambda e: 0.0 * e,
    "lankarani_nikravesh": lambda e: 3.0 * (1.0 - e * e) / 4.0,
    "hunt_crossley": lambda e: 3.0 * (1.0 - e) / 2.0,
    "flores": lambda e: 8.0 * (1.0 - e) / (5.0 * e),
    "gonthier": lambda e: (1.0 - e * e) / e,
}
CONTACT_LAWS = (*_PUBLISHED_LAWS, "calibrated")
DEFAULT_CONTACT_LAW = "calibrated"


def damping_factor(law: str, restitution: Number, scale: float = 1.0) -> Number:
    """The dimensionless hysteresis factor chi of ``law`` for restitution e (a float, or an
    array of restitutions for a batch of impacts), times ``scale``: the support's
    contact_damping_scale (1 = the law as published). Every path that needs a contact's chi
    (the solvers' problem, the batch, the fidelity estimate) takes it from here."""
    if law == "calibrated":
        return calibrated_chi(restitution) * scale
    try:
        return _PUBLISHED_LAWS[law](restitution) * scale
    except KeyError:
        raise InputError(
            "contact_model", law, f"must be one of {', '.join(CONTACT_LAWS)}"
        ) from None


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


def calibrated_chi(restitution: Number) -> Number:
    """The chi that delivers ``restitution`` (a float or an array) on a rigid wall, by linear
    interpolation in the delivered-restitution table; InputError names the first value outside
    the table's range."""
    chi_grid, e_grid = _restitution_table()
    if isinstance(restitution, (float, int)) and not isinstance(restitution, bool):
        return _calibrated_chi_scalar(float(restitution))
    e = np.asarray(restitution, dtype=float)
    flat = np.atleast_1d(e)
    for outside, allowed in (
        (~((flat > 0.0) & (flat <= 1.0)), "must be in (0, 1]"),
        (flat < e_grid[-1], f"must be >= {e_grid[-1]:.3f} for the calibrated law"),
    ):
        if outside.any():
            raise InputError("restitution", float(flat[np.argmax(outside)]), allowed)
    # e_grid decreases with chi: interpolate chi against e in increasing order; e = 1 is elastic.
    chi = np.where(e == 1.0, 0.0, np.interp(e, e_grid[::-1], chi_grid[::-1]))
    return chi if e.ndim else float(chi)


@lru_cache(maxsize=4096)
def _calibrated_chi_scalar(e: float) -> float:
    """:func:`calibrated_chi` of one restitution, by the same interpolation (kept per value:
    most impacts take their material's restitution)."""
    chi_grid, e_grid = _restitution_table()
    if not 0.0 < e <= 1.0:
        raise InputError("restitution", e, "must be in (0, 1]")
    if e < e_grid[-1]:
        raise InputError("restitution", e, f"must be >= {e_grid[-1]:.3f} for the calibrated law")
    return 0.0 if e == 1.0 else float(np.interp(e, e_grid[::-1], chi_grid[::-1]))


class CrushingContact:
    """Brittle contact: Hertz until the contact pressure reaches ``crushing_pressure_pa``, then
    crushing.

    Thornton (1997, J. Appl. Mech. 64:383) elastic-perfectly-plastic sphere: Hertz loading
    F = K delta^1.5 until the peak Hertz pressure 2 E* a / (pi R) reaches the limit p_y, i.e.
    up to delta_y = R (pi p_y / 2 E*)^2; past it the pressure is capped, so the force grows
    only linearly, F = F_y + pi p_y R (delta - delta_y). Unloading is Hertzian on the flattened
    tip: F = 4/3 E* sqrt(R_p) (delta - delta_p)^1.5 with R_p = 4 E* a^3 / (3 F_max),
    a^2 = (2 F_max + F_y) / (2 pi p_y), so the crushed volume keeps the energy it absorbed and
    the particle leaves when delta falls back to delta_p. Forces in N, lengths in m.
    """

    def __init__(
        self, effective_modulus_pa: float, radius_m: float, crushing_pressure_pa: float
    ) -> None:
        self.modulus = effective_modulus_pa
        self.radius = radius_m
        self.pressure = crushing_pressure_pa
        self.stiffness = hertz_constant(effective_modulus_pa, radius_m)
        self.yield_penetration_m = (
            radius_m * (math.pi * crushing_pressure_pa / (2.0 * effective_modulus_pa)) ** 2
        )
        self.yield_force_n = self.stiffness * self.yield_penetration_m**1.5

    def loading(self, delta_m: float) -> float:
        """Force while the penetration grows past its previous maximum, N."""
        if delta_m <= self.yield_penetration_m:
            return self.stiffness * delta_m**1.5 if delta_m > 0.0 else 0.0
        return self.yield_force_n + math.pi * self.pressure * self.radius * (
            delta_m - self.yield_penetration_m
        )

    def unloading_curve(self, max_penetration_m: float) -> tuple[float, float]:
        """(4/3 E* sqrt(R_p), delta_p) of the unloading branch from ``max_penetration_m``."""
        if max_penetration_m <= self.yield_penetration_m:
            return self.stiffness, 0.0
        peak = self.loading(max_penetration_m)
        contact_radius = math.sqrt(
            (2.0 * peak + self.yield_force_n) / (2.0 * math.pi * self.pressure)
        )
        radius_p = 4.0 * self.modulus * contact_radius**3 / (3.0 * peak)
        stiffness_p = hertz_constant(self.modulus, radius_p)
        return stiffness_p, max_penetration_m - (peak / stiffness_p) ** (2.0 / 3.0)

    def force(self, delta_m: float, max_penetration_m: float) -> float:
        """Force at ``delta_m`` given the largest penetration reached so far in this contact, N."""
        if delta_m >= max_penetration_m:
            return self.loading(delta_m)
        stiffness_p, offset = self.unloading_curve(max_penetration_m)
        return stiffness_p * (delta_m - offset) ** 1.5 if delta_m > offset else 0.0

    def rebound_energy_ratio(self, impact_energy_j: float) -> float:
        """Energy given back over energy brought, on a rigid wall (closed form, no gravity):
        e^2."""
        k, dy, fy = self.stiffness, self.yield_penetration_m, self.yield_force_n
        elastic_j = 0.4 * k * dy**2.5
        if impact_energy_j <= elastic_j:
            return 1.0
        slope = math.pi * self.pressure * self.radius
        # impact energy = elastic_j + fy s + slope s^2 / 2, s = delta_max - delta_y
        s = (-fy + math.sqrt(fy * fy + 2.0 * slope * (impact_energy_j - elastic_j))) / slope
        delta_max = dy + s
        _, offset = self.unloading_curve(delta_max)
        return 0.4 * self.loading(delta_max) * (delta_max - offset) / impact_energy_j
