"""Which way up the tail-beam accelerometer is bolted (tail_beam_id.signals.mounting): from
gravity, or, for a piezoelectric (AC-coupled) sensor that sees none, from the IMU beside it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from id_helpers import stream_chunk

from tail_beam_id.signals.mounting import sign_from_gravity, sign_from_imu
from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.replay import replay

G = 9.81


def test_gravity_gives_the_sign_of_a_dc_coupled_sensor_and_nothing_of_an_ac_coupled_one():
    """A DC-coupled sensor reads +g or -g at rest: its sign; an AC-coupled one reads about 0:
    gravity says nothing (the IMU must)."""
    rng = np.random.default_rng(1)
    assert sign_from_gravity(G + rng.normal(0, 0.2, 64), G) == 1.0
    assert sign_from_gravity(-G + rng.normal(0, 0.2, 64), G) == -1.0
    assert sign_from_gravity(rng.normal(0, 0.2, 64), G) is None


def _sway(t, start_s):
    """A beam set swaying at 39 Hz (0.8 % damping) at start_s, m/s^2."""
    dt = np.clip(t - start_s, 0.0, None)
    return np.where(
        t >= start_s, 3.0 * np.exp(-2 * np.pi * 39 * 0.008 * dt) * np.sin(2 * np.pi * 39 * dt), 0.0
    )


@pytest.mark.parametrize("mounted", [1.0, -1.0])
def test_the_imu_gives_the_sign_once_the_beam_moves(mounted):
    """A 2 kHz IMU (period means, +g) and a 25.6 kHz AC-coupled accelerometer beside it, both with
    their noise: quiet, the comparison says nothing; once the beam sways it gives the sign."""
    rng = np.random.default_rng(2)
    imu_t = np.arange(1, 2001) / 2000.0
    vib_t = np.arange(25600) / 25600.0
    imu_z = G + _sway(imu_t - 0.00025, 0.5) + rng.normal(0, 0.05, imu_t.size)
    vib = mounted * _sway(vib_t, 0.5) + rng.normal(0, 0.2, vib_t.size)
    assert sign_from_imu(vib_t, vib, imu_t, imu_z, 0.0, 0.25) is None
    assert sign_from_imu(vib_t, vib, imu_t, imu_z, 0.5, 0.75) == mounted


@pytest.fixture(scope="module")
def face(params):
    """Five impacts 0.3-0.45 s apart on the nominal support, the accelerometer fed."""
    starts = 0.3 + np.cumsum(0.3 + 0.15 * np.random.default_rng(3).uniform(size=5))
    commands = [
        (float(t), {"material": m, "radius_m": r, "drop_height_m": 3.0, "position_m": 1.0})
        for t, m, r in zip(
            starts,
            ["coal", "marble", "coal", "sandstone", "mudstone"],
            [0.06, 0.05, 0.08, 0.04, 0.07],
        )
    ]
    return stream_chunk(params, commands, float(starts[-1]) + 0.1)


def _labels(params, chunk, accel, chunk_s=0.01, imu=True):
    identifier = StreamIdentifier("statistical", params["identification"], params)
    vibration = replace(chunk.vibration, accel_mps2=accel.astype(np.float32))
    return replay(
        identifier,
        chunk.pressure,
        chunk.imu if imu else None,
        [r for _, r in chunk.rebounds],
        chunk_s=chunk_s,
        vibration=vibration,
    )


def test_an_ac_coupled_accelerometer_upside_down_labels_as_the_right_way_up(params, face):
    """The AC-coupled accelerometer upside down gives the labels of the DC-coupled one the right
    way up (the IMU gives its sign at the first impact; until then its data wait), says
    ``vibration_mount: inverted``, and does so whatever the chunking."""
    accel = np.asarray(face.vibration.accel_mps2, dtype=float)
    upright = _labels(params, face, accel)
    ac_inverted = -(accel - np.median(accel[:2000]))
    for chunk_s in (0.01, 0.003):
        labels = _labels(params, face, ac_inverted, chunk_s)
        assert [lab.decision()[:2] for lab in labels] == [lab.decision()[:2] for lab in upright]
        assert all(lab.vibration_mount == "inverted" for lab in labels)
        assert [lab.confidence for lab in labels] == pytest.approx(
            [lab.confidence for lab in upright], abs=0.02
        )


def test_without_an_imu_an_ac_coupled_accelerometer_is_taken_as_configured(params, face):
    """No IMU to compare with: the AC-coupled accelerometer is taken the right way up (as
    configured) once the IMU has been missing for the stream timeout, and the impacts are all
    labelled."""
    accel = np.asarray(face.vibration.accel_mps2, dtype=float)
    labels = _labels(params, face, accel - np.median(accel[:2000]), imu=False)
    assert len(labels) == 5 and all(lab.vibration_mount is None for lab in labels)
