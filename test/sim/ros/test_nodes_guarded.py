"""Nodes against other participants of the domain: parameter changes at run time are refused
(use_sim_time would rewrite the recorder's log times), bag_replay publishes the sensors only
unless asked, and `tail-beam demo` survives foreign messages on its topics."""

from __future__ import annotations

import json
import subprocess
import time
from pathlib import Path

import pytest
from bag_helpers import records, write_segments
from geometry_msgs.msg import TwistStamped
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rosprobe import RELIABLE, Probe, call_until_answered, ros_context, spin_for, spin_until
from sensor_msgs.msg import FluidPressure, Imu, LaserScan
from std_msgs.msg import String
from test_nodes_processes import BIN, Processes

from tail_beam_sim import topics
from tail_beam_sim.bags import records as bagio
from tail_beam_sim.bags.read import raw_messages, read_sensors

pytestmark = [pytest.mark.ros, pytest.mark.slow]


@pytest.fixture
def procs(tmp_path):
    manager = Processes(tmp_path)
    yield manager
    manager.close()


def string_record(topic: str, ns: int, payload: dict) -> tuple[str, int, bytes]:
    return (
        topic,
        ns,
        bytes(bagio.TYPESTORE.serialize_cdr(bagio.string_msg(payload), topics.MSG_TYPES[topic])),
    )


def set_parameter(executor, node, target: str, name: str, value) -> tuple[bool, str]:
    """Set one parameter of the node ``target`` as any participant can; (successful, reason)."""
    client = AsyncParameterClient(node, target)
    assert spin_until(executor, lambda: client.services_are_ready(), timeout_s=30), (
        f"{target}'s parameter services never came"
    )
    answer = call_until_answered(
        executor,
        lambda: client.set_parameters([Parameter(name, value=value)]),
        f"{target}'s set_parameters",
    )
    result = answer.results[0]
    return result.successful, result.reason


def test_running_nodes_refuse_parameter_changes_and_keep_their_clock(tmp_path, procs):
    """use_sim_time and start-up parameters set on a running recorder, replay and id_node are
    refused with a reason; the recorder keeps logging wall time."""
    bag = tmp_path / "recorded"
    replayed = tmp_path / "to_replay"
    write_segments(replayed, [records(50)])
    # its own namespace: these processes are killed at the end, and linger in discovery a while
    ns = "/guarded"
    recorder = procs.start("bag_recorder", f"recorder.bag_path:={bag}", ns=ns)
    procs.start("id_node", ns=ns)
    procs.start(
        "bag_replay", f"replay.bag_path:={replayed}", "replay.wait_for_subscribers:=50", ns=ns
    )  # waits: stays up
    with ros_context() as (context, executor):
        probe = Probe(context, {}, namespace=ns, name="intruder")
        executor.add_node(probe)
        truth_pub = probe.create_publisher(String, topics.IMPACT_TRUTH, RELIABLE)
        for target, name, value in [
            ("tail_beam_recorder", "use_sim_time", True),
            ("tail_beam_recorder", "recorder.segment_s", 0.01),
            ("tail_beam_id", "use_sim_time", True),
            ("tail_beam_id", "identification.method", "threshold"),
            ("tail_beam_replay", "use_sim_time", True),
            ("tail_beam_replay", "replay.rate", 100.0),
        ]:
            ok, reason = set_parameter(executor, probe, target, name, value)
            assert not ok and name in reason and "start-up" in reason, (target, name, reason)
        topic = probe.resolve_topic_name(topics.IMPACT_TRUTH)
        assert spin_until(executor, lambda: probe.count_subscribers(topic) >= 1, timeout_s=30)
        spin_for(executor, 1.0)
        sent_ns = time.time_ns()
        truth_pub.publish(String(data=json.dumps({"impact_id": "after-the-attempt"})))
        spin_for(executor, 1.0)
    assert procs.stop(recorder) == 0
    logged = list(raw_messages(bag, [topics.IMPACT_TRUTH]))
    assert len(logged) == 1
    assert abs(logged[0].log_time_ns - sent_ns) < 5e9, (
        "the recorder's log time is not wall time any more"
    )
    assert "parameter change refused: use_sim_time" in procs.log(recorder)


def test_bag_replay_publishes_the_sensors_only_unless_asked(tmp_path, procs):
    """Default replay.topics: sensor data goes out, the recorded label and truth do not; listed,
    they do."""
    bag = tmp_path / "bag"
    data = records(40)
    data.append(
        string_record(
            topics.LABEL,
            data[10][1],
            {"impact_stamp": 0.01, "label": "coal", "confidence": 0.9, "method": "statistical"},
        )
    )
    data.append(string_record(topics.IMPACT_TRUTH, data[12][1], {"impact_id": "t1"}))
    data.sort(key=lambda r: r[1])
    write_segments(bag, [data])
    runs = {
        "default": [],
        "asked": ["replay.topics:=[jack_pressure, imu, label, impact_truth]"],
    }
    # Both replays at once, each in a namespace of its own, so that it waits for its own probe
    # (and not for an endpoint another test's killed process left in discovery).
    with ros_context() as (context, executor):
        probes, replays = {}, {}
        for name, extra in runs.items():
            ns = f"/replay_{name}"
            probes[name] = Probe(
                context,
                {
                    topics.IMU: Imu,
                    topics.JACK_PRESSURE: FluidPressure,
                    topics.VIBRATION: LaserScan,
                    topics.REBOUND_VELOCITY: TwistStamped,
                    topics.LABEL: String,
                    topics.IMPACT_TRUTH: String,
                },
                namespace=ns,
                name=f"probe_{name}",
            )  # replay waits for its sensor subscribers
            executor.add_node(probes[name])
            replays[name] = procs.start(
                "bag_replay",
                f"replay.bag_path:={bag}",
                "replay.wait_for_subscribers:=1",
                "replay.subscriber_settle_s:=1.0",
                *extra,
                ns=ns,
            )
        assert spin_until(
            executor, lambda: all(r.poll() is not None for r in replays.values()), timeout_s=60
        ), {name: procs.log(r) for name, r in replays.items()}
        for replay in replays.values():
            assert replay.returncode == 0, procs.log(replay)
        spin_until(
            executor,
            lambda: all(len(p.messages[topics.IMU]) >= 40 for p in probes.values()),
            timeout_s=15,
        )
        spin_for(executor, 0.5)
        heard = {
            name: {
                t: len(probe.messages[t])
                for t in (topics.IMU, topics.JACK_PRESSURE, topics.LABEL, topics.IMPACT_TRUTH)
            }
            for name, probe in probes.items()
        }
    assert heard["default"] == {
        topics.IMU: 40,
        topics.JACK_PRESSURE: 40,
        topics.LABEL: 0,
        topics.IMPACT_TRUTH: 0,
    }
    assert heard["asked"] == {
        topics.IMU: 40,
        topics.JACK_PRESSURE: 40,
        topics.LABEL: 1,
        topics.IMPACT_TRUTH: 1,
    }


def test_demo_skips_foreign_messages_on_its_topics(tmp_path):
    """Non-JSON and wrong-shaped messages on label and impact_truth during `tail-beam demo`:
    skipped, counted, one warning per topic; the demo scores its own impacts (was:
    JSONDecodeError)."""
    namespace = "/demo_hostile"
    demo = subprocess.Popen(
        [
            str(BIN / "tail-beam"),
            "demo",
            "--count",
            "3",
            "--realtime-factor",
            "0",
            "--namespace",
            namespace,
            "--bag",
            str(tmp_path / "bag"),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    junk = [
        "not json",
        "[1, 2]",
        '{"label": "rock"}',
        '{"impact_stamp": "soon", "label": "coal", "confidence": 1, "method": "x"}',
        "{" * 5000,
    ]
    sent = 0
    with ros_context() as (context, executor):
        probe = Probe(context, {}, namespace=namespace, name="intruder")
        executor.add_node(probe)
        pubs = [
            probe.create_publisher(String, t, RELIABLE)
            for t in (topics.LABEL, topics.IMPACT_TRUTH)
        ]
        while demo.poll() is None:
            if all(p.get_subscription_count() >= 1 for p in pubs):
                for pub in pubs:
                    pub.publish(String(data=junk[sent % len(junk)]))
                sent += 1
            spin_for(executor, 0.1)
    out, err = demo.communicate(timeout=60)
    assert demo.returncode == 0, err[-3000:]
    assert "Traceback" not in err and sent > 0
    assert (
        out.count("warning: skipping messages on label") == 1
        and out.count("warning: skipping messages on impact_truth") == 1
    )
    counts = {
        line.split()[4]: int(line.split()[1])
        for line in out.splitlines()
        if line.startswith("skipped ")
    }
    assert set(counts) == {topics.LABEL, topics.IMPACT_TRUTH}, out
    assert counts and all(1 <= n <= sent for n in counts.values()), out
    assert "accuracy: " in out and "/3 = " in out
    assert len(read_sensors(Path(tmp_path / "bag")).json_topics[topics.IMPACT_TRUTH]) >= 3
