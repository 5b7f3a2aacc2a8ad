"""caving_node closes a flow's window on id_node's labels, and the decision is the one the same
rule gives offline on ``tail-beam identify``'s labels of the recorded bag (real rclpy nodes, a
real rosbag2 bag); hostile label and share messages are set aside and counted."""

from __future__ import annotations

import json
import time

import pytest
from rclpy.parameter import Parameter
from rosprobe import ros_context, spin_for, spin_until
from std_msgs.msg import String

from tail_beam_id.caving.feed import offline_decision
from tail_beam_id.caving.rules import rule_factories
from tail_beam_id.cli.identify_cmd import identify_bag
from tail_beam_id.ros.id_node import GANGUE_SHARE_TOPIC
from tail_beam_sim import topics
from tail_beam_sim.bags.read import read_sensors
from tail_beam_sim.config import default_config_dir, read_parameter_file
from tail_beam_sim.errors import InputError
from tail_beam_sim.ros import messages as ros_messages

pytestmark = pytest.mark.ros
RULE = "sprt"


def caving_section() -> dict:
    return read_parameter_file(default_config_dir() / "face.yaml")["caving"]


@pytest.mark.slow
def test_caving_node_closes_the_window_as_the_rule_decides_offline(tmp_path):
    """sim_node (flow), id_node, caving_node and the recorder live: caving_node opens the
    window, closes it on the SPRT of the labels, and that decision (stamp, reason, evidence)
    is the one the SPRT gives on tail-beam identify's labels of the bag, from the window's
    recorded opening."""
    from tail_beam_id.ros.caving_node import CavingNode
    from tail_beam_id.ros.id_node import IdNode
    from tail_beam_sim.ros.recorder_node import RecorderNode
    from tail_beam_sim.ros.sim_node import SimNode

    bag = tmp_path / "bag"
    with ros_context() as (context, executor):
        recorder = RecorderNode(
            context=context, parameter_overrides=[Parameter("recorder.bag_path", value=str(bag))]
        )
        ident = IdNode(
            context=context,
            parameter_overrides=[
                Parameter("method", value="threshold"),
                # On a loaded machine a stream held up for a moment is late, not stopped.
                Parameter("id_node.flush_after_idle_s", value=5.0),
                Parameter("id_node.stream_idle_s", value=5.0),
            ],
        )
        caving = CavingNode(
            context=context,
            parameter_overrides=[
                Parameter("caving_node.rule", value=RULE),
                Parameter("caving_node.open_at_s", value=0.2),
                Parameter("caving_node.settle_s", value=0.5),
                Parameter("caving_node.max_open_s", value=30.0),
            ],
        )
        for node in (recorder, ident, caving):
            executor.add_node(node)
        spin_for(executor, 0.5)
        sim = SimNode(
            context=context,
            parameter_overrides=[
                Parameter("sim_node.realtime_factor", value=0.0),
                Parameter("sim_node.wait_for_subscribers", value=2),
                Parameter("sim_node.subscriber_settle_s", value=0.3),
                Parameter("sim_node.exit_after_idle_s", value=0.5),
                Parameter("scenario.source", value="flow"),
                Parameter("flow.lumps_per_s", value=15.0),
                # Pure coal for the first 20 kg (about 3 s), then the gangue share rises.
                Parameter("flow.share_drawn_mass_kg", value=[0.0, 20.0, 60.0]),
                Parameter("flow.share_gangue", value=[0.0, 0.0, 0.8]),
            ],
        )
        executor.add_node(sim)
        assert spin_until(executor, lambda: caving.round_done, timeout_s=60)
        assert spin_until(executor, lambda: sim.finished.done(), timeout_s=30)
        sim.close()
        executor.remove_node(sim)

        def blocks() -> tuple[int, int]:
            return recorder.vibration.blocks, ident.received[topics.VIBRATION]

        seen = (-1, -2)
        deadline = time.monotonic() + 60.0
        while (seen[0] != seen[1] or seen != blocks()) and time.monotonic() < deadline:
            seen = blocks()
            spin_for(executor, 0.5)
        assert seen[0] == seen[1] > 0
        recorder.close()
        executor.remove_node(recorder)
    assert sim.flow is not None and not sim.flow.is_open
    (window,) = caving.windows
    assert window.closed_by == "rule" and window.refused == {}
    live = caving.decisions[0]
    assert live["rule"] == RULE and live["evidence"]

    recorded = read_sensors(bag, required=()).json_topics
    states = recorded[topics.WINDOW_STATE]
    assert [s["state"] for s in states] == ["open", "closed"]
    assert recorded[topics.CAVING_DECISION] == [live]
    assert [c["action"] for c in recorded[topics.WINDOW_CMD]] == ["open", "close"]

    shares: list = []
    labels = identify_bag(str(bag), "threshold", calibrate=False, shares=shares)
    rule = rule_factories(caving_section())[RULE]()
    offline = offline_decision(rule, states[0]["stamp_s"], labels, shares)
    assert offline is not None
    assert (offline.stamp_s, offline.reason) == (live["stamp_s"], live["reason"])
    assert live["opened_stamp_s"] == states[0]["stamp_s"]


def test_caving_node_sets_hostile_messages_aside_and_goes_on():
    """Labels and shares that do not read (not JSON, a confidence of 7, NaN in a field, a
    truth without its stamp) are set aside and counted by topic; the node keeps running and a
    good label still reaches an open window's rule."""
    from tail_beam_id.ros.caving_node import CavingNode

    with ros_context() as (context, executor):
        caving = CavingNode(
            context=context,
            parameter_overrides=[Parameter("caving_node.rule", value="first_gangue")],
        )
        client = rclpy_node(context)
        for node in (caving, client):
            executor.add_node(node)
        pubs = {
            name: client.create_publisher(String, name, ros_messages.EVENT_QOS)
            for name in (topics.LABEL, GANGUE_SHARE_TOPIC, topics.GANGUE_SHARE_TRUTH)
        }
        assert spin_until(
            executor, lambda: all(p.get_subscription_count() >= 1 for p in pubs.values()), 10
        )
        spin_for(executor, 0.5)
        window = caving.windows[0]
        window.state, window.opened_s = "open", 0.0  # as the tick opens it, without a sim_node
        window.rule = rule_factories(caving_section())["first_gangue"]()
        hostile = {
            topics.LABEL: [
                "not json",
                json.dumps({"impact_stamp": 1.0, "label": "gangue", "confidence": 7}),
                json.dumps({"impact_stamp": 1.0, "label": "rock", "confidence": 0.9}),
            ],
            GANGUE_SHARE_TOPIC: ["[1, 2]", json.dumps({"share": float("nan")})],
            topics.GANGUE_SHARE_TRUTH: [json.dumps({"share_by_mass": 0.5})],
        }
        for name, texts in hostile.items():
            for text in texts:
                pubs[name].publish(String(data=text))
        assert spin_until(
            executor,
            lambda: sum(window.refused.values()) == sum(map(len, hostile.values())),
            timeout_s=10,
        )
        assert window.refused == {name: len(texts) for name, texts in hostile.items()}
        good = {"impact_stamp": 2.0, "label": "gangue", "confidence": 0.8, "method": "threshold"}
        pubs[topics.LABEL].publish(String(data=json.dumps(good)))
        assert spin_until(executor, lambda: window.state == "closed", timeout_s=10)
    assert window.decision is not None and window.decision.stamp_s == 2.0
    assert "confidence 0.80" in window.decision.reason


def rclpy_node(context):
    from rclpy.node import Node

    return Node("hostile_client", context=context)


def test_caving_node_refuses_an_unknown_rule_by_name():
    """A rule that is none of the caving section's is refused naming caving_node.rule."""
    from tail_beam_id.ros.caving_node import CavingNode

    with ros_context() as (context, _):
        with pytest.raises(InputError, match="caving_node.rule"):
            CavingNode(
                context=context,
                parameter_overrides=[Parameter("caving_node.rule", value="share_0.5")],
            )


def test_one_caving_node_draws_two_supports_one_after_another():
    """Two supports under their own namespaces, each with a stand-in for its sim_node (its
    window_cmd subscribed, its clock published on jack_pressure): the first window opens when its
    clock reaches open_at_s, closes on its first gangue label; only then does the second open,
    on its own clock, and it closes on its own label, not on the first support's."""
    from sensor_msgs.msg import FluidPressure

    from tail_beam_id.ros.caving_node import CavingNode

    supports = ["/support_001", "/support_002"]
    with ros_context() as (context, executor):
        caving = CavingNode(
            context=context,
            parameter_overrides=[
                Parameter("caving_node.rule", value="first_gangue"),
                Parameter("caving_node.supports", value=supports),
                Parameter("caving_node.open_at_s", value=1.0),
                Parameter("caving_node.next_open_delay_s", value=0.5),
                Parameter("caving_node.settle_s", value=0.2),
            ],
        )
        stand_in = rclpy_node(context)
        commands: dict[str, list[str]] = {ns: [] for ns in supports}
        clock, labels = {}, {}
        for ns in supports:
            stand_in.create_subscription(
                String,
                f"{ns}/{topics.WINDOW_CMD}",
                lambda msg, ns=ns: commands[ns].append(json.loads(msg.data)["action"]),
                ros_messages.EVENT_QOS,
            )
            clock[ns] = stand_in.create_publisher(FluidPressure, f"{ns}/jack_pressure", 10)
            labels[ns] = stand_in.create_publisher(
                String, f"{ns}/{topics.LABEL}", ros_messages.EVENT_QOS
            )
        for node in (caving, stand_in):
            executor.add_node(node)

        def tick(ns: str, stamp_s: float) -> None:
            clock[ns].publish(FluidPressure(header=ros_messages.header(stamp_s, "jack")))

        def gangue(ns: str, stamp_s: float) -> None:
            text = {"impact_stamp": stamp_s, "label": "gangue", "confidence": 0.9, "method": "x"}
            labels[ns].publish(String(data=json.dumps(text)))

        assert spin_until(
            executor, lambda: all(p.get_subscription_count() for p in labels.values()), 10
        )
        tick(supports[0], 0.5)
        tick(supports[1], 7.0)
        spin_for(executor, 1.0)
        assert commands == {supports[0]: [], supports[1]: []}  # its clock is not at 1 s yet
        tick(supports[0], 1.2)
        assert spin_until(executor, lambda: commands[supports[0]] == ["open"], 10)
        gangue(supports[1], 7.5)  # the other support's window is not open: no decision
        gangue(supports[0], 1.8)
        assert spin_until(executor, lambda: commands[supports[0]] == ["open", "close"], 10)
        spin_for(executor, 0.5)
        assert commands[supports[1]] == []  # its clock has not moved 0.5 s since its turn came
        tick(supports[1], 7.6)
        assert spin_until(executor, lambda: commands[supports[1]] == ["open"], 10)
        gangue(supports[1], 8.0)
        assert spin_until(executor, lambda: commands[supports[1]] == ["open", "close"], 10)
    assert caving.round_done
    first, second = caving.decisions
    assert (first["support"], first["stamp_s"], first["opened_stamp_s"]) == (supports[0], 1.8, 1.2)
    assert (second["support"], second["stamp_s"], second["opened_stamp_s"]) == (
        supports[1],
        8.0,
        7.6,
    )
    assert caving.windows[1].outside == 1  # the label before its window opened
