"""SensorChannels (tail_beam_id.stream.channels): the three streams' samples taken in, which
of them are live, and the outages of an acceleration channel that stopped and came back."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tail_beam_id.stream.channels import SensorChannels, within_outage
from tail_beam_id.stream.config import IdentifierConfig

PRESSURE_PA = 20e6
GRAVITY_MPS2 = 9.81


@pytest.fixture
def channels(params):
    """Empty channels with the shipped identification section."""
    return SensorChannels(IdentifierConfig.from_params(params["identification"]))


def _imu(channels, stamps_s):
    """IMU samples at rest (+g along z) at ``stamps_s``."""
    accel = np.tile([0.0, 0.0, GRAVITY_MPS2], (stamps_s.size, 1))
    channels.add_imu(stamps_s, np.zeros((stamps_s.size, 3)), accel)


def test_non_finite_samples_are_left_out_and_counted_by_stream(channels):
    """A NaN value or an infinite stamp drops that sample alone and counts it under its stream."""
    channels.add_pressure(np.array([0.0, 0.001, 0.002]), np.array([PRESSURE_PA, np.nan, 1.0]))
    channels.add_vibration(np.array([0.0, np.inf, 0.002]), np.zeros(3))
    channels.update(final=False)
    assert channels.refused_samples == {"jack_pressure": 1, "imu": 0, "vibration": 1}
    assert channels.pressure.stamp_s.tolist() == [0.0, 0.002]
    assert channels.vibration_start_s == 0.0


def test_a_lagging_imu_is_declared_stopped_and_an_outage_recorded_when_it_is_back(channels):
    """The IMU lagging the pressure by more than stream_timeout_s is stopped at its newest
    stamp; samples after it that keep up take it up again from the first new one plus a sway and
    a baseline window, and with no accelerometer the pressure stood in for that stretch."""
    config = channels.config
    step_s = 0.001
    _imu(channels, np.arange(0.0, 0.1, step_s))
    channels.add_pressure(np.arange(0.0, 0.3, step_s), np.full(300, PRESSURE_PA))
    channels.update(final=False)
    stop_s = channels.imu_stop_s
    assert stop_s == pytest.approx(0.099) and channels.accel_stop_s() == stop_s
    assert not channels.live(channels.imu, False) and channels.live(channels.imu, True)
    _imu(channels, np.arange(0.25, 0.3, step_s))
    channels.update(final=False)
    back_s = 0.25 + config.detection.sway_window_s + config.detection.baseline_window_s
    assert channels.imu_stop_s == math.inf
    assert channels.imu_outages == [(stop_s, pytest.approx(back_s))]
    assert channels.pressure_outages == channels.imu_outages


def test_the_vibration_stream_is_the_acceleration_channel_while_it_is_live(channels):
    """Fed and keeping up, the accelerometer is the channel in use; once it lags by more than
    stream_timeout_s it is declared stopped and the IMU is the channel again."""
    _imu(channels, np.arange(0.0, 0.05, 0.001))
    channels.add_vibration(np.arange(0.0, 0.05, 1e-4), np.zeros(500))
    channels.update(final=False)
    assert channels.acceleration_in_use() is channels.vibration
    _imu(channels, np.arange(0.05, 0.2, 0.001))
    channels.update(final=False)
    assert channels.vibration_stop_s == pytest.approx(0.0499)
    assert channels.acceleration_in_use() is channels.imu


def test_samples_are_forgotten_only_past_the_slack(channels):
    """forget_before trims a stream once its oldest sample lies more than the slack before the
    stamp needed, and then keeps everything from that stamp on."""
    channels.add_pressure(np.arange(0.0, 1.0, 0.01), np.full(100, PRESSURE_PA))
    channels.update(final=False)
    channels.forget_before(0.5, 0.6)
    assert channels.pressure.stamp_s[0] == 0.0
    channels.forget_before(0.5, 0.4)
    assert channels.pressure.stamp_s[0] == pytest.approx(0.5)
    assert channels.pressure.base_index == 50


def test_an_outage_is_open_at_both_ends():
    """within_outage: strictly between the stop and the stamp the channel counts again."""
    outages = [(1.0, 1.3)]
    assert within_outage(outages, 1.1)
    assert not within_outage(outages, 1.0) and not within_outage(outages, 1.3)
    assert not within_outage([], 1.1)
