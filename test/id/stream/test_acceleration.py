"""PlateNormalAcceleration (tail_beam_id.stream.acceleration): each acceleration channel along
the plate normal the right way up, its mounting sign read once."""

from __future__ import annotations

import numpy as np
import pytest

from tail_beam_id.stream.acceleration import (
    IMU_MOUNT_SAMPLES,
    VIBRATION_MOUNT_SAMPLES,
    PlateNormalAcceleration,
)
from tail_beam_id.stream.channels import SensorChannels
from tail_beam_id.stream.config import IdentifierConfig

GRAVITY_MPS2 = 9.81


@pytest.fixture
def channels(params):
    """Empty channels with the shipped identification section."""
    return SensorChannels(IdentifierConfig.from_params(params["identification"]))


@pytest.mark.parametrize("mounted", [1.0, -1.0])
def test_the_imu_sign_is_read_from_gravity_once_there_are_enough_samples(channels, mounted):
    """Fewer than IMU_MOUNT_SAMPLES samples: no answer; then the sign of gravity's median, and
    z comes out +g at rest either way up."""
    acceleration = PlateNormalAcceleration(channels, GRAVITY_MPS2)
    n = IMU_MOUNT_SAMPLES - 1
    accel = np.tile([0.0, 0.0, mounted * GRAVITY_MPS2], (n, 1))
    channels.add_imu(np.arange(n) * 1e-3, np.zeros((n, 3)), accel)
    channels.update(final=False)
    assert acceleration.imu_z() is None and acceleration.mount_sign is None
    channels.add_imu(np.array([n * 1e-3]), np.zeros((1, 3)), accel[:1])
    channels.update(final=False)
    assert np.allclose(acceleration.imu_z(), GRAVITY_MPS2)
    assert acceleration.mount_sign == mounted
    assert acceleration.imu_inverted == (mounted < 0)


def test_an_accelerometer_upside_down_reads_the_right_way_up(channels):
    """A DC-coupled accelerometer reading -g has sign -1 and its column comes out +g."""
    acceleration = PlateNormalAcceleration(channels, GRAVITY_MPS2)
    n = VIBRATION_MOUNT_SAMPLES
    channels.add_vibration(np.arange(n) * 1e-4, np.full(n, -GRAVITY_MPS2))
    channels.update(final=False)
    assert np.allclose(acceleration.vibration_z(), GRAVITY_MPS2)
    assert acceleration.vibration_mount_sign == -1.0 and acceleration.vibration_inverted


def test_an_ac_coupled_accelerometer_without_an_imu_is_taken_as_configured(channels):
    """No gravity and no IMU: no sign while the IMU may yet come, then +1 once
    stream_timeout_s of accelerometer data have passed without one."""
    acceleration = PlateNormalAcceleration(channels, GRAVITY_MPS2)
    n = VIBRATION_MOUNT_SAMPLES
    channels.add_vibration(np.arange(n) * 1e-4, np.zeros(n))
    channels.update(final=False)
    assert acceleration.vibration_z() is None
    timeout_s = channels.config.stream_timeout_s
    channels.add_vibration(np.array([timeout_s + 1e-3]), np.zeros(1))
    channels.update(final=False)
    assert acceleration.vibration_z() is not None
    assert acceleration.vibration_mount_sign == 1.0
