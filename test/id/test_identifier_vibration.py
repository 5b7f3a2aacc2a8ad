"""A high-rate tail-beam accelerometer (StreamIdentifier.add_vibration): while it is fed it is
the acceleration channel for pulse detection and the IMU impulse; without it nothing changes."""

from __future__ import annotations

import numpy as np
import pytest

from id_helpers import impact
from tail_beam_id.identifier import StreamIdentifier
from tail_beam_id.replay import replay

VIBRATION_RATE_HZ = 20000.0
DECIMATION = 10  # the IMU at 2 kHz: the mean of every 10 vibration samples


@pytest.fixture(scope="module")
def fast_impact(params):
    """One 40 mm sandstone impact with the accelerometer sampled at 20 kHz."""
    return impact(params, material="sandstone", radius_m=0.04, seed=21, sensors={"imu_rate_hz": VIBRATION_RATE_HZ})


def _slow_imu(imu):
    """The 20 kHz IMU averaged over blocks of DECIMATION samples, stamped at each block's end:
    what a 2 kHz IMU reporting the mean specific force over its period gives."""
    n = imu.stamp_s.size // DECIMATION * DECIMATION
    stamps = imu.stamp_s[DECIMATION - 1:n:DECIMATION]
    gyro = imu.angular_velocity_radps[:n].reshape(-1, DECIMATION, 3).mean(axis=1)
    accel = imu.linear_acceleration_mps2[:n].reshape(-1, DECIMATION, 3).mean(axis=1)
    return stamps, gyro, accel


def _feed(identifier, result, slow, vibration_until_s=np.inf, chunk_s=0.01):
    """Deliver pressure, the 2 kHz IMU, the vibration stream (up to ``vibration_until_s``) and
    the rebound in chunks of stamp time, polling after each; then flush."""
    stamps, gyro, accel = slow
    vib_t = result.imu.stamp_s
    vib_a = result.imu.linear_acceleration_mps2[:, 2]
    labels = []
    edges = np.arange(0.0, max(stamps[-1], result.pressure.stamp_s[-1]) + 2 * chunk_s, chunk_s)
    rebound_sent = False
    for low, high in zip(edges[:-1], edges[1:]):
        take = (result.pressure.stamp_s >= low) & (result.pressure.stamp_s < high)
        identifier.add_pressure(result.pressure.stamp_s[take], result.pressure.pressure_pa[take])
        take = (stamps >= low) & (stamps < high)
        identifier.add_imu(stamps[take], gyro[take], accel[take])
        take = (vib_t >= low) & (vib_t < high) & (vib_t <= vibration_until_s)
        if take.any():
            identifier.add_vibration(vib_t[take], vib_a[take])
        if not rebound_sent and result.rebound.stamp_s < high:
            identifier.add_rebound(result.rebound.stamp_s, result.rebound.velocity_mps)
            rebound_sent = True
        labels += identifier.poll()
    return labels + identifier.flush()


def test_vibration_stream_is_the_acceleration_channel(params, fast_impact):
    """With the 20 kHz vibration stream fed beside a 2 kHz IMU, the one impact is detected and
    its impulse measured in the vibration stream: signals name it, the pulse period is its."""
    labels = _feed(StreamIdentifier("statistical", params["identification"], params), fast_impact, _slow_imu(fast_impact.imu))
    assert len(labels) == 1
    label = labels[0]
    assert label["signals"] == ["jack_pressure", "vibration", "rebound_velocity"]
    assert label["features"]["imu_period_s"] == pytest.approx(1.0 / VIBRATION_RATE_HZ, rel=1e-6)
    assert label["label"] == "gangue"
    # The 20 kHz channel places the onset within one of its periods and a half of the contact.
    assert abs(label["impact_stamp"] - fast_impact.contact_stamp_s) < 1.5 / VIBRATION_RATE_HZ


def test_without_vibration_the_imu_is_the_channel(params, fast_impact):
    """The same streams without the vibration: the IMU's 2 kHz accel z detects the impact and
    the label is the one the plain replay of pressure, IMU and camera gives."""
    slow = _slow_imu(fast_impact.imu)
    labels = _feed(StreamIdentifier("statistical", params["identification"], params), fast_impact, slow, vibration_until_s=-1.0)
    assert len(labels) == 1
    assert labels[0]["signals"] == ["jack_pressure", "imu", "rebound_velocity"]
    assert labels[0]["features"]["imu_period_s"] == pytest.approx(1.0 / (VIBRATION_RATE_HZ / DECIMATION), rel=1e-6)
    from tail_beam_sim.physics.sensors import ImuStream

    imu = ImuStream(slow[0], slow[1], slow[2], 0.0, 0.0)
    plain = replay(StreamIdentifier("statistical", params["identification"], params), fast_impact.pressure, imu, [fast_impact.rebound])
    assert [(l["impact_stamp"], l["label"], l["confidence"]) for l in labels] == [(l["impact_stamp"], l["label"], l["confidence"]) for l in plain]


def test_vibration_stopping_hands_back_to_the_imu(params, fast_impact):
    """The vibration stream ending well before the impact is declared stopped (it lags the
    others by more than stream_timeout_s); the impact is then detected in the IMU."""
    until = fast_impact.contact_stamp_s - 0.1
    labels = _feed(StreamIdentifier("statistical", params["identification"], params), fast_impact, _slow_imu(fast_impact.imu), vibration_until_s=until)
    assert len(labels) == 1
    assert "imu" in labels[0]["signals"] and "vibration" not in labels[0]["signals"]
    assert abs(labels[0]["impact_stamp"] - fast_impact.contact_stamp_s) < 1e-3


def test_vibration_with_mismatched_lengths_is_refused(params):
    """One value per stamp, or a clear InputError naming the field."""
    from tail_beam_sim.errors import InputError

    identifier = StreamIdentifier("threshold", params["identification"], params)
    with pytest.raises(InputError, match="vibration"):
        identifier.add_vibration(np.arange(3) * 1e-4, np.zeros(2))
