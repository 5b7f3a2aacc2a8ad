"""Whether two simulation results agree: the group path of simulate_many against simulate.

Their trajectories come from the same arithmetic in another order (arrays over impacts, the
free response as products of exponentials), so the float signals agree to rounding: 1e-11 of
each signal's largest magnitude (the IMU's mean accelerations divide velocity differences by
the sample period, which multiplies the velocities' rounding by up to 1e4); the
accelerometer's float32 samples to one float32 rounding; the noise, the stamps, the block
indices and every flag are the same.
"""

from __future__ import annotations

import math

import numpy as np

SIGNAL_TOLERANCE = 1e-11  # of the signal's largest magnitude


def assert_same_signal(got: np.ndarray, expected: np.ndarray, name: str = "") -> None:
    got, expected = np.asarray(got), np.asarray(expected)
    assert got.shape == expected.shape and got.dtype == expected.dtype, name
    if expected.dtype == np.float32:
        np.testing.assert_allclose(got, expected, rtol=2.0**-23, atol=0.0, err_msg=name)
        return
    scale = float(np.max(np.abs(expected))) if expected.size else 0.0
    error = float(np.max(np.abs(got - expected), initial=0.0))
    assert error <= SIGNAL_TOLERANCE * scale, f"{name}: {error} of {scale}"


def assert_same_result(got, expected) -> None:
    """``got`` and ``expected`` (SimulationResults of one scene) agree (module docstring)."""
    assert got.contact_stamp_s == expected.contact_stamp_s
    assert got.summary.keys() == expected.summary.keys()
    for key, value in expected.summary.items():
        if isinstance(value, float) and not isinstance(value, bool):
            if math.isnan(value):
                assert math.isnan(got.summary[key]), key
            else:
                assert abs(got.summary[key] - value) <= SIGNAL_TOLERANCE * abs(value), key
        else:
            assert got.summary[key] == value, key
    assert np.array_equal(got.pressure.stamp_s, expected.pressure.stamp_s)
    assert_same_signal(got.pressure.pressure_pa, expected.pressure.pressure_pa, "pressure")
    assert np.array_equal(got.imu.stamp_s, expected.imu.stamp_s)
    assert_same_signal(got.imu.angular_velocity_radps, expected.imu.angular_velocity_radps, "gyro")
    assert_same_signal(
        got.imu.linear_acceleration_mps2, expected.imu.linear_acceleration_mps2, "accel"
    )
    assert np.array_equal(got.vibration.first_index, expected.vibration.first_index)
    assert np.array_equal(got.vibration.stamp_s, expected.vibration.stamp_s)
    assert_same_signal(got.vibration.accel_mps2, expected.vibration.accel_mps2, "vibration")
    assert got.rebound.stamp_s == expected.rebound.stamp_s
    assert_same_signal(got.rebound.velocity_mps, expected.rebound.velocity_mps, "rebound")
    assert [c.start_s for c in got.trajectory.contacts] == [
        c.start_s for c in expected.trajectory.contacts
    ]
    assert got.history.keys() == expected.history.keys()
    for key, values in expected.history.items():
        assert_same_signal(got.history[key], values, key)
