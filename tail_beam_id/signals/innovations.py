"""The accelerometer's ringing predicted from the samples before: what is new in each sample.

A lightly damped beam rings for a tenth of a second after an impact, and a pulse detector that
compares each sample with a smooth extrapolation and the ringing's envelope loses the pulses of
smaller lumps that strike meanwhile. The free ringing of every mode is a linear recursion of
the samples before it, so a one-step linear predictor of order p (two per mode, and some to
spare for the sensor's filter) fitted on the support's own recording predicts it; what it does
not predict, the prediction error, is the noise and each new contact. A detector scanning the
prediction errors instead of the samples finds pulses inside another impact's ringing.

Pure numpy/scipy: no ROS.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

ORDER = 8  # the predictor's order: four modes' pole pairs
MIN_SAMPLES_PER_COEFFICIENT = 50  # samples a fit needs per coefficient
ROBUST_REFIT_SIGMA = 4.0  # the refit leaves out samples predicted worse than this, noise RMS
MAX_FIT_SAMPLES = 2**19  # a fit reads at most this many samples (20 s at 25.6 kHz)


def _robust_rms(values: np.ndarray) -> float:
    """RMS from the median absolute deviation (a few pulses do not move it)."""
    return 1.4826 * float(np.median(np.abs(values - np.median(values))))


def fit_predictor(accel: np.ndarray, order: int = ORDER) -> np.ndarray | None:
    """The coefficients a_1..a_order of the one-step predictor x[n] ~ sum_k a_k x[n - k] of
    ``accel`` (evenly sampled, finite), least squares over the recording, then again without
    the samples it predicted worse than ROBUST_REFIT_SIGMA x the errors' robust RMS (the
    contacts themselves), over the first MAX_FIT_SAMPLES samples at most. None when the
    recording is too short for the order."""
    x = np.asarray(accel, dtype=float)[:MAX_FIT_SAMPLES]
    if order < 1 or x.size < MIN_SAMPLES_PER_COEFFICIENT * order + order:
        return None
    lagged = np.stack([x[order - k - 1 : x.size - k - 1] for k in range(order)], axis=1)
    target = x[order:]
    rows: np.ndarray | slice = slice(None)
    coefficients = np.zeros(order)
    for _ in range(2):
        coefficients, *_ = np.linalg.lstsq(lagged[rows], target[rows], rcond=None)
        errors = target - lagged @ coefficients
        rms = _robust_rms(errors)
        if not rms > 0.0:
            break
        rows = np.abs(errors - np.median(errors)) < ROBUST_REFIT_SIGMA * rms
    return coefficients if np.all(np.isfinite(coefficients)) else None


def prediction_errors(accel: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """x[n] - sum_k a_k x[n - k] for every sample of ``accel`` (m/s^2); the first ``order``
    samples, whose history is not in ``accel``, take the first full one's error (a flat start
    instead of a transient). Every later sample's error is the same wherever ``accel`` was cut
    before it; the detector looks at no sample that near a trimmed buffer's start (retention
    keeps IdentifierConfig.kept_s before what it needs)."""
    x = np.asarray(accel, dtype=float)
    a = np.asarray(coefficients, dtype=float)
    errors = lfilter(np.concatenate([[1.0], -a]), [1.0], x)
    if x.size > a.size:
        errors[: a.size] = errors[a.size]
    return errors


__all__ = ["ORDER", "fit_predictor", "prediction_errors"]
