"""The contact's duration from the acceleration pulse itself, on any support, without the camera.

Why: the time from the pulse's onset to the camera's end-of-contact stamp carries the contact
duration (the particle's stiffness and mass), but up to one camera frame (0.2 ms at 5 kHz) of
lag blurs it, as long as a 25 mm particle's whole contact; the duration itself tells coal from
gangue far better (``test/bench/bench_contact.py`` measures by how much). A tail-beam
accelerometer at
10-50 kHz samples the contact several times; what it reads is the contact force passed through
the beam: directly (the rigid beam's acceleration is the force's moment over its inertia) and
through each bending mode, which goes on ringing after the particle has left.

How: the ringing after the contact is a sum of damped sinusoids; their poles (frequency and
decay) are read from the ring-down itself by the matrix pencil method, so the support's modes
need no profile and no config/. Then, for each candidate force pulse (a half-sine of duration
tau starting at t0), the samples around the pulse are fitted by least squares with the pulse
itself, its convolution with each pole's response and a quadratic for the beam's sway; the
candidate with the least residual gives ``duration_s``. Then once more with the poles read
from a ring-down that starts soon after the contact just read: a stiff beam's modes that shape
the pulse may ring out before the first ring-down starts. A hysteretic contact's force is not a
half-sine (it peaks early and tails off), so ``duration_s`` is the half-sine that best matches
the pulse, not the time to separation: shorter, and shorter still for low-restitution gangue.
The models learn what it means across drawn supports and contact laws; it is a measurement of
the pulse's shape in seconds, not a category.

Numpy only; a few ms per impact (all candidates solved at once).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, NamedTuple

import numpy as np

from tail_beam_id.signals.contact_force import ForceReading, explained, read_force
from tail_beam_sim.errors import InputError
from tail_beam_sim.spec import Section, flag, integer, number, positive

PENCIL_WIDTH = 24  # columns of the ring-down's Hankel matrix: 3 x the most poles (8) read from it
# Durations of the first, coarse search (a log grid from min_duration_s to max_duration_s, each
# 1.25 x the one before at the defaults). A coarser grid can stop the search in a local minimum,
# so that one particle reads differently by the support it struck (measured: the read durations
# of one 25 mm particle in docs/results/archive.md).
COARSE_DURATIONS = 20


_FIT_S = dict(unit="s", high=0.1)

CONTACT_FIT = Section(
    "identification.contact_fit",
    "The contact's duration read from the acceleration pulse (feature contact_duration_s).",
    (
        positive(
            "ring_start_s",
            "Ring-down read from this long after the onset.",
            default=0.0015,
            **_FIT_S,
        ),
        positive(
            "ring_end_s", "... to this long after it (> ring_start_s).", default=0.006, **_FIT_S
        ),
        positive("before_s", "Fit from this long before the onset.", default=0.0003, **_FIT_S),
        positive(
            "early_ring_start_s",
            "Second pass: ring-down not before this.",
            default=0.0005,
            **_FIT_S,
        ),
        positive(
            "ring_after_contact_s",
            "Second pass: this after the first pass's contact.",
            default=0.0001,
            **_FIT_S,
        ),
        number(
            "ring_after_contact_factor",
            "... plus this many first-pass durations.",
            "",
            1.0,
            10.0,
            default=1.5,
        ),
        positive("after_s", "Fit to this long after the onset.", default=0.003, **_FIT_S),
        positive("min_duration_s", "Shortest half-sine force tried.", default=3.0e-5, **_FIT_S),
        positive("max_duration_s", "Longest half-sine force tried.", default=0.002, **_FIT_S),
        integer("max_modes", "Most damped sinusoids read from the ring-down.", 1, 8, default=4),
        integer("min_ring_samples", "Fewer ring-down samples: no fit.", 8, 10000, default=24),
        number(
            "min_mode_frequency_hz",
            "Slower poles are left to the sway.",
            "Hz",
            0.0,
            1e5,
            default=150.0,
        ),
        flag(
            "force_readout",
            "Also read the contact force through the ring-down (features contact_force_*, "
            "the unreliable-duration cap); about 2-3x the fit's cost, not read by the shipped "
            "models.",
            default=False,
        ),
        number(
            "long_contact_half_periods",
            "A force read this many half periods of the slowest mode long: duration unreliable.",
            "",
            0.1,
            100.0,
            default=5.0,
        ),
        number(
            "poor_fit_unexplained",
            "A force fit leaving more of the pulse's power than this: duration unreliable.",
            "",
            0.0,
            1.0,
            default=0.25,
        ),
        number(
            "poor_fit_noise_ratio",
            "... and a residual RMS above this many noise RMS.",
            "",
            0.0,
            1000.0,
            default=3.0,
        ),
        number(
            "unreliable_confidence_cap",
            "Most confidence of a label whose duration is unreliable.",
            "",
            0.5,
            1.0,
            default=0.7,
        ),
        number(
            "max_fit_rate_hz",
            "A faster channel is decimated to at most this.",
            "Hz",
            1000.0,
            1e6,
            default=51200.0,
        ),
    ),
    file="identification.yaml",
)


@dataclass(frozen=True)
class ContactFitConfig:
    """The ``identification.contact_fit`` section: times in s after (or before) the onset."""

    ring_start_s: float = (
        0.0015  # the ring-down read for the poles starts here (the contact is over)
    )
    ring_end_s: float = 0.006  # ... and ends here (<= the accelerometer's data window)
    early_ring_start_s: float = 0.0005  # a second pass's ring-down starts no sooner than this
    ring_after_contact_factor: float = 1.5  # ... nor sooner than this many first-pass durations
    ring_after_contact_s: float = 0.0001  # ... plus this after the first pass's start
    before_s: float = 0.0003  # samples before the onset in the fit (the background)
    after_s: float = 0.003  # samples after the onset in the fit
    min_duration_s: float = 3.0e-5
    max_duration_s: float = 2.0e-3
    max_modes: int = 4  # damped sinusoids read from the ring-down, at most
    min_ring_samples: int = 24  # fewer samples in the ring-down (a slow channel): no fit
    min_mode_frequency_hz: float = 150.0  # slower poles are left to the quadratic (the sway)
    max_fit_rate_hz: float = (
        51200.0  # a faster channel is read every k-th sample, at most this rate (cost)
    )
    force_readout: bool = False  # the force read-out and the cap it feeds (costly)
    long_contact_half_periods: float = 5.0  # a force this many half periods long: unreliable
    poor_fit_unexplained: float = 0.25  # a force fit leaving this share of the power: unreliable
    poor_fit_noise_ratio: float = 3.0  # ... with a residual above this many noise RMS
    unreliable_confidence_cap: float = 0.7  # the most confidence such a label may carry

    @classmethod
    def from_params(cls, section: Mapping[str, Any] | None) -> ContactFitConfig:
        config = cls(**CONTACT_FIT.check(section or {}))
        if config.ring_end_s <= config.ring_start_s:
            raise InputError(
                "identification.contact_fit.ring_end_s",
                config.ring_end_s,
                f"must be > ring_start_s ({config.ring_start_s:g} s)",
            )
        if config.max_duration_s <= config.min_duration_s:
            raise InputError(
                "identification.contact_fit.max_duration_s",
                config.max_duration_s,
                f"must be > min_duration_s ({config.min_duration_s:g} s)",
            )
        return config


@dataclass(frozen=True)
class ContactFit:
    """The best half-sine force pulse: its duration and start (s), and the support's ringing modes
    (Hz) as the ring-down from ring_start_s reads them."""

    duration_s: float
    start_s: float
    mode_frequencies_hz: tuple[float, ...]
    # The force history read through the same poles (tail_beam_id.signals.contact_force); None
    # on a channel too slow for a ring-down, or when no force could be read.
    force: ForceReading | None = None


def ringing_poles(
    values: np.ndarray, period_s: float, max_modes: int, noise: float, min_frequency_hz: float
) -> np.ndarray:
    """Continuous-time poles (1/s, upper half-plane, decaying) of the damped sinusoids in a
    ring-down, by the matrix pencil: as many as its Hankel matrix has singular values clear of
    the noise (at least one, at most ``max_modes``), poles slower than ``min_frequency_hz``
    left out."""
    y = values - values.mean()
    width = min(y.size // 2, PENCIL_WIDTH)
    # sliding_window_view's (y.size - width) x (width + 1) view, built directly (its argument
    # checks cost more than the pencil's products)
    hankel = np.ndarray(
        (y.size - width, width + 1), dtype=y.dtype, buffer=y, strides=(y.itemsize, y.itemsize)
    )
    hankel.flags.writeable = False
    # The right singular vectors and values from the small Gram matrix (width + 1 square), so
    # that the cost does not grow with the sampling rate's square.
    power, vectors = np.linalg.eigh(hankel.T @ hankel)
    power, vectors = power[::-1], vectors[:, ::-1]
    singular = np.sqrt(np.maximum(power, 0.0))
    floor = max(float(singular[0]) * 1e-3, 3.0 * noise * math.sqrt(hankel.shape[0]))
    order = min(max(int(np.count_nonzero(singular > floor)), 2), 2 * max_modes)
    v = vectors[:, :order]
    shift = np.linalg.lstsq(v[:-1], v[1:], rcond=None)[0]
    z = np.linalg.eigvals(shift)
    z = z[np.abs(z) > 1e-9]
    poles = np.log(z.astype(complex)) / period_s
    poles = -np.abs(poles.real) + 1j * np.abs(poles.imag)  # one of each pair, never growing
    poles = poles[np.abs(poles) > 2.0 * math.pi * min_frequency_hz]
    return np.unique(np.round(poles, 6))[:max_modes]


class _PulseGrid(NamedTuple):
    """What the bases of a grid of half-sines (D durations x S starts) at the samples ``t``
    share whatever the poles: ``after`` (S, N) each sample's time since each start > 0;
    ``clamped`` that time where after, else 0, s; ``within`` the (duration, start, sample)
    indices inside each pulse; at those, ``w_in`` the pulse's angular frequency pi / d (1/s),
    ``sine`` and ``cosine`` of w_in times the time since the start; ``d`` the durations
    (D, 1, 1), ``w`` pi / d; ``pair`` each inside index's (duration, start) pair, d x S + s,
    and ``flat_in`` / ``flat_since`` its place in a flattened (D, S, N) / (S, N) array (one
    flat index is much cheaper to gather and scatter with than three)."""

    t: np.ndarray
    durations: np.ndarray
    starts: np.ndarray
    d: np.ndarray
    w: np.ndarray
    after: np.ndarray
    clamped: np.ndarray
    within: tuple[np.ndarray, np.ndarray, np.ndarray]
    w_in: np.ndarray
    sine: np.ndarray
    cosine: np.ndarray
    pair: np.ndarray
    flat_in: np.ndarray
    flat_since: np.ndarray


# The last grids built, newest first: the coarse search of a fit's second pass reads the same
# samples and grid (the same arrays) as its first, with other poles.
_last_grids: list[_PulseGrid] = []
LAST_GRIDS = 2


def _pulse_grid(t: np.ndarray, durations: np.ndarray, starts: np.ndarray) -> _PulseGrid:
    """The :class:`_PulseGrid` of these arrays; one of the last LAST_GRIDS again when called
    with the very same arrays (which the caller does not change in between)."""
    for last in _last_grids:
        if last.t is t and last.durations is durations and last.starts is starts:
            return last
    d = durations[:, None, None]  # (D, 1, 1)
    since = t[None, :] - starts[:, None]  # time since each candidate start, (S, N)
    after = since > 0.0
    w = math.pi / d
    within = np.nonzero(after[None] & (since[None] < d))  # (D, S, N) indices in the pulse
    t_in, w_in = since[within[1], within[2]], w.ravel()[within[0]]
    pair = within[0] * starts.size + within[1]
    grid = _PulseGrid(
        t,
        durations,
        starts,
        d,
        w,
        after,
        np.where(after, since, 0.0),
        within,
        w_in,
        np.sin(w_in * t_in),
        np.cos(w_in * t_in),
        pair,
        pair * t.size + within[2],
        within[1] * t.size + within[2],
    )
    _last_grids[:] = [grid, *_last_grids[: LAST_GRIDS - 1]]
    return grid


def _best(
    t: np.ndarray,
    y: np.ndarray,
    sway: np.ndarray,
    poles: np.ndarray,
    durations: np.ndarray,
    starts: np.ndarray,
) -> tuple[float, float]:
    """The (duration, start) among every pair of ``durations`` x ``starts`` whose basis fits
    ``y`` at ``t`` with the least residual, all candidates solved together. The basis: a
    quadratic (``sway``, N x 3 orthonormal; ``y`` comes with it taken out), the half-sine
    pulse, and the pulse convolved with exp(pole t) for each pole, in closed form:
    ((-p sin wT - w cos wT) exp(p (t - d)+) + w exp(p t)) / (p^2 + w^2) with w = pi / d and
    T = min(t, d), whose exponentials factor into t and d alone."""
    n = t.size
    grid = _pulse_grid(t, durations, starts)
    d, w, within, sine, cosine = grid.d, grid.w, grid.within, grid.sine, grid.cosine
    after, w_in = grid.after, grid.w_in
    rows = 1 + 2 * poles.size
    basis = np.zeros((durations.size, starts.size, rows, n))
    # the sine's row: at each inside sample's (pair, row 0, sample) of the flattened basis
    basis.reshape(-1)[grid.pair * (rows * n) + within[2]] = sine
    # Inside the pulse (few samples) the closed form in full; after it the response is the
    # pulse's end value carried by exp(p t), a product of a (D,) and an (S, N) factor.
    for k, pole in enumerate(poles):
        grows = np.where(after, np.exp(pole * grid.clamped), 0.0)  # exp(p t) after start, (S, N)
        value = (w * (1.0 + np.exp(-pole * d)) / (pole * pole + w * w)) * grows[None]
        value.reshape(-1)[grid.flat_in] = (
            (-pole * sine - w_in * cosine) + w_in * grows.reshape(-1)[grid.flat_since]
        ) / (pole * pole + w_in * w_in)
        basis[:, :, 1 + 2 * k] = value.real
        basis[:, :, 2 + 2 * k] = value.imag
    basis = basis.reshape(-1, rows, n)
    # the least squares against [sway, basis], as the force read-out scores its shapes
    score = explained(basis, y, sway)
    best = int(np.argmax(score))
    return float(durations[best // starts.size]), float(starts[best % starts.size])


@lru_cache(maxsize=16)
def _coarse_durations(min_duration_s: float, max_duration_s: float) -> np.ndarray:
    """The first search's durations, s: a log grid of COARSE_DURATIONS (read-only, shared)."""
    durations = np.exp(
        np.linspace(math.log(min_duration_s), math.log(max_duration_s), COARSE_DURATIONS)
    )
    durations.flags.writeable = False
    return durations


def _coarse_grid(period_s: float, config: ContactFitConfig) -> tuple[np.ndarray, np.ndarray]:
    """The first search's (durations, starts), s: a log grid of COARSE_DURATIONS durations,
    starts half a sample apart."""
    durations = _coarse_durations(config.min_duration_s, config.max_duration_s)
    return durations, _coarse_starts(period_s)


@lru_cache(maxsize=16)
def _coarse_starts(period_s: float) -> np.ndarray:
    """The first search's starts, s after the onset: half a sample apart (read-only, shared)."""
    starts = np.arange(-3, 6) * period_s / 2.0
    starts.flags.writeable = False
    return starts


@lru_cache(maxsize=16)
def _refine_factors(min_duration_s: float, max_duration_s: float) -> np.ndarray:
    """The refined durations over the coarse best's: a coarse step either side, nine of them
    (read-only, shared)."""
    coarse = _coarse_durations(min_duration_s, max_duration_s)
    step = math.log(coarse[1] / coarse[0])
    factors = np.exp(np.linspace(-step, step, 9))
    factors.flags.writeable = False
    return factors


def _refine_grid(
    duration: float, start: float, period_s: float, config: ContactFitConfig
) -> tuple[np.ndarray, np.ndarray]:
    """The (durations, starts) about the coarse best (``duration``, ``start``), s: a coarse
    step either side, and starts a third of a sample apart."""
    return (
        duration * _refine_factors(config.min_duration_s, config.max_duration_s),
        start + np.arange(-2, 3) * period_s / 6.0,
    )


def _search(
    t: np.ndarray,
    y: np.ndarray,
    sway: np.ndarray,
    poles: np.ndarray,
    period_s: float,
    config: ContactFitConfig,
) -> tuple[float, float]:
    """(duration, start) of the best half-sine: every duration of a log grid (COARSE_DURATIONS)
    with starts half a sample apart, then refined around the best."""
    duration, start = _best(t, y, sway, poles, *_coarse_grid(period_s, config))
    return _best(t, y, sway, poles, *_refine_grid(duration, start, period_s, config))


def _early_ring_start_s(
    duration_s: np.ndarray | float, start_s: np.ndarray | float, config: ContactFitConfig
) -> np.ndarray | float:
    """Where the second pass's ring-down starts after a first pass that read ``duration_s``
    from ``start_s`` (s after the onset; arrays: for each pair)."""
    return np.maximum(
        config.early_ring_start_s,
        start_s + config.ring_after_contact_factor * duration_s + config.ring_after_contact_s,
    )


def one_second_ring_down(
    stamp_s: np.ndarray,
    onset_s: float,
    early_s: np.ndarray,
    period_s: float,
    config: ContactFitConfig,
) -> bool:
    """Whether the second pass's ring-down starts at the same samples whichever of ``early_s``
    (s after the onset ``onset_s``; one for each pair the first pass's refinement could pick)
    it starts from, each early enough for a second pass: then the refinement can change
    nothing and is left out (:func:`fit_contact`)."""
    low, high = float(np.min(early_s)), float(np.max(early_s))
    return high < config.ring_start_s - period_s and not np.any(
        (stamp_s > onset_s + low) & (stamp_s <= onset_s + high)
    )


LONG_CONTACT = "contact_longer_than_mode"  # what a capped label lists in outside_training
POOR_FIT = "contact_fit_poor"


def half_periods(fit: ContactFit | None, config: ContactFitConfig) -> float | None:
    """How many half periods of the slowest mode the ring-down shows the force read through the
    ringing lasts (a 0 Hz pole, a pure decay, is no mode); None when no force or no mode was
    read."""
    if fit is None or fit.force is None:
        return None
    ringing = [f for f in fit.mode_frequencies_hz if f >= config.min_mode_frequency_hz]
    return 2.0 * fit.force.duration_s * min(ringing) if ringing else None


def unreliable(fit: ContactFit | None, config: ContactFitConfig) -> tuple[str, ...]:
    """Why the half-sine's duration (feature contact_duration_s) cannot be trusted, if it
    cannot: the force read through the ringing lasts ``long_contact_half_periods`` half
    periods of the slowest mode read from the ring-down or more (the mode's response then
    overlaps the pulse, and the half-sine that fits best depends on the support:
    LONG_CONTACT), or the force fit leaves more than ``poor_fit_unexplained`` of the pulse's
    power and ``poor_fit_noise_ratio`` x the noise unexplained (the support or the contact is
    unlike the model: POOR_FIT). Empty when reliable or nothing was read."""
    if fit is None or fit.force is None:
        return ()
    reasons = []
    long = half_periods(fit, config)
    if long is not None and long >= config.long_contact_half_periods:
        reasons.append(LONG_CONTACT)
    if (
        fit.force.unexplained > config.poor_fit_unexplained
        and fit.force.residual_noise_ratio > config.poor_fit_noise_ratio
    ):
        reasons.append(POOR_FIT)
    return tuple(reasons)


def unbroken(where: np.ndarray, stamp_s: np.ndarray, period_s: float) -> np.ndarray:
    """The longest run of ``where`` whose stamps step by one ``period_s``: the matrix pencil
    needs evenly spaced samples, and a sample left out (not finite, lost with its block) would
    shift every one after it by a period (one such gap at 1 ms turned a 323 us reading into
    119 us)."""
    if where.size < 2:
        return where
    breaks = np.flatnonzero(np.diff(stamp_s[where]) > 1.5 * period_s) + 1
    if not breaks.size:
        return where
    runs = np.split(where, breaks)
    return max(runs, key=len)


def clipped_samples(accel: np.ndarray, where: np.ndarray) -> np.ndarray:
    """The indices among ``where`` whose |value| is the largest there, when two or more share it:
    a sensor clipped at its range (a true peak is one sample; the range itself need not be
    known). Empty when nothing is clipped."""
    if not where.size:
        return where
    magnitude = np.abs(accel[where])
    at_limit = where[magnitude >= magnitude.max() * (1.0 - 1e-6)]
    return at_limit if at_limit.size >= 2 else where[:0]


def clipped_near(
    stamp_s: np.ndarray, accel: np.ndarray, onset_s: float, config: ContactFitConfig
) -> bool:
    """Whether the sensor clipped in the window the fit reads (before_s before the onset to
    ring_end_s after it): the label then says the channel saturated."""
    where = np.flatnonzero(
        (stamp_s > onset_s - config.before_s) & (stamp_s <= onset_s + config.ring_end_s)
    )
    return bool(clipped_samples(accel, where).size)


def fit_contact(
    stamp_s: np.ndarray,
    accel: np.ndarray,
    onset_s: float,
    period_s: float,
    noise: float,
    config: ContactFitConfig,
    with_force: bool = True,
) -> ContactFit | None:
    """The contact's half-sine duration from the samples (stamps in s, acceleration along the
    plate normal in m/s^2) around a pulse whose onset is ``onset_s``, and (``with_force``) the
    force's shape read through the same poles (:mod:`tail_beam_id.signals.contact_force`). A
    channel too slow for a ring-down of ``min_ring_samples`` gives its sample period (the
    contact fell within one sample; ``mode_frequencies_hz`` empty); None when a fast channel's
    samples do not cover the window (the stream ended) or are not finite: then nothing is known
    of the duration."""
    span_s = config.ring_end_s - config.ring_start_s
    if span_s / period_s < config.min_ring_samples:
        return ContactFit(period_s, onset_s, ())
    ring = (stamp_s > onset_s + config.ring_start_s) & (stamp_s <= onset_s + config.ring_end_s)
    inside = (stamp_s > onset_s - config.before_s) & (stamp_s <= onset_s + config.after_s)
    if (
        ring.sum() < config.min_ring_samples
        or inside.sum() < 8
        or not np.all(np.isfinite(accel[inside | ring]))
    ):
        return None
    # Above max_fit_rate_hz every stride-th sample from the window's first: the cost grows with
    # the samples in the window, and a channel faster than the training's (8-64 kHz) is then
    # read as one at period x stride would be.
    stride = max(1, math.ceil(1.0 / (period_s * config.max_fit_rate_hz) - 1e-9))
    kept = (np.arange(stamp_s.size) - int(np.argmax(inside))) % stride == 0
    clipped = clipped_samples(accel, np.flatnonzero((ring | inside) & kept))
    ring, inside = np.flatnonzero(ring & kept), np.flatnonzero(inside & kept)
    period_s *= stride
    # A sensor driven past its range reads its limit: those samples say only that the signal
    # was beyond it, so the fit leaves them out (they read as a flat top, i.e. a long pulse
    # shortened to its edges), and the ring-down is read after the last of them.
    if clipped.size:
        inside = np.setdiff1d(inside, clipped)
    if inside.size < 8:
        return None

    def ring_down(from_s: float) -> np.ndarray:
        """The kept, finite samples from ``from_s`` after the onset to ring_end_s, after any
        clipped one: their longest unbroken run."""
        where = np.flatnonzero(
            kept
            & (stamp_s > onset_s + from_s)
            & (stamp_s <= onset_s + config.ring_end_s)
            & np.isfinite(accel)
        )
        return unbroken(
            where[where > clipped.max()] if clipped.size else where, stamp_s, period_s
        )

    t = stamp_s[inside] - onset_s
    y = accel[inside] - float(np.mean(accel[inside]))
    sway = np.linalg.qr(np.stack([np.ones_like(t), t, t * t], axis=1))[
        0
    ]  # the beam's sway: a quadratic, N x 3
    y = y - sway @ (sway.T @ y)
    ring = ring_down(config.ring_start_s)
    if ring.size < config.min_ring_samples:
        return None
    poles = ringing_poles(
        accel[ring], period_s, config.max_modes, noise, config.min_mode_frequency_hz
    )
    duration, start = _best(t, y, sway, poles, *_coarse_grid(period_s, config))
    refine = _refine_grid(duration, start, period_s, config)
    # A second pass whose ring-down starts soon after the contact the first pass read (not
    # before early_ring_start_s): on a stiff beam the modes that shape the pulse ring out
    # within a millisecond, before ring_start_s, and without them the reading can split between
    # two minima, far apart for the same particle.
    # When every pair the refinement could pick starts that ring-down at the same samples and
    # it is read, the first pass is not refined: its reading is then used for nothing else.
    early = _early_ring_start_s(refine[0][:, None], refine[1][None, :], config)
    sooner = (
        ring_down(float(np.min(early)))
        if one_second_ring_down(stamp_s, onset_s, early, period_s, config)
        else None
    )
    if sooner is None or sooner.size < config.min_ring_samples:
        duration, start = _best(t, y, sway, poles, *refine)
        early_s = float(_early_ring_start_s(duration, start, config))
        sooner = ring_down(early_s) if early_s < config.ring_start_s - period_s else None
    used = poles
    if sooner is not None and sooner.size >= config.min_ring_samples:
        used = ringing_poles(
            accel[sooner], period_s, config.max_modes, noise, config.min_mode_frequency_hz
        )
        duration, start = _search(t, y, sway, used, period_s, config)
    force = (
        read_force(t, y, sway, poles, period_s, start, duration, noise, config.max_duration_s)
        if with_force
        else None
    )
    return ContactFit(
        duration,
        onset_s + start,
        tuple(float(p.imag / (2.0 * math.pi)) for p in poles),  # the late ring-down's
        force,
    )
