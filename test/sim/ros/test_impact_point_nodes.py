"""impact_point over the real middleware: sim_node publishes where each particle struck when its
camera reports it, id_node puts it in the labels, the recorder records it and `tail-beam
identify` on the recording gives the same labels; hostile points are refused by name and
counted, and the node labels on."""

from __future__ import annotations

import math

import numpy as np
import pytest
from geometry_msgs.msg import PointStamped, TwistStamped
from rcl_interfaces.msg import Log
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosprobe import Probe, ros_context, spin_for, spin_until
from std_msgs.msg import String

from tail_beam_id.cli.identify_cmd import identify_bag
from tail_beam_id.stream.label import match, match_tolerance_s
from tail_beam_sim import topics
from tail_beam_sim.bags.read import read_sensors
from tail_beam_sim.config import load_parameters
from tail_beam_sim.ros import messages as ros_messages

pytestmark = pytest.mark.ros

NOISE_M = 0.01  # sensors.impact_point_noise_m's default
POINTS_ON = {"sensors.camera_reports_impact_point": True}


def node(cls, context, values):
    return cls(
        context=context, parameter_overrides=[Parameter(k, value=v) for k, v in values.items()]
    )


def sim_node(context, **values):
    from tail_beam_sim.ros.sim_node import SimNode

    return node(
        SimNode,
        context,
        {"scenario.source": "generated", "sim_node.wait_for_subscribers": 2, **values},
    )


def id_node(context):
    from tail_beam_id.ros.id_node import IdNode

    return node(IdNode, context, {"method": "threshold", "id_node.flush_after_idle_s": 0.3})


def test_sim_node_publishes_the_points_and_id_node_and_the_recording_use_them(tmp_path):
    """sim_node publishes one point per impact, stamped as its rebound and within 5 sigma of the
    truth; id_node's labels carry it; the recorder records it; identify on the bag agrees."""
    from tail_beam_sim.ros.recorder_node import RecorderNode

    with ros_context() as (context, executor):
        sim = sim_node(
            context, **POINTS_ON, **{"scenario.count": 3, "sim_node.realtime_factor": 0.0}
        )
        recorder = node(
            RecorderNode,
            context,
            {"recorder.bag_path": str(tmp_path / "bag"), "recorder.segment_s": 60.0},
        )
        ident = id_node(context)
        probe = Probe(
            context,
            {
                topics.IMPACT_POINT: PointStamped,
                topics.REBOUND_VELOCITY: TwistStamped,
                topics.IMPACT_TRUTH: String,
                topics.LABEL: String,
            },
        )
        for each in (sim, recorder, ident, probe):
            executor.add_node(each)
        assert spin_until(
            executor, lambda: len(probe.messages[topics.IMPACT_TRUTH]) == 3, timeout_s=90
        )
        assert spin_until(executor, lambda: len(probe.messages[topics.LABEL]) >= 3, timeout_s=20)
        spin_for(executor, 0.5)
        truths = probe.json(topics.IMPACT_TRUTH)
        points = probe.messages[topics.IMPACT_POINT]
        rebounds = probe.messages[topics.REBOUND_VELOCITY]
        assert len(points) == len(rebounds) == 3
        for point, rebound, truth in zip(points, rebounds, truths):
            assert point.header.frame_id == topics.FRAME_PLATE
            assert point.header.stamp == rebound.header.stamp
            assert abs(point.point.x - truth["position_m"]) < 5 * NOISE_M
            assert abs(point.point.y) < 5 * NOISE_M and point.point.z == 0.0
        labels = probe.labels(topics.LABEL)
        tolerance = match_tolerance_s(load_parameters()["identification"])
        matching = match(truths, labels, tolerance)
        assert not matching.missed
        by_stamp = {ros_messages.stamp_s(p.header.stamp): p.point for p in points}
        for _, paired in matching.pairs:
            x = labels[paired].features["impact_x_m"]
            assert any(abs(x - p.x) < 1e-12 for p in by_stamp.values())
        assert ident.refused_points == {}
        executor.remove_node(recorder)
        recorder.close()
    recorded = read_sensors(tmp_path / "bag")
    assert [p[2][0] for p in recorded.points] == [p.point.x for p in points]
    offline = identify_bag(str(tmp_path / "bag"), "threshold", calibrate=False)

    def firsts(found):
        return sorted(
            (lab.impact_stamp_s, lab.material, lab.features["impact_x_m"])
            for lab in found
            if lab.revises is None
        )

    assert firsts(offline) == firsts(labels)


def test_id_node_refuses_each_hostile_point_by_name_and_labels_on():
    """A participant publishing points no camera sends (NaN, off the plate, another frame, z
    not 0, at no rebound's stamp): each refused by its field and counted, warned on /rosout,
    never a traceback; every impact is labelled, with its own point."""
    reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    with ros_context() as (context, executor):
        sim = sim_node(
            context,
            **POINTS_ON,
            **{"scenario.count": 3, "scenario.start_s": 1.0, "sim_node.wait_for_subscribers": 1},
        )
        ident = id_node(context)
        probe = Probe(
            context,
            {
                topics.IMPACT_POINT: PointStamped,
                topics.IMPACT_TRUTH: String,
                topics.LABEL: String,
                "/rosout": Log,
            },
        )
        intruder = probe.create_publisher(PointStamped, topics.IMPACT_POINT, reliable)
        for each in (sim, ident, probe):
            executor.add_node(each)
        assert spin_until(executor, lambda: len(probe.messages[topics.IMPACT_POINT]) >= 1, 60)
        real = probe.messages[topics.IMPACT_POINT][0]
        stamp_s = ros_messages.stamp_s(real.header.stamp)
        cases = {
            "impact_point.point.x: must be a finite number": ((math.nan, 0.0, 0.0), stamp_s),
            "impact_point.point.x: must be in [0, 1.6] m": ((-0.2, 0.0, 0.0), stamp_s),
            "impact_point.point.y: must be in [-0.75, 0.75] m": ((0.5, -1.0, 0.0), stamp_s),
            "impact_point.point.z: must be 0 m": ((0.5, 0.0, -0.3), stamp_s),
            "impact_point.header.frame_id: must be 'tail_beam_plate'": ((0.5, 0.0, 0.0), stamp_s),
            "no rebound at its stamp": ((0.5, 0.0, 0.0), stamp_s + 0.1),
        }
        for name, (xyz, stamp) in cases.items():
            frame = "tail_beam_imu" if "frame_id" in name else topics.FRAME_PLATE
            msg = PointStamped(header=ros_messages.header(stamp, frame))
            msg.point.x, msg.point.y, msg.point.z = xyz
            intruder.publish(msg)
        assert spin_until(
            executor, lambda: len(probe.messages[topics.IMPACT_TRUTH]) == 3, timeout_s=60
        )
        assert spin_until(
            executor,
            lambda: (
                all(any(k.startswith(n) for k in ident.refused_points) for n in cases)
                and len(probe.messages[topics.LABEL]) >= 3
            ),
            timeout_s=20,
        ), ident.refused_points
        for name in cases:
            (count,) = [n for k, n in ident.refused_points.items() if k.startswith(name)]
            assert count == 1, (name, ident.refused_points)
        assert spin_until(
            executor,
            lambda: any(
                "impact_point:" in m.msg and "refused or set aside" in m.msg
                for m in probe.messages["/rosout"]
            ),
            timeout_s=10,
        )
        labels = probe.labels(topics.LABEL)
        truths = probe.json(topics.IMPACT_TRUTH)
        matching = match(truths, labels, match_tolerance_s(load_parameters()["identification"]))
        assert not matching.missed
        for truth_index, paired in matching.pairs:
            x = labels[paired].features["impact_x_m"]
            assert abs(x - truths[truth_index]["position_m"]) < 5 * NOISE_M
        assert not any("Traceback" in m.msg for m in probe.messages["/rosout"])
        assert np.isfinite([lab.confidence for lab in labels]).all()


def test_replay_publishes_the_recorded_points_by_default(tmp_path):
    """bag_replay's default topics carry impact_point: the points come out as recorded."""
    import copy

    from tail_beam_sim.bags import records as bagio
    from tail_beam_sim.physics.scene import Scene
    from tail_beam_sim.physics.simulate import simulate
    from tail_beam_sim.ros.replay_node import ReplayNode

    params = copy.deepcopy(load_parameters())
    params["sensors"]["camera_reports_impact_point"] = True
    result = simulate(Scene.from_params(params))
    bagio.write_bag(tmp_path / "bag", bagio.result_records(result))
    with ros_context() as (context, executor):
        from sensor_msgs.msg import FluidPressure, Imu, LaserScan

        probe = Probe(
            context,
            {
                topics.IMPACT_POINT: PointStamped,
                topics.JACK_PRESSURE: FluidPressure,
                topics.IMU: Imu,
                topics.VIBRATION: LaserScan,
                topics.REBOUND_VELOCITY: TwistStamped,
            },
        )
        replay = node(
            ReplayNode,
            context,
            {
                "replay.bag_path": str(tmp_path / "bag"),
                "replay.rate": 4.0,
                "replay.wait_for_subscribers": 1,
            },
        )
        executor.add_node(probe)
        executor.add_node(replay)
        assert spin_until(executor, lambda: len(probe.messages[topics.IMPACT_POINT]) == 1)
    (point,) = probe.messages[topics.IMPACT_POINT]
    assert [point.point.x, point.point.y, point.point.z] == result.point.point_m.tolist()
    assert point.header.frame_id == topics.FRAME_PLATE
