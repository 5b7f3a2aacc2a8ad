"""CameraFrame (tail_beam_id.stream.camera_frame): the camera's frame period as configured,
measured from the rebound stamps, or read by self-calibration."""

from __future__ import annotations

import pytest

from tail_beam_id.stream.camera_frame import (
    CameraFrame,
    configured_frame_period_s,
    profile_frame_period_s,
)
from tail_beam_sim.errors import InputError


def test_the_frame_periods_come_from_the_rates_in_hz():
    """sensors.camera_frame_rate_hz gives the configured period and
    calibration.camera_frame_rate_hz the measured one; absent, none; a rate no camera has
    (0, below 1 Hz, text, NaN) is refused naming the field, in either place."""
    assert configured_frame_period_s({"sensors": {"camera_frame_rate_hz": 5000.0}}) == 2e-4
    assert configured_frame_period_s({}) is None
    assert profile_frame_period_s({"calibration": {"camera_frame_rate_hz": 1000.0}}) == 1e-3
    assert profile_frame_period_s({"calibration": {"camera_frame_rate_hz": None}}) is None
    for rate in ("fast", 0.0, 1e-300, float("nan")):
        with pytest.raises(InputError, match="sensors.camera_frame_rate_hz"):
            configured_frame_period_s({"sensors": {"camera_frame_rate_hz": rate}})
        with pytest.raises(InputError, match="calibration.camera_frame_rate_hz"):
            profile_frame_period_s({"calibration": {"camera_frame_rate_hz": rate}})


def test_a_camera_measured_fast_by_self_calibration_is_not_slower():
    """With no stamps measured yet, a profile's fast frame (5 kHz) says the camera is not
    slower than known; without a profile it may be; recalibrate takes the profile's."""
    camera = CameraFrame({"sensors": {"camera_frame_rate_hz": 5000.0}})
    assert camera.period_at(1.0) == pytest.approx(2e-4)
    assert camera.may_be_slower(1.0)
    camera.recalibrate({"calibration": {"camera_frame_rate_hz": 5000.0}})
    assert camera.profile_frame_s == pytest.approx(2e-4)
    assert not camera.may_be_slower(1.0)
