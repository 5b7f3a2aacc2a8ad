"""StreamIdentifier as a coordinator: the attributes callers read are its parts' own state, and
recalibrate hands a measured support to every part that reads it."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from tail_beam_id.signals.timing import TimingConfig
from tail_beam_id.stream.config import LOOK_BACKS_KEPT
from tail_beam_id.stream.decision import profile_says_timing_suspect
from tail_beam_id.stream.detection import scanned_s
from tail_beam_id.stream.identifier import StreamIdentifier


def test_the_attributes_callers_read_are_the_parts_state(params):
    """Buffers, detectors, outages, signs, the method and the timing verdict read through the
    identifier are the very objects its parts hold, so a caller sees them change."""
    identifier = StreamIdentifier("statistical", params["identification"], params)
    assert identifier.pressure is identifier.channels.pressure
    assert identifier.imu is identifier.channels.imu
    assert identifier.vibration is identifier.channels.vibration
    assert identifier.imu_outages is identifier.channels.imu_outages
    assert identifier.vibration_outages is identifier.channels.vibration_outages
    assert identifier.refused_samples is identifier.channels.refused_samples
    assert identifier.detector is identifier.finder.imu_detector
    assert identifier.vibration_detector is identifier.finder.vibration_detector
    assert identifier.pressure_detector is identifier.finder.pressure_detector
    assert identifier.method is identifier.decider.method
    assert identifier.timing is identifier.decider.timing
    assert identifier.camera is identifier.camera_frame.frame_period
    identifier.add_pressure(np.array([0.0, np.nan]), np.array([20e6, 20e6]))
    assert identifier.refused_samples["jack_pressure"] == 1
    assert identifier.mount_sign is None and identifier.vibration_mount_sign is None


def test_recalibrate_reaches_every_part_that_reads_the_support(params):
    """A profile with another gravity, ring decay, camera frame and a slow bending mode: the
    detectors, the pressure detector, the decider, the mounting, the camera knowledge and the
    accelerometer's data window all take it, and the identifier then says calibrated."""
    identifier = StreamIdentifier("statistical", params["identification"], params)
    assert not identifier.calibrated and identifier.profile_frame_s is None
    merged = copy.deepcopy(params)
    merged["support"]["gravity_mps2"] = 9.79
    merged["calibration"] = {
        "rigid_mode_frequency_hz": 3.0,
        "camera_frame_rate_hz": 2000.0,
        "ringing_modes_hz": [150.0],
        "ringing_damping_ratios": [0.02],
    }
    ring_decay_s = 0.123
    merged["identification"]["detection"]["ring_decay_s"] = ring_decay_s
    identifier.recalibrate(merged)
    assert identifier.calibrated
    assert identifier.profile_frame_s == pytest.approx(5e-4)
    for detector in (identifier.detector, identifier.vibration_detector):
        assert detector.config.ring_decay_s == ring_decay_s
        assert detector.sway_frequency_hz == identifier.model.support.rigid_mode_frequency_hz
    assert identifier.pressure_detector.model is identifier.model is identifier.decider.model
    assert identifier.model.support.gravity_mps2 == identifier.acceleration.gravity_mps2 == 9.79
    # the accelerometer's window: the configured periods of the profile's 150 Hz mode, within
    # vibration_window_s .. window_s
    section = params["identification"]
    periods_s = section["vibration_window_mode_periods"] / 150.0
    expected = min(section["window_s"], max(section["vibration_window_s"], periods_s))
    assert expected > section["vibration_window_s"]  # the profile's mode is what moved it
    assert identifier.impacts.vibration_window_s == pytest.approx(expected)


def test_a_profile_counts_timing_suspect_only_from_whole_counts():
    """profile_says_timing_suspect: no verdict without the profile's two integer counts; with
    them, the timing rule's."""
    config = TimingConfig.from_params({})
    assert not profile_says_timing_suspect({}, config)
    counts = {"delay_checked_impacts": 40, "delay_unusual_impacts": 40}
    assert profile_says_timing_suspect({"calibration": counts}, config)
    counts = {"delay_checked_impacts": 40.0, "delay_unusual_impacts": 40}
    assert not profile_says_timing_suspect({"calibration": counts}, config)


def test_a_fresh_detector_has_scanned_nothing_and_retention_keeps_four_look_backs(params):
    """scanned_s is -inf before the detector has looked at a sample; retention keeps
    LOOK_BACKS_KEPT times the longest look-back (noise block, the longest background stretch
    with the data window) before what is needed."""
    identifier = StreamIdentifier("statistical", params["identification"], params)
    assert scanned_s(identifier.imu, identifier.detector) == float("-inf")
    config = identifier.config
    longest_s = max(config.pressure_background_s, config.impulse_background_s)
    expected_s = LOOK_BACKS_KEPT * max(config.detection.noise_block_s, longest_s + config.window_s)
    assert identifier.retention.keep_s() == pytest.approx(expected_s)
