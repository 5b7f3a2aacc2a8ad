"""Streams another recorder or simulator may hand the identifier: every sample twice (a topic
recorded by two recorders, a replay recorded beside its source), an accelerometer that starts
before or runs without the pressure and the IMU. The identifier must label them as it labels
the plain streams, never fail on them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from id_helpers import impact

from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.replay import replay

VIBRATION_RATE_HZ = 25600.0


@pytest.fixture(scope="module")
def sandstone(params):
    """One 40 mm sandstone impact, with the 25.6 kHz accelerometer."""
    return impact(
        params,
        material="sandstone",
        radius_m=0.04,
        seed=23,
        sensors={"vibration_rate_hz": VIBRATION_RATE_HZ},
    )


def _key(labels):
    """What two runs' labels must agree on: stamp, material, confidence and signals."""
    return [(lab.impact_stamp_s, lab.material, lab.confidence, lab.signals) for lab in labels]


def _twice(stream):
    """The stream with every sample repeated, at the same stamp, next to itself."""
    fields = {f.name: getattr(stream, f.name) for f in dataclasses.fields(stream)}
    return dataclasses.replace(
        stream,
        **{k: np.repeat(v, 2, axis=0) for k, v in fields.items() if isinstance(v, np.ndarray)},
    )


def test_every_sample_repeated_gives_the_labels_of_the_plain_streams(params, sandstone):
    """Each pressure and IMU sample delivered twice with the same stamp (a bag holding a topic
    twice): the repeats are dropped as a repeated stamp is (Series.append), and the labels are
    those of the plain streams (a repeat inside one delivery too: it would give the IMU a
    sample period of 0)."""
    section = params["identification"]
    plain = replay(
        StreamIdentifier("statistical", section, params),
        sandstone.pressure,
        sandstone.imu,
        [sandstone.rebound],
    )
    doubled = replay(
        StreamIdentifier("statistical", section, params),
        _twice(sandstone.pressure),
        _twice(sandstone.imu),
        [sandstone.rebound],
    )
    assert len(plain) == 1
    assert _key(doubled) == _key(plain)


def test_an_accelerometer_alone_is_identified(params, sandstone):
    """The accelerometer's blocks and the camera, no jack pressure and no IMU (a support
    instrumented with those two): the accelerometer finds the impact, as id_node's live
    identifier does (replay takes its span from the accelerometer too), not the camera
    alone."""
    section = params["identification"]
    labels = replay(
        StreamIdentifier("statistical", section, params),
        None,
        None,
        [sandstone.rebound],
        vibration=sandstone.vibration,
    )
    assert len(labels) == 1
    assert labels[0].signals == ("vibration", "rebound_velocity")


def test_accelerometer_samples_outside_the_pressure_and_imu_span_are_fed(params, sandstone):
    """An accelerometer that runs on after the pressure and IMU stopped (their recording cut
    short of the impact) still has its samples fed: the impact after their end is found on
    it."""
    section = params["identification"]
    contact = sandstone.contact_stamp_s
    cut = sandstone.pressure.stamp_s < contact - 0.05
    pressure = dataclasses.replace(
        sandstone.pressure,
        stamp_s=sandstone.pressure.stamp_s[cut],
        pressure_pa=sandstone.pressure.pressure_pa[cut],
    )
    keep = sandstone.imu.stamp_s < contact - 0.05
    imu = dataclasses.replace(
        sandstone.imu,
        stamp_s=sandstone.imu.stamp_s[keep],
        angular_velocity_radps=sandstone.imu.angular_velocity_radps[keep],
        linear_acceleration_mps2=sandstone.imu.linear_acceleration_mps2[keep],
    )
    labels = replay(
        StreamIdentifier("statistical", section, params),
        pressure,
        imu,
        [sandstone.rebound],
        vibration=sandstone.vibration,
    )
    assert [label.signals for label in labels] == [("vibration", "rebound_velocity")]
    assert abs(labels[0].impact_stamp_s - contact) < float(section["match_tolerance_s"])
