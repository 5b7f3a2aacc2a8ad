"""sim_node and id_node in one rclpy context, spun by an EventsExecutor in the test, over the
real middleware: commands in, the contract's messages out; bad commands; a stream that stops."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from geometry_msgs.msg import TwistStamped
from rcl_interfaces.msg import Log
from rclpy.parameter import Parameter
from rosprobe import Probe, ros_context, spin_for, spin_until
from sensor_msgs.msg import FluidPressure, Imu, LaserScan
from std_msgs.msg import String

from tail_beam_id.stream.label import match, match_tolerance_s
from tail_beam_sim import topics
from tail_beam_sim.config import deep_merge, default_config_dir, load_parameters
from tail_beam_sim.physics.stream import StreamSimulator
from tail_beam_sim.ros import messages as ros_messages

pytestmark = pytest.mark.ros

COAL = {"material": "coal", "radius_m": 0.06, "drop_height_m": 3.0, "position_m": 1.0}
MARBLE = {"material": "marble", "radius_m": 0.06, "drop_height_m": 3.0, "position_m": 1.0}
SIM_TOPICS = {
    topics.JACK_PRESSURE: FluidPressure,
    topics.IMU: Imu,
    topics.VIBRATION: LaserScan,
    topics.REBOUND_VELOCITY: TwistStamped,
    topics.IMPACT_TRUTH: String,
}


def sim_node(context, **overrides):
    from tail_beam_sim.ros.sim_node import SimNode

    values = {"sim_node.realtime_factor": 0.0, **overrides}
    return SimNode(
        context=context, parameter_overrides=[Parameter(k, value=v) for k, v in values.items()]
    )


def id_node(context, **overrides):
    from tail_beam_id.ros.id_node import IdNode

    values = {"method": "threshold", "id_node.flush_after_idle_s": 0.3, **overrides}
    return IdNode(
        context=context, parameter_overrides=[Parameter(k, value=v) for k, v in values.items()]
    )


def connected(probe: Probe, node) -> bool:
    return probe.command_pub.get_subscription_count() >= 1 and all(
        node.count_publishers(probe.resolve_topic_name(t)) >= 1
        for t in probe.messages
        if t != "/rosout"
    )


def test_sim_node_turns_commands_into_the_contract_messages():
    """Two commands give two truths with their ids and labels, every pressure and IMU sample
    from t = 0 at k / rate with the contract's frames, units and variances, and rebounds at the
    camera's frame after separation."""
    with ros_context() as (context, executor):
        sim = sim_node(context, **{"sim_node.wait_for_subscribers": 1})
        probe = Probe(context, SIM_TOPICS)
        executor.add_node(sim)
        executor.add_node(probe)
        assert spin_until(executor, lambda: connected(probe, sim))
        probe.send({**COAL, "impact_id": "c-1"})
        probe.send(MARBLE)
        assert spin_until(executor, lambda: len(probe.messages[topics.IMPACT_TRUTH]) == 2)
        spec = sim.stream.sensors
        truths = probe.json(topics.IMPACT_TRUTH)
        assert [t["impact_id"] for t in truths] == ["c-1", "sim-0002"]
        assert [t["label"] for t in truths] == ["coal", "gangue"]
        pressure = probe.messages[topics.JACK_PRESSURE]
        stamps = np.array([ros_messages.stamp_s(m.header.stamp) for m in pressure])
        # Every sample from t = 0 on, none lost or repeated: consecutive k / rate stamps.
        assert stamps[0] == 0.0
        np.testing.assert_allclose(np.diff(stamps), 1.0 / spec.pressure_rate_hz, atol=1e-9)
        assert stamps[-1] >= truths[-1]["contact_end_stamp"]
        assert {m.header.frame_id for m in pressure} == {"tail_beam_jack"}
        assert {m.variance for m in pressure} == {spec.pressure_noise_pa**2}
        # Pa, not MPa: the static setting pressure before the first impact.
        before = np.array([m.fluid_pressure for m in pressure])[
            stamps < truths[0]["contact_start_stamp"]
        ]
        assert before.mean() == pytest.approx(
            sim.stream.support.setting_pressure_pa, abs=3 * spec.pressure_noise_pa
        )
        imu = probe.messages[topics.IMU]
        imu_stamps = np.array([ros_messages.stamp_s(m.header.stamp) for m in imu])
        np.testing.assert_allclose(np.diff(imu_stamps), 1.0 / spec.imu_rate_hz, atol=1e-9)
        assert {m.header.frame_id for m in imu} == {"tail_beam_imu"}
        assert all(m.orientation_covariance[0] == -1.0 for m in imu)
        accel_z = np.array([m.linear_acceleration.z for m in imu])[
            imu_stamps < truths[0]["contact_start_stamp"]
        ]
        assert accel_z.mean() == pytest.approx(
            9.81, abs=0.05
        )  # m/s^2, specific force of a plate at rest
        rebounds = probe.messages[topics.REBOUND_VELOCITY]
        assert len(rebounds) == 2 and {m.header.frame_id for m in rebounds} == {"tail_beam_plate"}
        for msg, truth in zip(rebounds, truths):
            stamp = ros_messages.stamp_s(msg.header.stamp)
            assert (
                truth["final_separation_stamp"]
                <= stamp
                <= truth["final_separation_stamp"] + 1.0 / spec.camera_frame_rate_hz + 1e-9
            )
            assert msg.twist.linear.z == pytest.approx(
                truth["rebound_speed_mps"], abs=0.05 + 4 * 0.02 * truth["rebound_speed_mps"]
            )
        # Coal rebounds faster than marble of the same size, speed and point (docs/physics.md).
        assert rebounds[0].twist.linear.z > rebounds[1].twist.linear.z


def test_malformed_commands_are_logged_with_the_field_and_lose_no_valid_impact():
    """Each malformed impact_cmd is one error line naming the field and range, and the valid
    commands around them are all simulated."""
    bad = {
        "not json": "{material: coal",
        "material": json.dumps({**COAL, "material": "granite"}),
        "position_m": json.dumps({**COAL, "position_m": float("nan")}),
        "radius_m": json.dumps({**COAL, "radius_m": -0.02}),
        "position_m ": json.dumps({**COAL, "position_m": 3.0}),  # off the 1.6 m plate
        "drop_height_m/impact_speed_mps": json.dumps(
            {k: v for k, v in COAL.items() if k != "drop_height_m"}
        ),
        "colour": json.dumps({**COAL, "colour": "black"}),
        "impact": json.dumps([1, 2, 3]),
    }
    with ros_context() as (context, executor):
        sim = sim_node(context)
        probe = Probe(context, {topics.IMPACT_TRUTH: String, "/rosout": Log})
        executor.add_node(sim)
        executor.add_node(probe)
        assert spin_until(executor, lambda: connected(probe, sim))
        probe.send({**COAL, "impact_id": "ok-before"})
        for text in bad.values():
            probe.send(text)
        probe.send({**MARBLE, "impact_id": "ok-after"})
        assert spin_until(executor, lambda: len(probe.messages[topics.IMPACT_TRUTH]) == 2)
        spin_for(executor, 0.3)
        assert [t["impact_id"] for t in probe.json(topics.IMPACT_TRUTH)] == [
            "ok-before",
            "ok-after",
        ]
        errors = [
            m.msg
            for m in probe.messages["/rosout"]
            if m.name == "tail_beam_sim" and m.level >= Log.ERROR
        ]
        assert len(errors) == len(bad)
        assert "not valid JSON" in errors[0]
        for error, field in zip(errors[1:], list(bad)[1:]):
            assert error.startswith(f"impact_cmd rejected: {field.strip()} = ")
        assert "must be one of coal, marble, mudstone, sandstone" in errors[1]
        assert (
            "must be in [0.001, 0.5] m" in errors[3]
        )  # a radius of at least 1 mm (config/support.yaml)
        assert "must be in [0, 1.6] m" in errors[4]  # the plate is 1.6 m long (docs/physics.md)


def test_queue_overflow_is_a_warning_and_the_queued_impacts_all_happen():
    """A command beyond stream.max_queued_impacts is one warning naming the limit and the
    impact; the queued impacts all happen."""
    with ros_context() as (context, executor):
        sim = sim_node(
            context, **{"stream.max_queued_impacts": 2, "sim_node.realtime_factor": 1.0}
        )
        probe = Probe(context, {topics.IMPACT_TRUTH: String, "/rosout": Log})
        executor.add_node(sim)
        executor.add_node(probe)
        assert spin_until(executor, lambda: connected(probe, sim))
        for i in range(3):
            probe.send({**COAL, "impact_id": f"q{i}"})
        assert spin_until(executor, lambda: len(probe.messages[topics.IMPACT_TRUTH]) == 2)
        warnings = [
            m.msg
            for m in probe.messages["/rosout"]
            if m.name == "tail_beam_sim" and m.level == Log.WARN
        ]
        assert (
            len(warnings) == 1
            and "stream.max_queued_impacts" in warnings[0]
            and "'q2'" in warnings[0]
        )
        assert [t["impact_id"] for t in probe.json(topics.IMPACT_TRUTH)] == ["q0", "q1"]


def test_id_node_labels_each_impact_of_a_live_sim_node():
    """id_node labels each of a live sim_node's impacts (the suite's matching rule,
    tail_beam_id.stream.label), in stamp order, missing no sample."""
    with ros_context() as (context, executor):
        sim = sim_node(
            context,
            **{
                "sim_node.wait_for_subscribers": 1,
                "scenario.source": "generated",
                "scenario.count": 4,
            },
        )
        ident = id_node(context)
        probe = Probe(
            context,
            {
                topics.LABEL: String,
                topics.IMPACT_TRUTH: String,
                topics.JACK_PRESSURE: FluidPressure,
            },
        )
        for node in (sim, ident, probe):
            executor.add_node(node)
        assert spin_until(
            executor, lambda: len(probe.messages[topics.IMPACT_TRUTH]) == 4, timeout_s=60
        )
        assert spin_until(executor, lambda: len(probe.messages[topics.LABEL]) >= 4, timeout_s=10)
        # Zero loss: the identifier got every sample the simulator published up to now.
        assert (
            ident.received[topics.JACK_PRESSURE] >= len(probe.messages[topics.JACK_PRESSURE]) - 200
        )
        truths = probe.json(topics.IMPACT_TRUTH)
        labels = probe.labels(topics.LABEL)
        matching = match(truths, labels, match_tolerance_s(load_parameters()["identification"]))
        assert not matching.missed, (
            f"no label for {[truths[i]['impact_id'] for i in matching.missed]}"
        )
        for _, paired in matching.pairs:
            assert (
                labels[paired].material in ("coal", "gangue")
                and 0.0 <= labels[paired].confidence <= 1.0
            )
            assert labels[paired].method == "threshold"
        stamps = [lab.impact_stamp_s for lab in labels]
        assert stamps == sorted(stamps)


def offline_chunk(count: int = 3, duration_s: float = 2.5):
    params = load_parameters([default_config_dir() / "sim_node.yaml"])
    deep_merge(params, {"scenario": {"source": "generated", "count": count}})
    from tail_beam_sim.physics.scenario import load_scenario

    stream = StreamSimulator.from_params(params)
    planned = load_scenario(params["scenario"], stream.materials, stream.support)
    for item in planned:
        stream.submit(item.command, item.contact_stamp_s)
    return stream.advance(duration_s)


def test_id_node_labels_from_what_remains_when_a_stream_stops():
    """When the IMU stream stops between impacts, id_node labels the later ones from pressure
    and the camera, and says so in signals."""
    chunk = offline_chunk()
    starts = [t["contact_start_stamp"] for _, t in chunk.truths]
    stop_s = 0.5 * (starts[0] + starts[1])  # the IMU stops between the first and second impact
    with ros_context() as (context, executor):
        ident = id_node(context)
        feeder = Probe(context, {topics.LABEL: String}, name="feeder")
        pubs = {
            topics.JACK_PRESSURE: feeder.create_publisher(
                FluidPressure, topics.JACK_PRESSURE, 10000
            ),
            topics.IMU: feeder.create_publisher(Imu, topics.IMU, 10000),
            topics.REBOUND_VELOCITY: feeder.create_publisher(
                TwistStamped, topics.REBOUND_VELOCITY, 100
            ),
        }
        executor.add_node(ident)
        executor.add_node(feeder)
        assert spin_until(executor, lambda: all(p.get_subscription_count() for p in pubs.values()))
        imu_kept = chunk.imu.stamp_s <= stop_s
        from tail_beam_sim.physics.sensors import ImuStream

        imu = ImuStream(
            chunk.imu.stamp_s[imu_kept],
            chunk.imu.angular_velocity_radps[imu_kept],
            chunk.imu.linear_acceleration_mps2[imu_kept],
            chunk.imu.gyro_variance,
            chunk.imu.accel_variance,
        )
        for msg in ros_messages.pressure_messages(chunk.pressure):
            pubs[topics.JACK_PRESSURE].publish(msg)
        for msg in ros_messages.imu_messages(imu):
            pubs[topics.IMU].publish(msg)
        for _, rebound in chunk.rebounds:
            pubs[topics.REBOUND_VELOCITY].publish(ros_messages.rebound_message(rebound))
        truths = [truth for _, truth in chunk.truths]
        tolerance_s = match_tolerance_s(load_parameters()["identification"])
        spin_until(
            executor,
            lambda: not match(truths, feeder.labels(topics.LABEL), tolerance_s).missed,
            timeout_s=20,
        )
        labels = feeder.labels(topics.LABEL)
        matching = match(truths, labels, tolerance_s)
        for number, start in enumerate(starts[1:], 1):
            later = matching.label_index(number)
            assert later is not None, (
                f"impact at {start:.4f} s after the IMU stopped was not labelled"
            )
            assert "imu" not in labels[later].signals and "jack_pressure" in labels[later].signals
        first = matching.label_index(0)
        assert first is not None and "imu" in labels[first].signals
        assert all(math.isfinite(lab.confidence) for lab in labels)


def sensor_publishers(feeder: Probe) -> dict:
    """The feeder's publishers of the four sensor topics, depths for a whole chunk."""
    return {
        topics.JACK_PRESSURE: feeder.create_publisher(FluidPressure, topics.JACK_PRESSURE, 10000),
        topics.IMU: feeder.create_publisher(Imu, topics.IMU, 10000),
        topics.VIBRATION: feeder.create_publisher(LaserScan, topics.VIBRATION, 1000),
        topics.REBOUND_VELOCITY: feeder.create_publisher(
            TwistStamped, topics.REBOUND_VELOCITY, 100
        ),
    }


def stamp_ordered(chunk, rebounds) -> list:
    """(topic, message) of a chunk's sensor data and ``rebounds``, in stamp order (a sensor's
    own order kept at equal stamps), as a live face would publish them."""
    messages = sorted(
        [
            (m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec, k, topic, m)
            for topic, batch in (
                (topics.JACK_PRESSURE, ros_messages.pressure_messages(chunk.pressure)),
                (topics.IMU, ros_messages.imu_messages(chunk.imu)),
                (topics.VIBRATION, ros_messages.vibration_messages(chunk.vibration)),
                (topics.REBOUND_VELOCITY, [ros_messages.rebound_message(r) for r in rebounds]),
            )
            for k, m in enumerate(batch)
        ],
        key=lambda item: item[:2],
    )
    return [(topic, msg) for _, _, topic, msg in messages]


def test_id_node_survives_a_restarted_simulator_and_a_stamp_from_the_future():
    """A stream whose stamps start again from 0 (sim_node restarted) and, before it, one IMU
    message stamped 1000 s ahead: id_node says so in its log and labels every impact of both
    runs, the same labels offline identification gives each run (it went deaf before)."""
    from tail_beam_id.stream.identifier import StreamIdentifier
    from tail_beam_id.stream.replay import replay

    chunk = offline_chunk()
    starts = [t["contact_start_stamp"] for _, t in chunk.truths]
    params = load_parameters()
    expected = replay(
        StreamIdentifier("threshold", params=params["identification"], model_params=params),
        chunk.pressure,
        chunk.imu,
        [r for _, r in chunk.rebounds],
        vibration=chunk.vibration,
    )
    assert len(expected) == len(starts)
    with ros_context() as (context, executor):
        ident = id_node(context)
        feeder = Probe(context, {topics.LABEL: String, "/rosout": Log}, name="feeder")
        pubs = sensor_publishers(feeder)
        executor.add_node(ident)
        executor.add_node(feeder)
        assert spin_until(executor, lambda: all(p.get_subscription_count() for p in pubs.values()))
        future = ros_messages.imu_messages(chunk.imu)[100]
        future.header.stamp = ros_messages.time_msg(1000.0)
        for run in range(2):
            messages = stamp_ordered(chunk, [r for _, r in chunk.rebounds])
            for i, (topic, msg) in enumerate(messages):
                pubs[topic].publish(msg)
                if run == 0 and i == len(messages) // 3:
                    pubs[topics.IMU].publish(future)
                if i % 2000 == 0:
                    spin_for(executor, 0.05)
            spin_until(
                executor,
                lambda: len(feeder.messages[topics.LABEL]) >= len(starts) * (run + 1),
                timeout_s=30,
            )
        spin_for(executor, 0.5)
        labels = feeder.labels(topics.LABEL)
        log = " | ".join(
            m.msg for m in feeder.messages["/rosout"] if m.name.endswith("tail_beam_id")
        )
    assert [(lab.material, lab.confidence) for lab in labels] == [
        (lab.material, lab.confidence) for lab in expected
    ] * 2, log
    # Stamps cross the middleware as integer nanoseconds.
    np.testing.assert_allclose(
        [lab.impact_stamp_s for lab in labels],
        [lab.impact_stamp_s for lab in expected] * 2,
        atol=1e-8,
    )
    assert "time jump" in log and "went back" in log
    assert "1 samples stamped more than 1 s ahead" in log


def test_id_node_gives_a_slow_cameras_late_rebounds_to_their_impacts_as_offline():
    """A camera at 100 Hz (its rebounds stamped up to 10 ms after the contact ended, past every
    rebound window): fed over the middleware in stamp order, id_node labels each impact once,
    the rebound taken late (rebound_late) as offline identification takes it (before, each
    rebound was an impact of its own: two labels per impact)."""
    from dataclasses import replace

    from tail_beam_id.stream.identifier import StreamIdentifier
    from tail_beam_id.stream.replay import replay

    chunk = offline_chunk()
    truths = [truth for _, truth in chunk.truths]
    rebounds = [
        replace(r, stamp_s=float(np.ceil(t["final_separation_stamp"] * 100.0) / 100.0))
        for (_, r), t in zip(chunk.rebounds, truths)
    ]
    params = load_parameters()
    expected = replay(
        StreamIdentifier("threshold", params=params["identification"], model_params=params),
        chunk.pressure,
        chunk.imu,
        rebounds,
        vibration=chunk.vibration,
    )
    assert len(expected) == len(truths) and any(
        label.features.get("rebound_late") for label in expected
    )
    with ros_context() as (context, executor):
        ident = id_node(context)
        feeder = Probe(context, {topics.LABEL: String}, name="feeder")
        pubs = sensor_publishers(feeder)
        executor.add_node(ident)
        executor.add_node(feeder)
        assert spin_until(executor, lambda: all(p.get_subscription_count() for p in pubs.values()))
        for i, (topic, msg) in enumerate(stamp_ordered(chunk, rebounds)):
            pubs[topic].publish(msg)
            if i % 2000 == 0:
                spin_for(executor, 0.05)
        spin_until(
            executor, lambda: len(feeder.messages[topics.LABEL]) >= len(truths), timeout_s=30
        )
        spin_for(executor, 1.0)
        labels = feeder.labels(topics.LABEL)
    matching = match(truths, labels, match_tolerance_s(params["identification"]))
    assert not matching.missed and not matching.extra
    assert [
        (lab.material, lab.confidence, bool(lab.features.get("rebound_late"))) for lab in labels
    ] == [
        (lab.material, lab.confidence, bool(lab.features.get("rebound_late"))) for lab in expected
    ]


def test_id_node_calibrates_itself_online_and_says_so():
    """A live sim_node (12 generated impacts, about 7 s) into id_node with calibrate_online_s 3:
    id_node's log names the sway it measured, the shipped support's lowest natural frequency
    within 2 %, and its labels say calibrated: false before and true after the learned window."""
    from tail_beam_sim.physics.fidelity import TIERS, FidelitySettings, structure_for
    from tail_beam_sim.physics.materials import material_table
    from tail_beam_sim.physics.support import Support

    params = load_parameters()
    sway_hz = structure_for(
        TIERS["modal"],
        Support.from_params(params["support"], material_table(params)),
        FidelitySettings.from_params(params).modes,
    ).natural_frequencies_hz()[0]
    with ros_context() as (context, executor):
        sim = sim_node(
            context,
            **{
                "sim_node.wait_for_subscribers": 1,
                "scenario.source": "generated",
                "scenario.count": 12,
                "sim_node.realtime_factor": 4.0,
            },
        )
        ident = id_node(context, method="statistical", **{"id_node.calibrate_online_s": 3.0})
        probe = Probe(context, {topics.LABEL: String, topics.IMPACT_TRUTH: String, "/rosout": Log})
        for node in (sim, ident, probe):
            executor.add_node(node)

        def log() -> str:
            return " | ".join(m.msg for m in probe.messages["/rosout"] if m.name == "tail_beam_id")

        assert spin_until(
            executor, lambda: len(probe.messages[topics.IMPACT_TRUTH]) == 12, timeout_s=90
        )
        assert spin_until(
            executor, lambda: len(probe.messages[topics.LABEL]) >= 12, timeout_s=20
        ), log()
        labels = probe.labels(topics.LABEL)
    flags = [label.calibrated for label in labels]
    assert flags[0] is False and flags[-1] is True and flags == sorted(flags), log()
    found = re.search(r"calibration: sway ([0-9.]+) Hz", log())
    assert found and float(found.group(1)) == pytest.approx(sway_hz, rel=0.02), log()


def test_publish_clock_gives_the_simulation_time_on_slash_clock():
    """/clock ticks forward with simulation time, ending within one chunk of the last published
    sample."""
    from rosgraph_msgs.msg import Clock

    with ros_context() as (context, executor):
        sim = sim_node(
            context,
            **{
                "sim_node.publish_clock": True,
                "sim_node.wait_for_subscribers": 1,
                "sim_node.exit_after_idle_s": 0.5,
            },
        )
        probe = Probe(context, {"/clock": Clock, **SIM_TOPICS})
        executor.add_node(sim)
        executor.add_node(probe)
        assert spin_until(executor, lambda: sim.finished.done())
        spin_for(executor, 0.3)
        clocks = np.array([ros_messages.stamp_s(m.clock) for m in probe.messages["/clock"]])
        stamps = np.array(
            [ros_messages.stamp_s(m.header.stamp) for m in probe.messages[topics.JACK_PRESSURE]]
        )
        assert clocks.size > 1 and np.all(np.diff(clocks) > 0)
        # Each /clock tick is the end of a published chunk: it follows the samples within a chunk
        # (the two topics are delivered independently, so either may be the last to arrive).
        assert abs(clocks[-1] - stamps[-1]) <= sim.max_chunk_s
        assert clocks[-1] >= 0.5


def test_replay_publishes_a_bag_in_log_time_order_with_its_clock(tmp_path, default_scene):
    """bag_replay publishes every message of a simulated bag, the pressure values exactly as
    simulated, with /clock."""
    from rosgraph_msgs.msg import Clock

    from tail_beam_sim.bags import records as bagio
    from tail_beam_sim.physics.simulate import simulate
    from tail_beam_sim.ros.replay_node import ReplayNode

    result = simulate(default_scene)
    bag = tmp_path / "one"
    count = bagio.write_bag(bag, bagio.result_records(result, {"material": "coal"}))
    with ros_context() as (context, executor):
        probe = Probe(context, {"/clock": Clock, **SIM_TOPICS, topics.IMPACT_CMD: String})
        replay = ReplayNode(
            context=context,
            parameter_overrides=[
                Parameter("replay.bag_path", value=str(bag)),
                Parameter("replay.rate", value=4.0),
                Parameter("replay.publish_clock", value=True),
                Parameter("replay.wait_for_subscribers", value=1),
                Parameter(
                    "replay.topics", value=list(topics.MSG_TYPES)
                ),  # every topic, not the sensors only (the default)
            ],
        )
        executor.add_node(probe)
        executor.add_node(replay)
        assert spin_until(executor, lambda: replay.finished.done())
        spin_for(executor, 0.3)
    assert replay.published == count
    pressure = probe.messages[topics.JACK_PRESSURE]
    np.testing.assert_array_equal(
        [m.fluid_pressure for m in pressure], result.pressure.pressure_pa
    )
    assert len(probe.messages[topics.IMU]) == result.imu.stamp_s.size
    assert (
        probe.json(topics.IMPACT_TRUTH)[0]["peak_contact_force_n"]
        == result.truth()["peak_contact_force_n"]
    )
    # bagio logs each message at its header stamp, so /clock replays the simulation time.
    clocks = [ros_messages.stamp_s(m.clock) for m in probe.messages["/clock"]]
    assert clocks == sorted(clocks) and len(clocks) == count
    assert clocks[-1] == pytest.approx(result.contact_stamp_s + default_scene.window_s, abs=1e-9)
