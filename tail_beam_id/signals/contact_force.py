"""The contact force's shape, read from the accelerometer pulse through the support's ringing,
and the contact's duration read where that force ends.

Why: the best half-sine (:mod:`tail_beam_id.signals.contact_fit`) matches the pulse's main lobe,
and a hysteretic contact's force is no half-sine: it rises sharply and tails off for longer
than it rose, the more so the less the particle rebounds. Where the contact lasts as long as
half a period of a bending mode, or a mode sits inside the pulse's band, the mode's response
overlaps the pulse, and how much shorter than the contact the best half-sine comes out depends
on the support. A fit over the forces a Hertz contact with hysteresis can make tells the end of
the force wherever the modes lie.

How: a sphere on a stiff plate with the force K d^n (1 + chi d'/v0) moves, in time and
penetration scaled by the contact's own scales, as d'' = -d^n (1 + chi d') from d = 0, d' = 1:
one force shape per exponent n (1.5 Hertz's sphere, 1 a linear contact: a plate that gives way
under a heavy particle) and hysteresis factor chi (chi 0 a symmetric pulse, chi 8 one that
peaks within a third of its span and tails off), whatever the law (each law is a chi) and the
particle (its mass, stiffness and speed set the scales). Each shape is tabulated once
(:func:`pulse_shapes`), its time scaled so that the force lasts one unit above ``END_FRACTION``
of its peak. For every candidate (shape, duration, start), the acceleration is fitted by least
squares with the force itself (the rigid beam's and the modes' instantaneous share), the force
convolved with each ringing pole read from the ring-down (exactly, the force being piecewise
linear between samples: a recursion per pole, :func:`pole_responses`) and a quadratic for the
beam's sway. A coarse grid of every shape, then every shape refined about its own best (the
fit is sharp in all three: a shape a grid step off its duration explains less than a wrong
shape aligned by chance); the candidate with the least residual gives the duration (the force
above ``END_FRACTION`` of its peak), the start, the rise to the peak, the shape; the residual,
in units of the channel's noise and as a share of the pulse's power, says how well the model
held.

Numpy / scipy only, every candidate of a grid solved at once; test/bench/bench_contact_readout.py
times it against the half-sine fit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

END_FRACTION = 0.05  # the force "ends" when it falls below this fraction of its peak
# Hertz's exponent and the hysteresis factors of the shapes tried. 1.5: a sphere's contact, chi
# the laws' for restitution 0.1-1 (Lankarani-Nikravesh 0-0.75, Hunt-Crossley 0-1.35, Gonthier
# 0-9.9, Flores 0-14) within the range that changes the force above END_FRACTION (beyond chi 8
# it barely changes). 1: a linear contact (chi 0 a half-sine), the shape of a contact whose
# plate gives way under the particle (a heavy particle on a compliant beam).
SHAPES = tuple(
    (1.5, chi) for chi in (0.0, 0.15, 0.3, 0.5, 0.7, 0.95, 1.2, 1.6, 2.0, 2.6, 3.2, 5.0, 8.0)
) + tuple((1.0, chi) for chi in (0.0, 0.3, 0.7, 1.2, 2.0, 3.2))
SHAPE_STEPS = 4000  # samples of each tabulated shape over its whole contact
DURATION_FACTORS = (0.8, 4.0)  # coarse durations: this range x the half-sine's (log grid)
COARSE_DURATIONS = 10
START_STEPS = np.array([-0.5, 0.5])  # coarse starts: the half-sine's + these x the period
REFINE_DURATIONS = np.linspace(-0.5, 0.5, 3)  # refined: the best's x exp(these x coarse step)
REFINE_STARTS = np.array([-1.0, 0.0, 1.0]) / 3.0  # ... and + these x the period


@dataclass(frozen=True)
class ForceReading:
    """The best force shape: how long it stays above END_FRACTION of its peak (s), when it
    starts (s after the onset; the contact's first touch), how soon after that it peaks (s),
    its hysteresis factor chi (the shape: 0 symmetric, larger peaks sooner and tails off), and
    the RMS of what the fit leaves unexplained over the channel's noise RMS (about 1: the
    model held)."""

    duration_s: float
    start_s: float
    rise_s: float
    exponent: float
    chi: float
    residual_noise_ratio: float
    half_sine_s: float  # the half-sine that matches this force best on a rigid support, s
    unexplained: float  # the share of the pulse's power (the sway taken out) the fit leaves


@dataclass(frozen=True)
class PulseShape:
    """One tabulated force shape: force (peak 1) at times in units of its span above
    END_FRACTION of the peak, from first touch (0) to the force's end."""

    exponent: float
    chi: float
    times: np.ndarray
    force: np.ndarray
    peak_time: float  # when it peaks, same units
    lead: float  # from first touch to END_FRACTION of the peak, same units
    half_sine: float  # the duration of the half-sine that matches it best, same units


@lru_cache(maxsize=1)
def pulse_shapes() -> tuple[PulseShape, ...]:
    """The force shapes of SHAPES (module docstring), by fourth-order Runge-Kutta on the
    dimensionless contact d'' = -d^n (1 + chi d'), once per process."""
    return tuple(_shape(exponent, chi) for exponent, chi in SHAPES)


def _shape(exponent: float, chi: float) -> PulseShape:
    """One shape of :func:`pulse_shapes`."""
    # scipy's integrators and filters are imported where used: a process that never reads the
    # force (the force read-out off, the caving node) need not pay for importing them.
    from scipy.integrate import solve_ivp

    def rhs(_: float, s: np.ndarray) -> list[float]:
        d, v = s
        return [v, -max(max(d, 0.0) ** exponent * (1.0 + chi * v), 0.0)]

    def leaves(_: float, s: np.ndarray) -> float:
        return s[0] + 1e-12

    leaves.terminal, leaves.direction = True, -1  # type: ignore[attr-defined]
    solution = solve_ivp(
        rhs, (0.0, 40.0), [1e-12, 1.0], dense_output=True, rtol=1e-9, atol=1e-12, events=leaves
    )
    t = np.linspace(0.0, float(solution.t[-1]), SHAPE_STEPS)
    d, v = solution.sol(t)
    f = np.clip(np.clip(d, 0.0, None) ** exponent * (1.0 + chi * v), 0.0, None)
    f /= f.max()
    above = np.flatnonzero(f >= END_FRACTION)
    t = t / (t[above[-1]] - t[above[0]])
    # The half-sine (duration w, start s) with the largest normalised correlation.
    grid = np.linspace(0.0, t[-1], 400)
    shape = np.interp(grid, t, f)
    w = np.linspace(0.2, 1.5, 131)[:, None, None]
    since = grid[None, None, :] - np.linspace(0.0, 0.3, 16)[None, :, None]
    inside = (since >= 0) & (since <= w)
    sine = np.where(inside, np.sin(np.pi * np.clip(since, 0.0, None) / w), 0.0)
    match = (sine * shape).sum(axis=-1) / np.sqrt((sine * sine).sum(axis=-1) + 1e-300)
    half_sine = float(w.ravel()[np.unravel_index(np.argmax(match), match.shape)[0]])
    return PulseShape(exponent, chi, t, f, float(t[np.argmax(f)]), float(t[above[0]]), half_sine)


def pole_responses(forces: np.ndarray, poles: np.ndarray, period_s: float) -> np.ndarray:
    """The convolution of each row of ``forces`` (piecewise linear between nodes a sample
    apart) with exp(p t) for each pole, at the nodes, exactly: (rows, 2 x poles, nodes), the
    real parts then the imaginary ones. Over one sample a node's value enters as E1 and the one
    before as E0 - E1, and what came before decays by z = exp(p T): the filter
    (E1 + (E0 - E1) q^-1) / (1 - z q^-1), run as two real second-order filters (its numerator
    and denominator times 1 - conj(z) q^-1; ten times faster than a complex one)."""
    from scipy.signal import lfilter

    out = np.empty((forces.shape[0], 2 * poles.size, forces.shape[1]))
    for k, pole in enumerate(poles):
        pole = complex(pole)
        z = complex(np.exp(pole * period_s))
        e0 = (z - 1.0) / pole
        e1 = (z - 1.0 - pole * period_s) / (pole * pole * period_s)
        numerator = np.array([e1, (e0 - e1) - e1 * z.conjugate(), -(e0 - e1) * z.conjugate()])
        denominator = [1.0, -2.0 * z.real, abs(z) ** 2]
        out[:, k] = lfilter(numerator.real, denominator, forces, axis=-1)
        out[:, poles.size + k] = lfilter(numerator.imag, denominator, forces, axis=-1)
    return out


def explained(basis: np.ndarray, y: np.ndarray, sway: np.ndarray) -> np.ndarray:
    """For each candidate basis (C x rows x N), the share of ``y``'s power (y orthogonal to
    ``sway``, N x 3 orthonormal) that a least-squares fit with the basis and the sway explains
    (y' P y). With y orthogonal to the sway, taking the sway out of each column changes its Gram
    matrix by -(Q'B)'(Q'B) and leaves B'y as it is (cheaper than projecting every column); then
    each column scaled to unit norm, for the conditioning (a column all but inside the sway's
    span is floored at 1e-12 of its own norm, so that rounding never scales it to infinity)."""
    count, rows, n = basis.shape
    on_sway = (basis.reshape(-1, n) @ sway).reshape(count, rows, sway.shape[1])
    products = basis @ basis.transpose(0, 2, 1)
    gram = products - on_sway @ on_sway.transpose(0, 2, 1)
    norm = np.maximum(np.einsum("cii->ci", gram), 1e-12 * np.einsum("cii->ci", products)) + 1e-300
    scale = 1.0 / np.sqrt(norm)
    gram = gram * scale[:, :, None] * scale[:, None, :] + 1e-9 * np.eye(rows)
    projected = (basis @ y) * scale
    coefficients = np.linalg.solve(gram, projected[..., None])[..., 0]
    score = np.einsum("ck,ck->c", coefficients, projected)
    return np.where(np.isfinite(score), score, -np.inf)


def _scores(
    index: np.ndarray,
    y: np.ndarray,
    sway: np.ndarray,
    poles: np.ndarray,
    period_s: float,
    node_t: np.ndarray,
    shape: np.ndarray,
    duration_s: np.ndarray,
    start_s: np.ndarray,
) -> np.ndarray:
    """The explained power of each candidate (shape number, duration s, start s: arrays)
    with the force at the nodes ``node_t`` (s) and its responses to ``poles`` (1/s)."""
    shapes = pulse_shapes()
    forces = np.zeros((shape.size, node_t.size))
    for k in np.unique(shape):
        mine = shape == k
        s = shapes[int(k)]
        forces[mine] = np.interp(
            (node_t[None, :] - start_s[mine, None]) / duration_s[mine, None],
            s.times,
            s.force,
            left=0.0,
            right=0.0,
        )
    basis = np.concatenate([forces[:, None], pole_responses(forces, poles, period_s)], axis=1)
    if index.size < node_t.size:  # samples left out (clipped, lost): their rows go
        basis = basis[:, :, index]
    return explained(basis, y, sway)


def read_force(
    t_s: np.ndarray,
    y: np.ndarray,
    sway: np.ndarray,
    poles: np.ndarray,
    period_s: float,
    start_s: float,
    duration_s: float,
    noise: float,
    max_duration_s: float,
) -> ForceReading | None:
    """The best force shape behind ``y`` (acceleration at ``t_s``, s after the onset, sampled
    every ``period_s`` with gaps allowed; the sway ``sway`` (N x 3 orthonormal) already taken
    out) given the ringing ``poles`` (1/s) and the best half-sine (``start_s``, ``duration_s``)
    to search around; durations no longer than ``max_duration_s``. ``noise``: the channel's
    noise RMS (units of y). None when nothing was tried (a window of fewer than 8 samples)."""
    if t_s.size < 8:
        return None
    index = np.rint((t_s - t_s[0]) / period_s).astype(int)
    nodes = int(index[-1]) + 1
    node_t = t_s[0] + np.arange(nodes) * period_s
    shapes = pulse_shapes()
    ratio = math.log(DURATION_FACTORS[1] / DURATION_FACTORS[0]) / (COARSE_DURATIONS - 1)

    # Every shape, duration and start of the coarse grid; then every shape once more about its
    # own best, durations half a coarse step and starts a third of a sample apart. The fit is
    # sharp in all three (a shape a coarse step off its duration or half a sample off its start
    # explains less than a wrong shape aligned by chance), so every shape is refined, not only
    # the coarse winner.
    low, high = (duration_s * f for f in DURATION_FACTORS)
    high = max(min(high, max_duration_s), low)
    durations = np.exp(np.linspace(math.log(low), math.log(high), COARSE_DURATIONS))
    count = len(shapes)
    grid = np.meshgrid(
        np.arange(count), durations, start_s + START_STEPS * period_s, indexing="ij"
    )
    shape, duration, start = (g.reshape(count, -1) for g in grid)
    scores = _scores(
        index, y, sway, poles, period_s, node_t, shape.ravel(), duration.ravel(), start.ravel()
    ).reshape(count, -1)
    rows = np.arange(count)
    best = np.argmax(scores, axis=1)
    grid = np.meshgrid(rows, REFINE_DURATIONS * ratio, REFINE_STARTS * period_s, indexing="ij")
    shape = grid[0].ravel()
    duration = duration[rows, best][shape] * np.exp(grid[1].ravel())
    start = start[rows, best][shape] + grid[2].ravel()
    scores = _scores(index, y, sway, poles, period_s, node_t, shape, duration, start)
    k = int(np.argmax(scores))
    shape, duration, start, score = (
        int(shape[k]),
        float(duration[k]),
        float(start[k]),
        float(scores[k]),
    )
    dof = max(t_s.size - 3 - 1 - 2 * poles.size - 3, 1)
    rms = math.sqrt(max(float(y @ y) - score, 0.0) / dof)
    s = shapes[shape]
    return ForceReading(
        duration_s=duration,
        start_s=start,
        rise_s=(s.peak_time - s.lead) * duration,
        exponent=s.exponent,
        chi=s.chi,
        residual_noise_ratio=rms / max(noise, 1e-12),
        half_sine_s=s.half_sine * duration,
        unexplained=max(float(y @ y) - score, 0.0) / max(float(y @ y), 1e-300),
    )
