"""The contact as a universal pulse: pre-integrated once, scaled to each impact, fed to the beam.

The particle is 1e-4 .. 1e-2 of the beam's effective mass at the contact point, so during the
0.1-1 ms contact the plate moves like a free mass: the relative penetration delta then obeys
mu delta'' = -K delta^1.5 (1 + chi delta' / v), mu = m m_eff / (m + m_eff), whose solution is
one dimensionless curve per hysteresis factor chi, scaled by the length (mu v^2 / K)^(2/5), the
time length / v and the force K length^1.5. :func:`pulse_table` integrates those curves once
for a grid of chi (vectorised RK4, then again with each row's own step so that the samples fall
on the same fractions of each row's duration); :func:`contact_pulse` blends the two rows around
a chi and returns the force history, and :func:`structure_response` drives the linear
structure with it exactly (piecewise-linear force, modal closed form). What this neglects, the
plate's own spring and damping forces and gravity on the particle during the contact, is
returned as an error estimate so that a caller can fall back to integrating the contact.
"""

from __future__ import annotations

import cmath
import math
from bisect import bisect_right
from contextvars import ContextVar
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.special import factorial

from tail_beam_sim.physics.solvers.lazy import lazy

PULSE_NODES = 64  # samples per contact: enough for cubic Hermite sampling to 1e-6 of the peak
SUBSTEPS = 8  # RK4 steps between samples in the second pass
FIRST_PASS_STEP = (
    0.02  # dimensionless RK4 step of the first pass (duration ~3.2 units elastic; 2e-6 relative)
)
MAX_SPAN = 40.0  # dimensionless time limit of the first pass (chi = 40 lasts about 25 units)
MOMENTS = 64  # moments of each pulse kept for its spectrum's power series
# |lambda T| up to which the series is used (largest term ~2e4, last ~1e-20: about 1e-11 relative)
SERIES_RADIUS = 12.0


@dataclass(frozen=True)
class PulseTable:
    """Dimensionless contact pulses on a grid of chi. ``rows[i]`` holds, at the fractions
    ``fractions`` of row i's duration, the penetration u, its rate u' and the force
    f = u^1.5 (1 + chi u') (shape (chi, 3, PULSE_NODES + 1)); per row also the duration, the
    delivered restitution, the peak force and the largest sampled penetration."""

    chi: np.ndarray
    duration: np.ndarray
    restitution: np.ndarray
    rows: np.ndarray
    fractions: np.ndarray
    peak_force: np.ndarray
    peak_penetration: np.ndarray
    moments: np.ndarray


def _rk4_rows(
    chi: np.ndarray, u: np.ndarray, v: np.ndarray, dt: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray]:
    """One RK4 step of u'' = -max(0, u^1.5 (1 + chi u')) for every row."""

    def acc(uu: np.ndarray, vv: np.ndarray) -> np.ndarray:
        return -np.maximum(0.0, np.maximum(uu, 0.0) ** 1.5 * (1.0 + chi * vv))

    k1u, k1v = v, acc(u, v)
    k2u, k2v = v + 0.5 * dt * k1v, acc(u + 0.5 * dt * k1u, v + 0.5 * dt * k1v)
    k3u, k3v = v + 0.5 * dt * k2v, acc(u + 0.5 * dt * k2u, v + 0.5 * dt * k2v)
    k4u, k4v = v + dt * k3v, acc(u + dt * k3u, v + dt * k3v)
    return u + dt / 6.0 * (k1u + 2 * k2u + 2 * k3u + k4u), v + dt / 6.0 * (
        k1v + 2 * k2v + 2 * k3v + k4v
    )


@lru_cache(maxsize=1)
def pulse_table() -> PulseTable:
    """Integrate the dimensionless pulses (about 0.3 s, once per process)."""
    chi = np.concatenate([np.linspace(0.0, 2.0, 201)[:-1], np.geomspace(2.0, 40.0, 121)])
    # Pass 1: each row's duration, the zero of u located by cubic Hermite inside the last step.
    u, v = np.zeros_like(chi), np.ones_like(chi)
    duration = np.full_like(chi, np.nan)
    t = 0.0
    h = FIRST_PASS_STEP
    while t < MAX_SPAN and np.isnan(duration).any():
        u_new, v_new = _rk4_rows(chi, u, v, h)
        crossed = np.isnan(duration) & (u_new <= 0.0) & (t > 0.0)
        for i in np.nonzero(crossed)[0]:
            duration[i] = t + h * _hermite_zero(u[i], v[i], u_new[i], v_new[i], h)
        u, v, t = u_new, v_new, t + h
    keep = ~np.isnan(duration)
    chi, duration = chi[keep], duration[keep]
    # Pass 2: each row with its own step, so that sample j lands at j / PULSE_NODES of its
    # duration.
    step = duration / (PULSE_NODES * SUBSTEPS)
    u, v = np.zeros_like(chi), np.ones_like(chi)
    us, vs = [u], [v]
    for _ in range(PULSE_NODES):
        for _ in range(SUBSTEPS):
            u, v = _rk4_rows(chi, u, v, step)
        us.append(u)
        vs.append(v)
    u_nodes, v_nodes = np.array(us).T, np.array(vs).T
    u_nodes[:, -1] = 0.0  # the end of contact, by construction
    force = np.maximum(0.0, np.maximum(u_nodes, 0.0) ** 1.5 * (1.0 + chi[:, None] * v_nodes))
    rows = np.stack([u_nodes, v_nodes, force], axis=1)
    fractions = np.linspace(0.0, 1.0, PULSE_NODES + 1)
    peaks = np.array([parabolic_peak(row) for row in force])
    return PulseTable(
        chi,
        duration,
        -v_nodes[:, -1],
        rows,
        fractions,
        peaks,
        u_nodes.max(axis=1),
        _moments(force, fractions) / factorial(np.arange(MOMENTS)),
    )


def _moments(force: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """int_0^1 f(s) s^m ds, m < MOMENTS, of the piecewise-linear interpolant of each row
    (exact)."""
    a, b = fractions[:-1], fractions[1:]
    h = b - a
    m = np.arange(MOMENTS)[:, None]
    first = (b ** (m + 1) - a ** (m + 1)) / (m + 1)
    second = (b ** (m + 2) - a ** (m + 2)) / (m + 2)
    return (
        force[:, :-1] @ ((b * first - second) / h).T + force[:, 1:] @ ((second - a * first) / h).T
    )


def _hermite_zero(u0: float, v0: float, u1: float, v1: float, h: float) -> float:
    """Fraction of a step where the cubic Hermite interpolant of u falls to zero (bisection)."""
    low, high = 0.0, 1.0
    for _ in range(50):
        s = 0.5 * (low + high)
        value = (
            (2 * s**3 - 3 * s**2 + 1) * u0
            + (s**3 - 2 * s**2 + s) * h * v0
            + (-2 * s**3 + 3 * s**2) * u1
            + (s**3 - s**2) * h * v1
        )
        low, high = (s, high) if value > 0.0 else (low, s)
    return 0.5 * (low + high)


@lru_cache(maxsize=1)
def max_chi() -> float:
    """The largest hysteresis factor the table covers."""
    return float(pulse_table().chi[-1])


_POWERS = np.arange(MOMENTS)


class Pulse:
    """A contact pulse in physical units, blended from the table rows ``row`` and ``row + 1``
    with weight ``weight``: its scalars at once (duration s, relative separation speed m/s, peak
    force N, refined between samples by a parabola, largest penetration m) and its samples on
    demand (times from contact start s, relative penetration m and its rate m/s, force N)."""

    def __init__(
        self, row: int, weight: float, length_m: float, approach_mps: float, hertz_stiffness: float
    ) -> None:
        table = pulse_table()
        self.row, self.weight = row, weight
        self.length_m, self.approach_mps = length_m, approach_mps
        self.force_scale_n = hertz_stiffness * length_m**1.5
        self.duration_s = self._blend(table.duration) * length_m / approach_mps
        self.separation_mps = approach_mps * self._blend(table.restitution)
        self.peak_force_n = self.force_scale_n * self._blend(table.peak_force)
        self.max_penetration_m = length_m * self._blend(table.peak_penetration)

    def _blend(self, values: np.ndarray) -> float:
        return (1 - self.weight) * float(values[self.row]) + self.weight * float(
            values[self.row + 1]
        )

    @lazy
    def _blended(self) -> np.ndarray:
        """The two table rows blended (3, samples): penetration, its rate and the force, each
        row as a blend of its own alone would be, dimensionless."""
        rows = pulse_table().rows
        return (1 - self.weight) * rows[self.row] + self.weight * rows[self.row + 1]

    def spectrum(self, eigenvalues: np.ndarray) -> np.ndarray:
        """int_0^T F(s) e^{-lambda_k s} ds per eigenvalue, N s: a power series in lambda T over the
        pulse's moments while |lambda T| <= SERIES_RADIUS, the quadrature beyond; both exact for
        the piecewise-linear pulse, as :func:`structure_response` is."""
        mu = eigenvalues * self.duration_s
        if np.abs(mu).max() > SERIES_RADIUS:
            return pulse_integral(eigenvalues, self.t_s, self.force_n)
        moments = (1 - self.weight) * pulse_table().moments[
            self.row
        ] + self.weight * pulse_table().moments[self.row + 1]
        return (np.power.outer(-mu, _POWERS) @ moments) * (self.force_scale_n * self.duration_s)

    @lazy
    def t_s(self) -> np.ndarray:
        return pulse_table().fractions * self.duration_s

    @lazy
    def centroid_s(self) -> float:
        """Force-weighted mean time of the pulse, s."""
        return float(np.dot(self.force_n, self.t_s)) / self._force_total

    @lazy
    def width_s(self) -> float:
        """Force-weighted RMS spread of the pulse about its centroid, s."""
        return math.sqrt(
            float(np.dot(self.force_n, (self.t_s - self.centroid_s) ** 2)) / self._force_total
        )

    @lazy
    def _force_total(self) -> float:
        """The sum of the force samples, N (the centroid's and the width's denominator)."""
        return float(self.force_n.sum())

    @lazy
    def force_n(self) -> np.ndarray:
        return self._blended[2] * self.force_scale_n

    @lazy
    def penetration_m(self) -> np.ndarray:
        return self._blended[0] * self.length_m

    @lazy
    def rate_mps(self) -> np.ndarray:
        return self._blended[1] * self.approach_mps


# The pulses made within :func:`shared_pulses`, by their arguments (None outside it).
_SHARED: ContextVar[dict[tuple[float, float, float, float], Pulse] | None] = ContextVar(
    "shared_pulses", default=None
)


class shared_pulses:  # noqa: N801 - used as a function: ``with shared_pulses():``
    """Within it, :func:`contact_pulse` asked again with the same arguments (one impact's
    plan and its solver) returns the same pulse, its samples computed once; forgotten on
    exit, so that nothing outlives the call that made it. (A class rather than a generator
    context manager: entered once per simulated impact, where the generator's machinery
    costs more than the pulse lookups it serves.)"""

    __slots__ = ("_token",)

    def __enter__(self) -> None:
        self._token = _SHARED.set({})

    def __exit__(self, *_: object) -> None:
        _SHARED.reset(self._token)


def contact_pulse(
    chi: float, hertz_stiffness: float, reduced_mass_kg: float, approach_mps: float
) -> Pulse:
    """The pulse of a contact with hysteresis ``chi`` (blend of the two nearest table rows);
    within :func:`shared_pulses`, one per distinct set of arguments (a pulse is only read)."""
    shared = _SHARED.get()
    if shared is None:
        return _contact_pulse(chi, hertz_stiffness, reduced_mass_kg, approach_mps)
    key = (chi, hertz_stiffness, reduced_mass_kg, approach_mps)
    pulse = shared.get(key)
    if pulse is None:
        pulse = shared[key] = _contact_pulse(*key)
    return pulse


def _contact_pulse(
    chi: float, hertz_stiffness: float, reduced_mass_kg: float, approach_mps: float
) -> Pulse:
    table = pulse_table()
    i = min(max(bisect_right(_chi_list(), chi) - 1, 0), table.chi.size - 2)
    lo, hi = float(table.chi[i]), float(table.chi[i + 1])
    length = (reduced_mass_kg * approach_mps**2 / hertz_stiffness) ** 0.4
    return Pulse(i, (chi - lo) / (hi - lo), length, approach_mps, hertz_stiffness)


@lru_cache(maxsize=1)
def _chi_list() -> list[float]:
    return pulse_table().chi.tolist()


def parabolic_peak(values: np.ndarray) -> float:
    """Peak of a smooth sampled curve: the parabola through the largest sample and its
    neighbours."""
    k = int(values.argmax())
    if k == 0 or k == values.size - 1:
        return float(values[k])
    left, mid, right = float(values[k - 1]), float(values[k]), float(values[k + 1])
    curvature = left - 2 * mid + right
    return mid - (right - left) ** 2 / (8 * curvature) if curvature < 0 else mid


def _segment_weights(lam_h: complex, h: float) -> tuple[complex, complex]:
    """(phi_a, phi_b): int_0^h e^{lam (h-s)} (1 - s/h) ds and the same with s/h (series near 0)."""
    if abs(lam_h) < 1e-2:
        total = h * (1 + lam_h / 2 + lam_h**2 / 6 + lam_h**3 / 24)
        phi_b = h * (0.5 + lam_h / 6 + lam_h**2 / 24 + lam_h**3 / 120)
    else:
        grown = cmath.exp(lam_h) - 1.0
        total = h * grown / lam_h
        phi_b = h * (grown - lam_h) / lam_h**2
    return total - phi_b, phi_b


def pulse_integral(eigenvalues: np.ndarray, t_s: np.ndarray, force_n: np.ndarray) -> np.ndarray:
    """int_0^T F(s) e^{-lambda_k s} ds per eigenvalue, F piecewise linear on uniform ``t_s``
    from 0 (exact, the same quadrature as :func:`structure_response`)."""
    h = float(t_s[1] - t_s[0])
    # on [t_j, t_j + h]: e^{-lam t_j} (F_j int e^{-lam u}(1 - u/h) du + F_{j+1} int e^{-lam u} u/h
    # du)
    weights = np.array([_segment_weights(-complex(lam) * h, h) for lam in eigenvalues])
    decay = np.exp(np.outer(-eigenvalues, t_s[:-1]))
    return decay @ force_n[1:] * weights[:, 0] + decay @ force_n[:-1] * weights[:, 1]


def structure_response(
    eigen: tuple[np.ndarray, np.ndarray, np.ndarray],
    load: np.ndarray,
    x0: np.ndarray,
    t_s: np.ndarray,
    force_n: np.ndarray,
) -> np.ndarray:
    """States x = [q, qd] (2n, T) of x' = A x + [0; load] F at uniformly spaced ``t_s`` from x0,
    with F piecewise linear between the samples: exact, in the eigen-basis of A."""
    eigenvalues, vectors, inverse = eigen
    n = load.size
    h = float(t_s[1] - t_s[0])
    weights = np.array([_segment_weights(complex(lam) * h, h) for lam in eigenvalues.tolist()]).T
    beta = np.dot(inverse[:, n:], load)
    increments = (beta * weights[0])[:, None] * force_n[:-1] + (beta * weights[1])[
        :, None
    ] * force_n[1:]
    growth = np.exp(eigenvalues[:, None] * (t_s - t_s[0]))
    modal = growth * np.dot(inverse, x0)[:, None]
    modal[:, 1:] += growth[:, 1:] * np.cumsum(increments / growth[:, 1:], axis=1)
    return np.dot(vectors, modal).real
