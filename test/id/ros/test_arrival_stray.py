"""The gated identifier against data no support makes: a steady tone in the jack pressure is no
sway to calibrate from, a new time base forgets what was learned, and a label resting on no
signal is never handed on."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from tail_beam_id.calibration.online import OnlineCalibration
from tail_beam_id.ros.arrival import GateConfig, GatedIdentifier
from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_sim.physics.sensors import VibrationBlocks

CONFIG = GateConfig(reorder_s=0.0, stream_idle_s=0.5, time_jump_s=1.0)
PRESSURE_HZ = 1000.0  # sample rate of the fake jack pressure
IMU_HZ = 1000.0  # sample rate of the IMU at rest


def gated(params, calibration=None) -> GatedIdentifier:
    return GatedIdentifier(
        lambda trained: StreamIdentifier(
            "statistical", params["identification"], params, prebuilt=trained
        ),
        CONFIG,
        calibration,
    )


def fake_sway(until_s: float, start_s: float = 0.0):
    """A 39 Hz tone of 50 kPa on 20 MPa with a 2 MPa spike every 0.5 s (Pa), and an IMU at
    rest (gravity on z), both stamped from ``start_s`` to ``until_s`` (s)."""
    t_p = start_s + np.arange(0.0, until_s - start_s, 1.0 / PRESSURE_HZ)
    p = 20e6 + 5e4 * np.sin(2 * np.pi * 39.0 * t_p)
    p[:: int(0.5 * PRESSURE_HZ)] += 2e6
    t_i = start_s + np.arange(0.0, until_s - start_s, 1.0 / IMU_HZ)
    imu = np.zeros((t_i.size, 6))
    imu[:, 5] = 9.81
    return (t_p, p.reshape(-1, 1)), (t_i, imu)


def feed(runner: GatedIdentifier, pressure, imu, wall_s: float, step_s: float = 0.05) -> float:
    """Hand the streams over in ``step_s`` chunks of stamp time, one wall second per stamp
    second from ``wall_s``; the wall clock (s) after the last."""
    lo = min(pressure[0][0], imu[0][0])
    hi = max(pressure[0][-1], imu[0][-1])
    for edge in np.arange(lo, hi + step_s, step_s):
        arrivals = {}
        for name, (t, v) in (("jack_pressure", pressure), ("imu", imu)):
            take = (t >= edge) & (t < edge + step_s)
            if take.any():
                arrivals[name] = (t[take], v[take])
        wall_s += step_s
        runner.tick(wall_s, arrivals, VibrationBlocks.empty(), [])
    return wall_s


def test_a_steady_tone_with_spikes_in_the_jack_pressure_is_no_sway_to_calibrate_from(params):
    """4 s of a 39 Hz tone with spikes in the jack pressure and an IMU at rest (nothing
    strikes the beam): the spectrum shows a peak, but no impact rang it, so the learned
    profile is refused (the log says how many impacts it had), nothing says calibrated."""
    calibration = OnlineCalibration(params, 3.0, "statistical", background=False)
    runner = gated(params, calibration)
    pressure, imu = fake_sway(4.0)
    feed(runner, pressure, imu, 0.0)
    assert calibration.state == "done" and calibration.result is not None
    assert calibration.result.profile.rigid_mode_frequency_hz is not None  # the tone is seen
    assert calibration.result.model_params is None and runner._profile is None
    assert not runner.identifier.calibrated
    assert any("no clear sway" in note and "0 impacts" in note for note in runner.notes)


def test_a_new_time_base_drops_the_learned_profile_and_learns_again(params):
    """A gated identifier deciding with a learned profile: stamps going back by more than
    time_jump_s (a new time base) drop the profile, start learning again and say so."""
    calibration = OnlineCalibration(params, 3.0, "statistical", background=False)
    runner = gated(params, calibration)
    pressure, imu = fake_sway(1.0)
    wall = feed(runner, pressure, imu, 0.0)
    calibration.state = "done"
    runner._profile = (params, None)
    runner.identifier.recalibrate(params, None)
    pressure, imu = fake_sway(-4.0, start_s=-5.0)
    feed(runner, pressure, imu, wall)
    assert runner.time_jumps == 1
    assert runner._profile is None and calibration.state == "learning"
    assert calibration.result is None and not runner.identifier.calibrated
    assert any("learned profile dropped" in note for note in runner.notes)


def test_a_label_resting_on_no_signal_is_dropped_and_counted(params, monkeypatch):
    """Should the identifier give a label with no signal behind it, the gated identifier drops
    it, counts it and notes it; labels with signals pass."""
    runner = gated(params)
    good = SimpleNamespace(signals=["imu"])
    empty = SimpleNamespace(signals=[])
    monkeypatch.setattr(runner.identifier, "poll", lambda: [empty, good, empty])
    labels = runner.decide(1.0)
    assert labels == [good] and runner.empty_labels == 2
    assert any("resting on no signal" in note for note in runner.notes)
