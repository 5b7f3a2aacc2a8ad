"""sim_node with scenario.source flow over the real middleware: the window opened and closed on
window_cmd (bad and repeated commands refused by name, the node running on), each lump's truth
on impact_truth, the true share per interval on gangue_share_truth, and bag_recorder recording
the new topics."""

from __future__ import annotations

import json

import pytest
from rcl_interfaces.msg import Log
from rclpy.parameter import Parameter
from rosprobe import RELIABLE, Probe, ros_context, spin_for, spin_until
from std_msgs.msg import String

from tail_beam_sim import topics
from tail_beam_sim.bags.read import read_sensors

pytestmark = pytest.mark.ros

FLOW = {
    "scenario.source": "flow",
    "flow.lumps_per_s": 60.0,
    "flow.onset_delay_s": 0.1,
    "flow.interval_s": 0.5,
    "flow.share_drawn_mass_kg": [0.0, 15.0, 40.0],
    "flow.share_gangue": [0.0, 0.0, 1.0],
    "sim_node.realtime_factor": 1.0,
    "sim_node.wait_for_subscribers": 1,
    "sim_node.subscriber_settle_s": 0.3,
}


def warnings(probe: Probe) -> list[str]:
    return [m.msg for m in probe.messages["/rosout"] if m.name.endswith("tail_beam_sim")]


def test_flow_opened_and_closed_on_window_cmd_with_share_truth_recorded(tmp_path):
    """sim_node's flow on window_cmd: refusals by name, share truth per interval matching the
    lump truths, all recorded."""
    from tail_beam_sim.ros.recorder_node import RecorderNode
    from tail_beam_sim.ros.sim_node import SimNode

    bag = tmp_path / "bag"
    with ros_context() as (context, executor):
        recorder = RecorderNode(
            context=context, parameter_overrides=[Parameter("recorder.bag_path", value=str(bag))]
        )
        sim = SimNode(
            context=context,
            parameter_overrides=[Parameter(k, value=v) for k, v in FLOW.items()],
        )
        probe = Probe(
            context,
            {topics.IMPACT_TRUTH: String, topics.GANGUE_SHARE_TRUTH: String, "/rosout": Log},
        )
        window = probe.create_publisher(String, topics.WINDOW_CMD, RELIABLE)
        for node in (recorder, sim, probe):
            executor.add_node(node)

        def send(text: str) -> None:
            window.publish(String(data=text))

        def refused(*words: str) -> bool:
            return any(all(w in line for w in words) for line in warnings(probe))

        assert spin_until(
            executor,
            lambda: (
                window.get_subscription_count() >= 2
                and sim._started
                and sim.count_subscribers(topics.GANGUE_SHARE_TRUTH) >= 2
            ),
        )
        send(json.dumps({"action": "close"}))
        assert spin_until(executor, lambda: refused("window_cmd.action = 'close'", "already"))
        send("{oops")
        assert spin_until(executor, lambda: refused("window_cmd = '{oops'", "must be JSON"))
        send(json.dumps({"action": "open", "when": 3}))
        assert spin_until(executor, lambda: refused("unknown field(s) when"))
        assert not sim.flow.is_open and sim.flow.lumps_submitted == 0
        send(json.dumps({"action": "open"}))
        assert spin_until(
            executor, lambda: len(probe.messages[topics.GANGUE_SHARE_TRUTH]) >= 4, timeout_s=30
        )
        send(json.dumps({"action": "open"}))
        assert spin_until(executor, lambda: refused("window_cmd.action = 'open'", "already open"))
        send(json.dumps({"action": "close"}))
        assert spin_until(executor, lambda: sim.flow.source.exhausted and sim.stream.queued == 0)
        spin_for(executor, 1.5)  # the last interval ends, the last truths come out
        assert sim.flow.source.windows[0][1] > sim.flow.source.windows[0][0]
        sim.close()
        spin_for(executor, 0.5)
        recorder.close()
    shares = probe.json(topics.GANGUE_SHARE_TRUTH)
    truths = probe.json(topics.IMPACT_TRUTH)
    assert len(truths) == sim.flow.lumps_submitted > 0
    assert set(shares[0]) >= {
        "start_stamp_s",
        "end_stamp_s",
        "share_by_mass",
        "share_by_count",
        "lumps",
        "mass_kg",
    }
    for before, after in zip(shares, shares[1:]):
        assert after["start_stamp_s"] == pytest.approx(before["end_stamp_s"])
    opened, closed = sim.flow.source.windows[0]
    assert shares[0]["start_stamp_s"] <= opened < shares[0]["end_stamp_s"]
    assert shares[-1]["end_stamp_s"] >= closed + 0.1
    for share in shares:  # each interval's counts are those of the lump truths stamped in it
        inside = [
            t
            for t in truths
            if share["start_stamp_s"] <= t["contact_start_stamp"] < share["end_stamp_s"]
        ]
        assert share["lumps"] == len(inside)
        assert share["gangue_lumps"] == sum(t["label"] == "gangue" for t in inside)
        assert share["mass_kg"] == pytest.approx(sum(t["mass_kg"] for t in inside))
    by_mass = [s["share_by_mass"] for s in shares if s["lumps"]]
    assert by_mass[0] == 0.0 and max(by_mass) > 0.5  # pure coal, then the boundary
    recorded = read_sensors(bag, required=())
    assert recorded.json_topics[topics.GANGUE_SHARE_TRUTH] == shares
    # every command as published, the refused ones too (the malformed one kept as text)
    assert recorded.json_topics[topics.WINDOW_CMD] == [
        {"action": "close"},
        {"_unparsed": "{oops"},
        {"action": "open", "when": 3},
        {"action": "open"},
        {"action": "open"},
        {"action": "close"},
    ]
    assert len(recorded.json_topics[topics.IMPACT_TRUTH]) == len(truths)
