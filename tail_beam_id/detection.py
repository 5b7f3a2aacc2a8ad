"""Impact detection in the continuous IMU stream: onsets, pulses, noise and overlap.

A particle's contact lasts 0.1-1 ms, far shorter than the beam's 40 Hz sway, and the IMU
reports the mean specific force over each sample period: the contact shows as a short
negative pulse (the plate is pushed away from the particle) on top of a slow background
(gravity, the beam still ringing from earlier impacts). The detector predicts each sample
from a quadratic fitted to the samples before it, and starts a pulse where the sample falls
below the prediction by ``accel_threshold_sigma`` noise RMS. The noise RMS is a robust (MAD)
estimate over fixed blocks of samples, so that the result depends only on the samples, never
on how they were chunked on arrival.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from tail_beam_sim.errors import require_range

MAD_TO_SIGMA = 1.4826  # median absolute deviation of a Gaussian times this = its RMS


@dataclass(frozen=True)
class DetectionConfig:
    """Detection thresholds (in noise RMS, sigma) and windows (s); see config/identification.yaml."""

    accel_threshold_sigma: float
    extend_threshold_sigma: float
    baseline_window_s: float
    noise_block_s: float
    max_contact_s: float
    rebound_early_tolerance_s: float
    unconfirmed_pulse_sigma: float
    pressure_threshold_sigma: float

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> DetectionConfig:
        """Validate the ``identification.detection`` section."""
        p = params or {}

        def get(name: str, low: float, high: float, unit: str = "") -> float:
            return require_range(f"identification.detection.{name}", p.get(name), low, high, low_open=True, unit=unit)

        return cls(
            accel_threshold_sigma=get("accel_threshold_sigma", 0.0, 1e3),
            extend_threshold_sigma=get("extend_threshold_sigma", 0.0, 1e3),
            baseline_window_s=get("baseline_window_s", 0.0, 1.0, "s"),
            noise_block_s=get("noise_block_s", 0.0, 100.0, "s"),
            max_contact_s=get("max_contact_s", 0.0, 1.0, "s"),
            rebound_early_tolerance_s=get("rebound_early_tolerance_s", 0.0, 1.0, "s"),
            unconfirmed_pulse_sigma=get("unconfirmed_pulse_sigma", 0.0, 1e6),
            pressure_threshold_sigma=get("pressure_threshold_sigma", 0.0, 1e3),
        )


@dataclass(frozen=True)
class Pulse:
    """One contact as the IMU saw it.

    ``onset_s``: start of the first sample period holding the pulse (the contact began at or
    after it); ``centroid_s``: impulse-weighted mean time of the pulse; ``width_s``: RMS
    duration of the pulse beyond the sample averaging's own (0 when it fits in one sample);
    ``impulse_mps``: velocity change of the plate at the IMU, away from the particle, m/s;
    ``peak_sigma``: the deepest sample's deviation in noise RMS; ``noise_mps2``: that RMS;
    ``period_s``: the IMU sample period read from the stamps.
    """

    onset_s: float
    centroid_s: float
    width_s: float
    impulse_mps: float
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


def extrapolation_weights(length: int) -> np.ndarray:
    """Weights w such that w @ y[-length:] is a quadratic least-squares fit's value one step on."""
    x = np.arange(-length, 0, dtype=float)
    basis = np.vstack([np.ones(length), x, x * x]).T
    return np.linalg.pinv(basis)[0]


def background_fit(values: np.ndarray, lo: int, hi: int, excluded: np.ndarray) -> np.ndarray:
    """Quadratic (in sample index, about ``hi``) fitted to values[lo:hi] outside ``excluded``."""
    index = np.arange(lo, hi)
    keep = ~excluded[lo:hi]
    x = (index[keep] - hi).astype(float)
    if x.size < 3:
        return np.array([float(np.mean(values[lo:hi])) if hi > lo else 0.0, 0.0, 0.0])
    basis = np.vstack([np.ones(x.size), x, x * x]).T
    coeffs, *_ = np.linalg.lstsq(basis, values[lo:hi][keep], rcond=None)
    return coeffs


class PulseDetector:
    """Finds contact pulses in one IMU stream's specific force along the plate normal.

    Feed it the whole buffered stream each time (``scan``); it remembers how far it got and
    returns the pulses whose first sample it has now decided on.
    """

    def __init__(self, config: DetectionConfig) -> None:
        self.config = config
        self.cursor = 0  # next sample index (absolute) to examine
        self.spans: list[tuple[int, int]] = []  # absolute (first, last) sample of each pulse found
        self._sigma_cache: dict[int, float] = {}  # noise RMS per block, by its first absolute index

    def geometry(self, period_s: float) -> tuple[int, int, int]:
        """(baseline samples, noise block samples, most samples a pulse spans) at this period."""
        c = self.config
        baseline = max(4, int(round(c.baseline_window_s / period_s)))
        block = max(16, int(round(c.noise_block_s / period_s)))
        span = int(math.ceil(c.max_contact_s / period_s)) + 1
        return baseline, block, span

    def noise(self, accel_z: np.ndarray, k: int, baseline: int, block: int, base_index: int) -> float:
        """Noise RMS for local sample ``k``: MAD of the prediction residuals over the previous
        whole block of samples (the first block for early samples). Blocks are aligned to the
        absolute sample index, so the value never depends on how the stream was chunked."""
        absolute = base_index + k
        start = max((absolute - baseline) // block - 1, 0) * block + baseline
        if start not in self._sigma_cache:
            lo = start - base_index
            self._sigma_cache[start] = robust_sigma(self._residual(accel_z, lo, lo + block, baseline))
        return self._sigma_cache[start]

    @staticmethod
    def _residual(accel_z: np.ndarray, lo: int, hi: int, baseline: int) -> np.ndarray:
        """Residuals of samples lo..hi-1 from the one-step quadratic prediction."""
        windows = np.lib.stride_tricks.sliding_window_view(accel_z[lo - baseline:hi - 1], baseline)
        return accel_z[lo:hi] - windows @ extrapolation_weights(baseline)

    def scan(self, stamp_s: np.ndarray, accel_z: np.ndarray, base_index: int = 0, final: bool = False) -> list[Pulse]:
        """New pulses in the buffered stream (``base_index`` = absolute index of element 0).

        Unless ``final``, only samples whose pulse is fully in the buffer are examined.
        """
        n = accel_z.size
        if n < 8:
            return []
        period = float(np.median(np.diff(stamp_s[-min(n, 64):])))
        baseline, block, span = self.geometry(period)
        self.spans = [span for span in self.spans if span[1] >= base_index]
        self._sigma_cache = {k: v for k, v in self._sigma_cache.items() if k >= base_index}
        mask = np.zeros(n, dtype=bool)
        for first, last in self.spans:
            mask[first - base_index:last - base_index + 1] = True
        if n < baseline + block:
            if not final:
                return []
            block = n - baseline
        stop = n if final else n - span - 1
        start = max(self.cursor - base_index, baseline)
        if stop <= start:
            return []
        residual = self._residual(accel_z, start, stop, baseline)
        pulses: list[Pulse] = []
        c = self.config
        k = start
        while k < stop:
            sigma = self.noise(accel_z, k, baseline, block, base_index)
            if mask[k - baseline:k].any():
                deviation = accel_z[k] - background_fit(accel_z, k - baseline, k, mask)[0]
            else:
                deviation = residual[k - start]
            if sigma > 0.0 and deviation < -c.accel_threshold_sigma * sigma:
                pulse = self._grow(stamp_s, accel_z, mask, k, baseline, span, sigma, period, base_index)
                pulses.append(pulse)
                mask[pulse.first_index - base_index:pulse.last_index - base_index + 1] = True
                self.spans.append((pulse.first_index, pulse.last_index))
                k = pulse.last_index - base_index + 1
            else:
                k += 1
        self.cursor = base_index + max(k, stop)
        return pulses

    def _grow(
        self, stamp_s: np.ndarray, accel_z: np.ndarray, mask: np.ndarray, k: int, baseline: int,
        span: int, sigma: float, period: float, base_index: int,
    ) -> Pulse:
        """The whole pulse around its first over-threshold sample ``k``."""
        c = self.config
        first = k
        coeffs = background_fit(accel_z, k - baseline, k, mask)
        # A pulse may have begun one sample earlier, below the detection threshold.
        if k - 1 - baseline >= 0 and not mask[k - 1]:
            previous = background_fit(accel_z, k - 1 - baseline, k - 1, mask)
            if accel_z[k - 1] - previous[0] < -c.extend_threshold_sigma * sigma:
                first, coeffs = k - 1, previous
        end = min(first + span, accel_z.size)
        x = np.arange(first, end) - first
        predicted = coeffs[0] + coeffs[1] * x + coeffs[2] * x * x
        deviation = accel_z[first:end] - predicted
        last = first
        for j in range(1, deviation.size):
            if deviation[j] >= -c.extend_threshold_sigma * sigma or mask[first + j]:
                break
            last = first + j
        dev = -deviation[: last - first + 1]
        times = stamp_s[first:last + 1] - 0.5 * period  # middle of each sample's averaging period
        weight = np.clip(dev, 0.0, None)
        total = float(weight.sum()) or 1.0
        centroid = float(np.sum(weight * times) / total)
        variance = float(np.sum(weight * (times - centroid) ** 2) / total)
        return Pulse(
            onset_s=float(stamp_s[first] - period),
            centroid_s=centroid,
            width_s=math.sqrt(max(variance, 0.0)),
            impulse_mps=float(dev.sum() * period),
            peak_sigma=float(dev.max() / sigma),
            noise_mps2=sigma,
            period_s=period,
            first_index=base_index + first,
            last_index=base_index + last,
        )
