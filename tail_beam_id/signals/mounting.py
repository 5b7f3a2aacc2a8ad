"""Which way up the tail-beam accelerometer is bolted, read from the recording itself.

Upside down, it reads every pulse with the opposite sign, and the models read a pulse's
polarity and ringing, so an accelerometer read the wrong way up gives confident wrong labels.
Two ways to tell, tried in this order:

* gravity: a DC-coupled sensor at rest reads +g the right way up, -g upside down;
* the IMU beside it (already read the right way up from its own gravity): a piezoelectric
  (AC-coupled) accelerometer sees no gravity, but once the beam moves it moves with the IMU's z.
  Both are averaged over each IMU period and smoothed, and their correlation's sign, once clear
  on a block of the recording where the beam moved, is the mounting's.
"""

from __future__ import annotations

import numpy as np

GRAVITY_FRACTION = (
    0.5  # a median reading beyond this x g (either sign) is gravity: the sensor is DC-coupled
)
BLOCK_S = 0.25  # the stretch of recording each IMU comparison looks at, s
SMOOTH_S = (
    0.005  # moving average before the comparison (the sway and the low modes, not the ringing), s
)
MIN_CORRELATION = 0.6  # |correlation| that settles the sign
MOTION_NOISE_RATIO = (
    10.0  # the IMU's smoothed z must swing this many times its noise RMS (the beam moved)
)
# of accelerometer data without an answer (no IMU, or a beam that never moved): as configured
GIVE_UP_S = 10.0


def sign_from_gravity(first_mps2: np.ndarray, gravity_mps2: float) -> float | None:
    """+1 or -1 from the median of the first samples (m/s^2) when it is gravity; None when it
    is near 0 (an AC-coupled sensor: no gravity to read)."""
    median = float(np.median(first_mps2))
    if abs(median) < GRAVITY_FRACTION * gravity_mps2:
        return None
    return 1.0 if median > 0.0 else -1.0


def sign_from_imu(
    vib_stamp_s: np.ndarray,
    vib_mps2: np.ndarray,
    imu_stamp_s: np.ndarray,
    imu_z_mps2: np.ndarray,
    start_s: float,
    end_s: float,
) -> float | None:
    """+1 or -1: the accelerometer's z against the IMU's (the right way up) over [start_s,
    end_s); None when the beam did not move enough there or the two do not clearly agree.

    The accelerometer is averaged over each IMU period (the IMU reports period means), both
    lose their median and are smoothed over ``SMOOTH_S``; their correlation decides."""
    take = (imu_stamp_s >= start_s) & (imu_stamp_s < end_s)
    stamps, imu = imu_stamp_s[take], imu_z_mps2[take]
    if stamps.size < 32:
        return None
    period = float(np.median(np.diff(stamps)))
    # Mean of the accelerometer samples in each IMU period (t - period, t].
    total = np.concatenate([[0.0], np.cumsum(vib_mps2, dtype=float)])
    lo = np.searchsorted(vib_stamp_s, stamps - period, side="right")
    hi = np.searchsorted(vib_stamp_s, stamps, side="right")
    have = hi > lo
    if have.sum() < 32:
        return None
    vib = (total[hi[have]] - total[lo[have]]) / (hi[have] - lo[have])
    imu = imu[have]
    width = max(1, int(round(SMOOTH_S / period)))
    kernel = np.ones(width) / width
    a = np.convolve(vib - np.median(vib), kernel, mode="valid")
    b = np.convolve(imu - np.median(imu), kernel, mode="valid")
    noise = 1.4826 * float(np.median(np.abs(np.diff(imu)))) / np.sqrt(2.0) / np.sqrt(width)
    if (
        a.size < 8
        or np.ptp(b) < MOTION_NOISE_RATIO * max(noise, 1e-12)
        or not (np.std(a) > 0.0 and np.std(b) > 0.0)
    ):
        return None
    correlation = float(np.corrcoef(a, b)[0, 1])
    if abs(correlation) < MIN_CORRELATION:
        return None
    return 1.0 if correlation > 0.0 else -1.0
