"""id_node publishes the flow's gangue share on ``gangue_share``, and its messages are the ones
``tail-beam identify`` gives for the recorded bag (real rclpy nodes, a real rosbag2 bag)."""

from __future__ import annotations

import json
import time

import pytest
from rclpy.parameter import Parameter
from rosprobe import Probe, ros_context, spin_for, spin_until
from std_msgs.msg import String

from tail_beam_id.cli.identify_cmd import identify_bag
from tail_beam_id.ros.id_node import GANGUE_SHARE_TOPIC
from tail_beam_id.stream.share import GangueShare
from tail_beam_sim import topics

pytestmark = pytest.mark.ros
COUNT = 10  # impacts of the generated caving stream (about 3.5 s of data)


def test_id_node_publishes_the_gangue_share_that_identify_gives_offline(tmp_path):
    """id_node's gangue_share messages on a live sim_node stream equal tail-beam identify's shares
    of the recorded bag."""
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
                Parameter("id_node.flush_after_idle_s", value=0.3),
            ],
        )
        probe = Probe(context, {GANGUE_SHARE_TOPIC: String, topics.IMPACT_TRUTH: String})
        for node in (recorder, ident, probe):
            executor.add_node(node)
        spin_for(executor, 0.5)
        sim = SimNode(
            context=context,
            parameter_overrides=[
                Parameter("sim_node.realtime_factor", value=0.0),
                Parameter("sim_node.wait_for_subscribers", value=2),
                Parameter("sim_node.subscriber_settle_s", value=0.3),
                Parameter("sim_node.exit_after_idle_s", value=0.5),
                Parameter("scenario.source", value="generated"),
                Parameter("scenario.count", value=COUNT),
            ],
        )
        executor.add_node(sim)
        assert spin_until(executor, lambda: sim.finished.done(), timeout_s=90)
        sim.close()
        executor.remove_node(sim)
        assert spin_until(
            executor, lambda: len(probe.messages[topics.IMPACT_TRUTH]) == COUNT, timeout_s=20
        )

        # On a busy machine either node may still work through its backlog: once both have had
        # the same vibration blocks for a while, the bag holds what id_node was given.
        def blocks() -> tuple[int, int]:
            return recorder.vibration.blocks, ident.received[topics.VIBRATION]

        seen = (-1, -2)
        deadline = time.monotonic() + 120.0
        while (seen[0] != seen[1] or seen != blocks()) and time.monotonic() < deadline:
            seen = blocks()
            spin_for(executor, 1.0)
        assert seen[0] == seen[1] > 0
        recorder.close()
        executor.remove_node(recorder)
        offline: list[GangueShare] = []
        identify_bag(str(bag), "threshold", calibrate=False, shares=offline)
        assert len(offline) >= 3
        # id_node flushes once its data has stopped for flush_after_idle_s.
        assert spin_until(
            executor,
            lambda: len(probe.messages[GANGUE_SHARE_TOPIC]) >= len(offline),
            timeout_s=120,
        )
        spin_for(executor, 1.0)
    live = [GangueShare.from_json(m.data) for m in probe.messages[GANGUE_SHARE_TOPIC]]
    assert ident.shares_published == len(live)
    ends = [s.end_stamp_s for s in live]
    assert ends == sorted(ends) and sum(s.lumps >= 1 for s in live) >= 3
    assert [json.loads(s.to_json()) for s in live] == [json.loads(s.to_json()) for s in offline]
