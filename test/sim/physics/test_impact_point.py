"""The camera's impact point: where the particle struck, with the camera's noise, stamped as its
rebound; off by default, and turning it on changes no other sensor's readings."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from tail_beam_sim.config import default_config_dir, load_parameters
from tail_beam_sim.physics.scene import Scene, SensorSpec
from tail_beam_sim.physics.sensors import Rebound, SensorSuite
from tail_beam_sim.physics.simulate import simulate
from tail_beam_sim.physics.stream import StreamSimulator

COMMANDS = [
    {"material": "coal", "radius_m": 0.04, "drop_height_m": 2.0, "position_m": 0.35},
    {"material": "sandstone", "radius_m": 0.03, "drop_height_m": 3.0, "position_m": 0.9},
    {"material": "marble", "radius_m": 0.05, "drop_height_m": 1.5, "position_m": 1.45},
]


def stream_params(points: bool) -> dict:
    params = load_parameters([default_config_dir() / "sim_node.yaml"])
    params = copy.deepcopy(params)
    params["sensors"]["camera_reports_impact_point"] = points
    return params


def run_stream(points: bool):
    simulator = StreamSimulator.from_params(stream_params(points))
    for k, command in enumerate(COMMANDS):
        simulator.submit(command, contact_stamp_s=0.1 + 0.25 * k)
    return simulator.advance(1.0)


def test_default_layout_reports_no_point():
    """The shipped layout has no impact-point camera: the stream simulates no point."""
    assert (
        SensorSpec.from_params(load_parameters()["sensors"]).camera_reports_impact_point is False
    )
    assert run_stream(points=False).points == []


def test_each_point_is_stamped_as_its_rebound_and_lies_where_it_struck():
    """One point per impact, its stamp its rebound's, within 5 sigma of the commanded position
    along the plate and of the beam's axis across it, z exactly 0; the other streams are the
    same to the bit as without the point."""
    with_points, without = run_stream(points=True), run_stream(points=False)
    sigma = SensorSpec.from_params(stream_params(True)["sensors"]).impact_point_noise_m
    assert [i for i, _ in with_points.points] == [i for i, _ in with_points.rebounds]
    for (_, point), (_, rebound), command in zip(
        with_points.points, with_points.rebounds, COMMANDS
    ):
        assert point.stamp_s == rebound.stamp_s
        assert point.point_m[2] == 0.0
        assert abs(point.point_m[0] - command["position_m"]) < 5 * sigma
        assert abs(point.point_m[1]) < 5 * sigma
        assert point.true_point_m.tolist() == [command["position_m"], 0.0, 0.0]
    np.testing.assert_array_equal(with_points.pressure.pressure_pa, without.pressure.pressure_pa)
    np.testing.assert_array_equal(
        with_points.imu.linear_acceleration_mps2, without.imu.linear_acceleration_mps2
    )
    np.testing.assert_array_equal(with_points.vibration.accel_mps2, without.vibration.accel_mps2)
    for (_, a), (_, b) in zip(with_points.rebounds, without.rebounds):
        assert a.stamp_s == b.stamp_s and a.velocity_mps.tolist() == b.velocity_mps.tolist()


def test_point_noise_is_the_cameras_gaussian_per_coordinate():
    """4000 readings of one point: mean within 5 standard errors of the truth, RMS within 8 %
    of impact_point_noise_m (5 standard errors of an RMS from 4000 draws), per coordinate."""
    spec = SensorSpec.from_params(
        {**load_parameters()["sensors"], "impact_point_noise_m": 0.02, "seed": 7}
    )
    suite = SensorSuite(spec)
    rebound = Rebound(0.5, np.zeros(3), np.zeros(3))
    readings = np.array([suite.impact_point(0.8, rebound, 1.6, 1.5).point_m for _ in range(4000)])
    errors = readings - np.array([0.8, 0.0, 0.0])
    for axis in (0, 1):
        assert abs(errors[:, axis].mean()) < 5 * 0.02 / np.sqrt(4000)
        assert errors[:, axis].std() == pytest.approx(0.02, rel=0.08)
    assert (readings[:, 2] == 0.0).all()


def test_a_point_near_an_edge_is_never_read_off_the_plate():
    """The camera sees the plate: a strike at the hinge or a corner reads on it."""
    spec = SensorSpec.from_params({**load_parameters()["sensors"], "impact_point_noise_m": 0.05})
    suite = SensorSuite(spec)
    rebound = Rebound(0.5, np.zeros(3), np.zeros(3))
    for position in (0.0, 1.6):
        xs = np.array(
            [suite.impact_point(position, rebound, 1.6, 0.02).point_m for _ in range(200)]
        )
        assert (xs[:, 0] >= 0.0).all() and (xs[:, 0] <= 1.6).all()
        assert (np.abs(xs[:, 1]) <= 0.01).all()


def test_offline_simulation_reports_the_point_only_when_asked():
    """tail-beam simulate's path gives the point, stamped as its rebound, only when the camera
    reports it; the other readings are the same either way."""
    params = load_parameters()
    plain = simulate(Scene.from_params(params))
    assert plain.point is None
    asked = copy.deepcopy(params)
    asked["sensors"]["camera_reports_impact_point"] = True
    result = simulate(Scene.from_params(asked))
    assert result.point is not None and result.point.stamp_s == result.rebound.stamp_s
    assert abs(result.point.point_m[0] - result.scene.impact.position_m) < 0.05
    np.testing.assert_array_equal(result.pressure.pressure_pa, plain.pressure.pressure_pa)
    assert result.rebound.velocity_mps.tolist() == plain.rebound.velocity_mps.tolist()
