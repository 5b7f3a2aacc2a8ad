"""Impact detection in the continuous IMU stream: onsets, pulses, noise and overlap.

A particle's contact lasts 0.1-1 ms, far shorter than the beam's 40 Hz sway, and the IMU
reports the mean specific force over each sample period: the contact shows as a sudden
departure from a slow background (gravity, the beam still swaying from earlier impacts):
negative when the plate is pushed away, positive when a bending mode answers first with the
opposite sign. The detector predicts each sample from a quadratic fitted to the samples
before it, and starts a pulse where a sample leaves the prediction by
``accel_threshold_sigma`` noise RMS; while the bending modes ring after a pulse the
threshold is raised in proportion to it. The noise RMS is a robust (MAD)
estimate over fixed blocks of samples, so that the result depends only on the samples, never
on how they were chunked on arrival.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from tail_beam_sim.spec import Section, flag, number, positive

MAD_TO_SIGMA = 1.4826  # median absolute deviation of a Gaussian times this = its RMS
PERIOD_SAMPLES = 64  # the sample period is read from the first this many stamps
# The onset look-back spans at least this many samples: at low rates the bending modes can
# take a few samples to build the response past the detection threshold.
ONSET_LOOKBACK_MIN_SAMPLES = 4
# A pulse found in the ringing of an earlier one has its onset moved past that ringing only
# when the move is this long, s: a shorter one is the contact's own response opening on the
# other side (a node of the rigid response), not a ringing lobe (3 samples at 25.6 kHz, at
# least 2 at any rate).
ONSET_PAST_RINGING_MIN_S = 1.0e-4
# The look-back's sway background needs at least this many samples (else a straight line).
SWAY_FIT_MIN_SAMPLES = 6


_SIGMA = dict(high=1e3)

_DET_S = dict(unit="s", high=1.0)

DETECTION = Section(
    "identification.detection",
    "Impact detection in the IMU, accelerometer and pressure streams (thresholds in noise RMS).",
    (
        positive("accel_threshold_sigma", "A pulse starts below -this.", **_SIGMA),
        positive(
            "extend_threshold_sigma", "The pulse extends over samples beyond this.", **_SIGMA
        ),
        positive("onset_threshold_sigma", "Its onset: the first sample beyond this.", **_SIGMA),
        positive(
            "onset_lookback_s", "Onset looked for up to this before the detection.", **_DET_S
        ),
        positive("baseline_window_s", "Background fitted over this before the pulse.", **_DET_S),
        positive("sway_window_s", "Free sway fitted over this before the look-back.", **_DET_S),
        positive("noise_block_s", "Noise RMS estimated over blocks of this.", "s", high=100.0),
        positive("max_contact_s", "Longest contact a pulse may span.", **_DET_S),
        positive(
            "rebound_early_tolerance_s",
            "A rebound this early still belongs to the pulse.",
            **_DET_S,
        ),
        positive("unconfirmed_pulse_sigma", "An unconfirmed pulse must be this strong.", high=1e6),
        positive(
            "pressure_confirm_sigma",
            "Moment impulse confirming a pulse, standard errors.",
            **_SIGMA,
        ),
        positive(
            "pressure_threshold_sigma",
            "Pressure-only detection threshold, standard errors.",
            **_SIGMA,
        ),
        positive(
            "ring_fraction", "Threshold over the ringing's envelope after a pulse.", high=100.0
        ),
        positive(
            "vibration_ring_fraction",
            "The same in an accelerometer stream of vibration_ring_min_rate_hz or faster.",
            high=100.0,
            default=None,
        ),
        positive(
            "vibration_ring_min_rate_hz",
            "Slowest accelerometer that vibration_ring_fraction applies to.",
            "Hz",
            high=1e6,
            default=20000.0,
        ),
        flag(
            "vibration_innovations",
            "Calibration fits the accelerometer's ringing predictor; its detector scans the "
            "prediction errors.",
            default=False,
        ),
        flag(
            "onset_past_ringing",
            "A pulse found in an earlier one's ringing takes its onset past that ringing "
            "(onset_after_ringing); the shipped models learnt without it.",
            default=False,
        ),
        positive("ring_decay_s", "Decay time of that envelope.", "s", high=10.0),
        positive("ring_window_s", "How long the raised threshold lasts.", "s", high=10.0),
        positive(
            "rebound_onset_lead_s", "Onset of a rebound-only impact before its stamp.", **_DET_S
        ),
        positive(
            "pressure_onset_uncertainty_s",
            "Onset uncertainty of pressure-only detection.",
            **_DET_S,
        ),
        positive(
            "onset_before_rebound_max_s",
            "Contact began at most this before the rebound.",
            **_DET_S,
        ),
        positive(
            "rebound_frame_allowance_s",
            "Camera frame the rebound window allows for.",
            default=0.0005,
            **_DET_S,
        ),
        number(
            "pressure_drift_confirm_sigma",
            "Moment impulse kept against a drifting sway.",
            "",
            0.0,
            1e3,
            default=2.5,
        ),
        number(
            "late_rebound_max_s",
            "A late rebound up to this after the onset (0 = off).",
            "s",
            0.0,
            1.0,
            default=0.025,
        ),
    ),
    file="identification.yaml",
)


@dataclass(frozen=True)
class DetectionConfig:
    """Detection thresholds (in noise RMS, sigma) and windows (s); see
    config/identification.yaml."""

    accel_threshold_sigma: float
    extend_threshold_sigma: float
    onset_threshold_sigma: float
    onset_lookback_s: float
    baseline_window_s: float
    sway_window_s: float
    noise_block_s: float
    max_contact_s: float
    rebound_early_tolerance_s: float
    unconfirmed_pulse_sigma: float
    pressure_confirm_sigma: float
    pressure_threshold_sigma: float
    ring_fraction: float
    ring_decay_s: float
    ring_window_s: float
    rebound_onset_lead_s: float
    pressure_onset_uncertainty_s: float
    onset_before_rebound_max_s: float
    rebound_frame_allowance_s: float = 0.0005
    pressure_drift_confirm_sigma: float = 2.5
    late_rebound_max_s: float = 0.025
    # The tail-beam accelerometer's ring_fraction when it samples at vibration_ring_min_rate_hz
    # or faster (None: ring_fraction's): PulseDetector's ``fast_ring_fraction``.
    vibration_ring_fraction: float | None = None
    vibration_ring_min_rate_hz: float = 20000.0
    # Self-calibration fits a one-step predictor of the accelerometer's ringing
    # (tail_beam_id.signals.innovations) and its detector scans what the predictor leaves.
    vibration_innovations: bool = False
    onset_past_ringing: bool = False  # the onset read past an earlier pulse's ringing

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> DetectionConfig:
        """Validate the ``identification.detection`` section."""
        return cls(**DETECTION.check(params or {}))


@dataclass(frozen=True)
class Pulse:
    """One contact as the IMU saw it: where the specific force first left its background.

    ``first_stamp_s``: stamp of the first sample deviating (the contact began within that
    sample's averaging period); ``onset_s``: the middle of that period, the contact-start
    estimate; ``polarity``: +1 when that sample shows the plate pushed away from the particle
    (a rigid beam's answer), -1 when the bending modes answer first with the opposite sign
    (impacts between the hinge and the jack pin); ``width_s``: RMS duration of the deviating
    run of samples; ``peak_sigma``: the largest deviation in noise RMS; ``noise_mps2``: that
    RMS, m/s^2; ``period_s``: the IMU sample period read from the stamps.
    """

    onset_s: float
    first_stamp_s: float
    polarity: int
    width_s: float
    peak_sigma: float
    noise_mps2: float
    period_s: float
    first_index: int
    last_index: int


def robust_sigma(values: np.ndarray) -> float:
    """Noise RMS from the median absolute deviation (insensitive to a few pulses)."""
    if values.size == 0:
        return math.nan
    return float(MAD_TO_SIGMA * np.median(np.abs(values - np.median(values))))


@lru_cache(maxsize=16)
def extrapolation_weights(length: int) -> np.ndarray:
    """Weights w such that w @ y[-length:] is a quadratic least-squares fit's value one step on."""
    x = np.arange(-length, 0, dtype=float)
    basis = np.vstack([np.ones(length), x, x * x]).T
    return np.linalg.pinv(basis)[0]


def background_fit(
    values: np.ndarray, lo: int, hi: int, excluded: np.ndarray, max_degree: int = 2
) -> np.ndarray:
    """Polynomial (in sample index, about ``hi``) fitted to values[lo:hi] outside ``excluded``:
    quadratic with 12 samples or more, linear with 8 or more, else constant (a high degree on
    few samples extrapolates wildly), at most ``max_degree``. Returns 3 coefficients, constant
    first."""
    index = np.arange(lo, hi)
    keep = ~excluded[lo:hi]
    x = (index[keep] - hi).astype(float)
    coeffs = np.zeros(3)
    if x.size == 0:
        coeffs[0] = float(np.mean(values[lo:hi])) if hi > lo else 0.0
        return coeffs
    degree = min(max_degree, 2 if x.size >= 12 else (1 if x.size >= 8 else 0))
    basis = np.vstack([x**p for p in range(degree + 1)]).T
    fitted, *_ = np.linalg.lstsq(basis, values[lo:hi][keep], rcond=None)
    coeffs[: degree + 1] = fitted
    return coeffs


def background_values(
    values: np.ndarray, ends: np.ndarray, baseline: int, excluded: np.ndarray
) -> np.ndarray:
    """``background_fit(values, e - baseline, e, excluded)[0]`` for every ``e`` in ``ends`` at
    once: the background each sample just after a pulse is compared with (the fit over the
    samples before it that no pulse covers, at the sample). Same degrees as ``background_fit``;
    the normal equations of the few samples in a window, in x / baseline, solved together."""
    ends = np.asarray(ends, dtype=int)
    if ends.size == 0:
        return np.empty(0)
    offsets, powers = _window_powers(baseline)
    index = ends[:, None] + offsets[None, :]
    y = values[index]
    keep = (~excluded[index]).astype(float)
    kept = keep.sum(axis=1)
    moments = keep @ powers.T  # (N, 5): sums of x^m over the kept samples
    rhs = (keep * y) @ powers[:3].T  # (N, 3)
    out = y.mean(axis=1)  # no sample kept: the plain mean, as background_fit
    degree = np.where(kept >= 12, 2, np.where(kept >= 8, 1, 0))
    for d in range(3):
        rows = (degree == d) & (kept > 0)
        if rows.any():
            normal = moments[rows][:, _HANKEL[d]]  # (n, d + 1, d + 1): moment p + q at (p, q)
            out[rows] = np.linalg.solve(normal, rhs[rows, : d + 1, None])[:, 0, 0]
    return out


# The moment each entry of a degree-d fit's normal matrix holds: p + q at (p, q).
_HANKEL = tuple(np.add.outer(np.arange(d + 1), np.arange(d + 1)) for d in range(3))


@lru_cache(maxsize=16)
def _window_powers(baseline: int) -> tuple[np.ndarray, np.ndarray]:
    """The sample offsets of a ``baseline`` window before a sample (-baseline..-1), and their
    powers 0..4 in units of the window, (5, baseline) (read-only, shared)."""
    offsets = np.arange(-baseline, 0)
    powers = (offsets / baseline)[None, :] ** np.arange(5)[:, None]
    offsets.flags.writeable = powers.flags.writeable = False
    return offsets, powers


RING_RUN_DECAYS = (
    20.0  # a run of ringing samples followed at once spans at most this many ring_decay_s
)


class PulseDetector:
    """Finds contact pulses in one IMU stream's specific force along the plate normal.

    Feed it the whole buffered stream each time (``scan``); it remembers how far it got and
    returns the pulses whose first sample it has now decided on.
    """

    def __init__(
        self,
        config: DetectionConfig,
        sway_frequency_hz: float | None = None,
        fast_ring_fraction: float | None = None,
    ) -> None:
        """``fast_ring_fraction``: the threshold over the ringing's envelope instead of
        ``ring_fraction`` once the stream shows itself sampled at ``vibration_ring_min_rate_hz``
        or faster (the tail-beam accelerometer's detector: :attr:`ring_fraction`)."""
        self.config = config
        self.sway_frequency_hz = (
            sway_frequency_hz  # the beam's free sway (the identifier's beam model), Hz
        )
        self.fast_ring_fraction = fast_ring_fraction
        self.cursor = 0  # next sample index (absolute) to examine
        self.spans: list[tuple[int, int]] = []  # absolute (first, last) sample of each pulse found
        self.period_s: float | None = None  # the IMU sample period, s, read from the stamps
        self.ring: tuple[float, float] | None = None  # ringing envelope: (stamp s, level m/s^2)
        self._sigma_cache: dict[
            int, float
        ] = {}  # noise RMS per block, by its first absolute index

    @property
    def ring_fraction(self) -> float:
        """The threshold over the ringing's envelope, x: ``fast_ring_fraction`` on a stream
        sampled at ``vibration_ring_min_rate_hz`` or faster, else ``ring_fraction``. There the
        one-step prediction follows a bending mode's ringing closely, so what it leaves of the
        ringing is small and a pulse standing a little out of the envelope is an impact; a
        slower stream (an IMU at 2 kHz, or an accelerometer as slow) aliases the same modes, and
        its ringing residual needs the wider margin or the ringing itself reads as impacts."""
        c = self.config
        if (
            self.fast_ring_fraction is not None
            and self.period_s is not None
            and self.period_s * c.vibration_ring_min_rate_hz <= 1.0 + 1e-9
        ):
            return self.fast_ring_fraction
        return c.ring_fraction

    def lookback_s(self) -> float:
        """How far before the sample that sets it off a pulse's onset may lie, s
        (``onset_lookback_s``, at least ``ONSET_LOOKBACK_MIN_SAMPLES`` samples): every pulse whose
        onset is this far before the scan's cursor has been found."""
        c = self.config
        if self.period_s is None:
            return c.onset_lookback_s
        samples = max(ONSET_LOOKBACK_MIN_SAMPLES, int(round(c.onset_lookback_s / self.period_s)))
        return samples * self.period_s

    def geometry(self, period_s: float) -> tuple[int, int, int]:
        """(baseline samples, noise block samples, most samples a pulse spans) at this period."""
        c = self.config
        baseline = max(4, int(round(c.baseline_window_s / period_s)))
        block = max(16, int(round(c.noise_block_s / period_s)))
        span = int(math.ceil(c.max_contact_s / period_s)) + 1
        return baseline, block, span

    def noise(
        self, accel_z: np.ndarray, k: int, baseline: int, block: int, base_index: int
    ) -> float:
        """Noise RMS for local sample ``k``: MAD of the prediction residuals over the previous
        whole block of samples (the first block for early samples). Blocks are aligned to the
        absolute sample index, so the value never depends on how the stream was chunked."""
        absolute = base_index + k
        start = max((absolute - baseline) // block - 1, 0) * block + baseline
        if start not in self._sigma_cache:
            # A stream that resumed after a gap may have had that block trimmed away: use the
            # oldest whole block still buffered instead.
            lo = min(max(start - base_index, baseline), max(accel_z.size - block, baseline))
            self._sigma_cache[start] = robust_sigma(
                self._residual(accel_z, lo, lo + block, baseline)
            )
        return self._sigma_cache[start]

    def _block_sigmas(
        self,
        accel_z: np.ndarray,
        start: int,
        stop: int,
        baseline: int,
        block: int,
        base_index: int,
    ) -> np.ndarray:
        """Noise RMS for every sample in [start, stop), one value per aligned block."""
        sigma = np.empty(stop - start)
        k = start
        while k < stop:
            absolute = base_index + k
            block_end = ((absolute - baseline) // block + 1) * block + baseline - base_index
            end = min(block_end, stop)
            sigma[k - start : end - start] = self.noise(accel_z, k, baseline, block, base_index)
            k = end
        return sigma

    @staticmethod
    def _residual(accel_z: np.ndarray, lo: int, hi: int, baseline: int) -> np.ndarray:
        """Residuals of samples lo..hi-1 from the one-step quadratic prediction."""
        history = accel_z[lo - baseline : hi - 1]
        # sliding_window_view's view, built directly (its argument checks cost more than the
        # product over a chunk's samples)
        shape, strides = (history.size - baseline + 1, baseline), (history.strides[0],) * 2
        if history.flags.c_contiguous:
            windows = np.ndarray(shape, dtype=history.dtype, buffer=history, strides=strides)
            windows.flags.writeable = False
        else:
            windows = np.lib.stride_tricks.as_strided(
                history, shape=shape, strides=strides, writeable=False
            )
        return accel_z[lo:hi] - windows @ extrapolation_weights(baseline)

    def scan(
        self, stamp_s: np.ndarray, accel_z: np.ndarray, base_index: int = 0, final: bool = False
    ) -> list[Pulse]:
        """New pulses in the buffered stream (``base_index`` = absolute index of element 0).

        Every sample is examined as it arrives (the tests are causal: a sample is compared with
        the samples before it and the noise of an earlier block), except that, unless ``final``,
        a sample over the threshold whose pulse is not yet fully in the buffer (``max_contact_s``
        of samples after it) stops the scan there until it is. So :attr:`cursor` is "every
        sample before this is decided": it stays at the newest sample on a quiet beam instead of
        ``max_contact_s`` behind it, and the pulses found never depend on the chunking.
        """
        n = accel_z.size
        if n < 8 or (n < PERIOD_SAMPLES and not final):
            return []
        if self.period_s is None:
            # Read once from the first samples and kept: the same for any chunking.
            self.period_s = float(np.median(np.diff(stamp_s[:PERIOD_SAMPLES])))
        period = self.period_s
        baseline, block, span = self.geometry(period)
        self.spans = [span for span in self.spans if span[1] >= base_index]
        self._sigma_cache = {k: v for k, v in self._sigma_cache.items() if k >= base_index}
        mask = np.zeros(n, dtype=bool)
        for first, last in self.spans:
            mask[first - base_index : last - base_index + 1] = True
        if n < baseline + block:
            if not final:
                return []
            block = n - baseline
        stop = n
        start = max(self.cursor - base_index, baseline)
        if stop <= start:
            return []
        residual = self._residual(accel_z, start, stop, baseline)
        # Samples over the plain noise threshold (ringing only raises it): the only candidates
        # outside the few samples after a pulse, which are checked one by one.
        sigma = self._block_sigmas(accel_z, start, stop, baseline, block, base_index)
        candidates = (
            np.flatnonzero(np.abs(residual) > self.config.accel_threshold_sigma * sigma) + start
        )
        pulses: list[Pulse] = []
        k = start
        while k < stop:
            ringing = self._ringing(float(stamp_s[k]), float(sigma[k - start]))
            if ringing:
                run_end = self._ring_run(
                    stamp_s, accel_z, residual, sigma, mask, k, stop, start, baseline
                )
                if run_end > k:
                    k = run_end
                    continue
            dirty = mask[max(k - baseline, 0) : k].any()
            if not dirty and not ringing:
                following = int(np.searchsorted(candidates, k))
                if following == candidates.size:
                    break
                k = int(candidates[following])
                if k >= stop:
                    break
                deviation = residual[k - start]
            elif dirty:
                deviation = accel_z[k] - background_fit(accel_z, k - baseline, k, mask)[0]
            else:
                deviation = residual[k - start]
            noise = sigma[k - start]
            if noise > 0.0 and abs(deviation) > self._threshold(float(stamp_s[k]), noise):
                if not final and k + span + 1 >= n:
                    self.cursor = (
                        base_index + k
                    )  # its pulse is not all in yet: look again from here
                    return pulses
                pulse = self._grow(
                    stamp_s, accel_z, mask, k, baseline, span, noise, period, base_index, ringing
                )
                pulses.append(pulse)
                mask[pulse.first_index - base_index : pulse.last_index - base_index + 1] = True
                self.spans.append((pulse.first_index, pulse.last_index))
                self.ring = (
                    float(stamp_s[pulse.last_index - base_index]),
                    pulse.peak_sigma * noise,
                )
                k = pulse.last_index - base_index + 1
            else:
                if ringing:
                    self._follow_ring(float(stamp_s[k]), abs(deviation))
                k += 1
        self.cursor = base_index + max(k, stop)
        return pulses

    def _ring_run(
        self,
        stamp_s: np.ndarray,
        accel_z: np.ndarray,
        residual: np.ndarray,
        sigma: np.ndarray,
        mask: np.ndarray,
        k: int,
        stop: int,
        start: int,
        baseline: int,
    ) -> int:
        """Follow the ringing over samples ``k``.. at once, as the sample-by-sample walk does
        (each raises the envelope it exceeds), for as long as every sample rings and stays under
        the threshold; returns the first that does not (a pulse, or the ringing is over: the
        walk decides it), ``k`` itself when that is the first. Vectorised: the envelope before
        each sample is a running maximum of |deviation| exp(t / ring_decay_s)."""
        c = self.config
        stamp0, level0 = self.ring  # type: ignore[misc]
        t0 = float(stamp_s[k])
        end = k + int(
            np.searchsorted(stamp_s[k:stop], t0 + RING_RUN_DECAYS * c.ring_decay_s, side="right")
        )
        t = stamp_s[k:end]
        deviation = residual[k - start : end - start].copy()
        lo = max(
            k - baseline, 0
        )  # masked samples in the baseline before each of the run's samples
        masked = np.concatenate([[0], np.cumsum(mask[lo:end])])
        rows = np.arange(k, end)
        dirty = masked[rows - lo] - masked[np.maximum(rows - baseline, 0) - lo] > 0
        if dirty.any():
            deviation[dirty] = accel_z[rows[dirty]] - background_values(
                accel_z, rows[dirty], baseline, mask
            )
        magnitude = np.abs(deviation)
        growth = np.exp((t - t0) / c.ring_decay_s)
        # Envelope in units of exp(t / ring_decay_s) after t0: entry 0 the state before k.
        candidate = np.concatenate(
            [[level0 * math.exp((stamp0 - t0) / c.ring_decay_s)], magnitude * growth]
        )
        running = np.maximum.accumulate(candidate)
        raises = candidate > np.concatenate([[-math.inf], running[:-1]])
        setter = np.maximum.accumulate(np.where(raises, np.arange(candidate.size), 0))
        before = running[:-1] / growth  # decayed envelope before each sample, m/s^2
        since = (
            t - np.concatenate([[stamp0], t])[setter[:-1]]
        )  # since the envelope was last raised, s
        noise = sigma[k - start : end - start]
        ringing = (since < c.ring_window_s) | (
            self.ring_fraction * before > c.accel_threshold_sigma * noise
        )
        over = (noise > 0.0) & (
            magnitude > np.maximum(c.accel_threshold_sigma * noise, self.ring_fraction * before)
        )
        halt = np.flatnonzero(over | ~ringing)
        r = int(halt[0]) if halt.size else end - k
        if r == 0:
            return k
        last = int(setter[r])
        if last > 0:
            self.ring = (float(t[last - 1]), float(magnitude[last - 1]))
        return k + r

    def _ringing(self, stamp_s: float, sigma: float) -> bool:
        """Whether the beam still rings from the last pulse: within ``ring_window_s`` of it, or
        for as long as the envelope followed on the samples themselves still stands above the
        noise threshold. A support whose bending mode is lighter damped than the shipped one
        rings for longer, and the detector learns that from its own samples instead of taking
        the ringing for new impacts once a fixed window is over."""
        if self.ring is None:
            return False
        stamp, level = self.ring
        if stamp_s - stamp < self.config.ring_window_s:
            return True
        decayed = level * math.exp(-(stamp_s - stamp) / self.config.ring_decay_s)
        return self.ring_fraction * decayed > self.config.accel_threshold_sigma * sigma

    def _threshold(self, stamp_s: float, sigma: float) -> float:
        """Detection threshold (m/s^2): the noise's, raised while the beam's bending modes
        ring after a pulse to ``ring_fraction`` times their envelope, which decays with
        ``ring_decay_s`` and follows every ringing sample (ringing is not a new impact)."""
        c = self.config
        threshold = c.accel_threshold_sigma * sigma
        if self.ring is not None:
            stamp, level = self.ring
            threshold = max(
                threshold,
                self.ring_fraction * level * math.exp(-(stamp_s - stamp) / c.ring_decay_s),
            )
        return threshold

    def _follow_ring(self, stamp_s: float, magnitude: float) -> None:
        """Raise the ringing envelope to a sample's deviation (m/s^2) if it exceeds it."""
        stamp, level = self.ring  # type: ignore[misc]
        decayed = level * math.exp(-(stamp_s - stamp) / self.config.ring_decay_s)
        if magnitude > decayed:
            self.ring = (stamp_s, magnitude)

    def _pulse_background(
        self,
        stamp_s: np.ndarray,
        accel_z: np.ndarray,
        lo: int,
        baseline: int,
        mask: np.ndarray,
        period: float,
    ) -> Callable[[np.ndarray], np.ndarray]:
        """The background a pulse's samples (from ``lo`` on) are compared with, as a function of
        sample index: a constant plus the beam's free sway (cosine and sine at its frequency)
        fitted over ``sway_window_s`` before ``lo``. After a large impact the beam sways for
        seconds; within the look-back and the contact the sway curves, and a straight line
        fitted before it leaves it by many noise RMS (an onset a sample or more early), while a
        quadratic extrapolates the noise too far. Without a known sway frequency, or too few
        clean samples: a straight line over the baseline window."""
        c = self.config
        reach = max(baseline, int(round(c.sway_window_s / period)))
        start = max(lo - reach, 0)
        keep = ~mask[start:lo]
        if self.sway_frequency_hz is not None and keep.sum() >= SWAY_FIT_MIN_SAMPLES:
            omega = 2.0 * math.pi * self.sway_frequency_hz
            t = stamp_s[start:lo][keep] - stamp_s[lo]
            basis = np.vstack([np.ones_like(t), np.cos(omega * t), np.sin(omega * t)]).T
            coeffs, *_ = np.linalg.lstsq(basis, accel_z[start:lo][keep], rcond=None)

            def sway(index: np.ndarray) -> np.ndarray:
                tau = (index - lo) * period
                return (
                    coeffs[0] + coeffs[1] * np.cos(omega * tau) + coeffs[2] * np.sin(omega * tau)
                )

            return sway
        line = background_fit(accel_z, lo - baseline, lo, mask, max_degree=1)
        return lambda index: line[0] + line[1] * (index - lo)

    def _grow(
        self,
        stamp_s: np.ndarray,
        accel_z: np.ndarray,
        mask: np.ndarray,
        k: int,
        baseline: int,
        span: int,
        sigma: float,
        period: float,
        base_index: int,
        ringing: bool = False,
    ) -> Pulse:
        """The whole deviating run of samples from its first over-threshold sample ``k``; while
        the beam still ``ringing`` from an earlier pulse, with ``onset_past_ringing``, its onset
        is read past that ringing (:func:`onset_after_ringing`)."""
        c = self.config
        # The contact may have begun earlier, below the detection threshold (the bending modes
        # can build the response up over several samples): look back ``onset_lookback_s``
        # against a straight line fitted before that (a quadratic would extrapolate the noise
        # too far) for the first sample past onset_threshold_sigma.
        lookback = max(ONSET_LOOKBACK_MIN_SAMPLES, int(round(c.onset_lookback_s / period)))
        lo = max(k - lookback, baseline)
        while mask[lo - baseline : k].any() and lo < k:
            lo += 1
        background = self._pulse_background(stamp_s, accel_z, lo, baseline, mask, period)
        before = accel_z[lo : k + 1] - background(np.arange(lo, k + 1))
        past = np.abs(before) > c.onset_threshold_sigma * sigma
        first = lo + int(np.argmax(past)) if past.any() else k
        if ringing and c.onset_past_ringing:
            least = max(2, math.ceil(ONSET_PAST_RINGING_MIN_S / period - 1e-9))
            first = onset_after_ringing(before, past, first - lo, least) + lo
        # At least up to k: at a slow rate (1 kHz and under) the look-back can reach further
        # back than a contact spans, and a run cut off before k sent the walk backwards.
        end = min(max(first + span, k + 1), accel_z.size)
        deviation = accel_z[first:end] - background(np.arange(first, end))
        # The run ends before the first sample after ``first`` that is back within
        # extend_threshold_sigma or already another pulse's; it reaches at least the sample that
        # set the detection off: an early sample past the onset threshold does not cut the
        # contact itself off.
        following = np.arange(first + 1, end)
        ends_run = (following > k) & (
            (np.abs(deviation[1:]) <= c.extend_threshold_sigma * sigma) | mask[first + 1 : end]
        )
        stops = np.flatnonzero(ends_run)
        last = int(following[stops[0]]) - 1 if stops.size else end - 1
        weight = np.abs(deviation[: last - first + 1])
        times = (
            stamp_s[first : last + 1] - 0.5 * period
        )  # middle of each sample's averaging period
        centre = float(np.sum(weight * times) / weight.sum())
        variance = float(np.sum(weight * (times - centre) ** 2) / weight.sum())
        return Pulse(
            onset_s=float(stamp_s[first] - 0.5 * period),
            first_stamp_s=float(stamp_s[first]),
            polarity=1 if deviation[0] < 0.0 else -1,
            width_s=math.sqrt(max(variance, 0.0)),
            peak_sigma=float(weight.max() / sigma),
            noise_mps2=sigma,
            period_s=period,
            first_index=base_index + first,
            last_index=base_index + last,
        )


def onset_after_ringing(
    before: np.ndarray, past: np.ndarray, first: int, least: int = 1
) -> int:
    """The onset's index in the look-back (``before``: deviations from the background up to
    the sample that set the detection off, its last; ``past``: those beyond the onset
    threshold) given the first beyond it, ``first``, for a pulse found while the beam rings
    from an earlier one. When samples beyond the threshold on the other side than the
    detection's lie before it, that ringing, not this contact, crosses the threshold there:
    the onset is then the start of the last run of samples beyond the threshold on the
    detection's side, the run that reaches the detection, not the ringing's first lobe in the
    look-back, if that is at least ``least`` samples later. (A sample or two on the other side
    just before the run is the contact's own response opening there, as it may where the
    accelerometer sits near a node of the rigid response; and on a quiet beam the look-back is
    left as it is.)"""
    side = np.sign(before[-1])
    other = past & (np.sign(before) == -side)
    if not other.any():
        return first
    same = past & (np.sign(before) == side)
    outside = np.flatnonzero(~same)
    run_start = int(outside[-1]) + 1 if outside.size else 0
    return run_start if run_start - first >= least else first
