"""The recorder re-subscribes an event topic when a publisher with other durability appears
(a foreign, volatile one on label). The middleware had meanwhile queued an incompatible-QoS
event for the old subscription; the executor then took it from the destroyed subscription and
raised InvalidHandle out of spin, ending bag_recorder (and `tail-beam demo`, seen in the suite)."""

from __future__ import annotations

import time

import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy
from rosprobe import RELIABLE, ros_context, spin_until
from std_msgs.msg import String

from tail_beam_sim import topics

pytestmark = [pytest.mark.ros]


def test_an_event_of_a_replaced_subscription_does_not_end_the_recorder(tmp_path):
    """Deterministically: the recorder subscribes label transient-local (a publisher offering it,
    as id_node's, is there); a foreign volatile publisher appears and the executor is not spun for
    1 s (the incompatible-QoS event is queued); the recorder re-subscribes volatile; spinning on
    must not raise, and a label published afterwards is in the bag."""
    from tail_beam_sim.bags.read import raw_messages
    from tail_beam_sim.ros import messages as ros_messages
    from tail_beam_sim.ros.recorder_node import RecorderNode
    from tail_beam_sim.ros.spin import spin_once

    foreign = rclpy.Context()
    rclpy.init(context=foreign)
    try:
        with ros_context() as (context, executor):
            recorder = RecorderNode(
                context=context,
                namespace="/resub",
                parameter_overrides=[Parameter("recorder.bag_path", value=str(tmp_path / "bag"))],
            )
            executor.add_node(recorder)
            suite = rclpy.create_node("labeller", namespace="/resub", context=foreign)
            suite.create_publisher(
                String, topics.LABEL, ros_messages.EVENT_PUBLISHER_QOS
            )  # transient-local, as id_node's

            def durable():
                return recorder._events[topics.LABEL][1][0] == DurabilityPolicy.TRANSIENT_LOCAL

            deadline = time.monotonic() + 20
            while not durable() and time.monotonic() < deadline:
                spin_once(executor, 0.02)
            assert durable()
            deadline = time.monotonic() + 0.5
            while time.monotonic() < deadline:
                spin_once(executor, 0.02)
            intruder = rclpy.create_node("intruder", namespace="/resub", context=foreign)
            pub = intruder.create_publisher(String, topics.LABEL, RELIABLE)  # volatile
            time.sleep(1.0)  # discovery runs in the middleware's threads: the event is queued now
            # re-subscribes volatile, destroying the old subscription
            recorder._follow_event_publishers()
            deadline = time.monotonic() + 1.0
            while time.monotonic() < deadline:
                spin_once(executor, 0.02)
            assert spin_until(executor, lambda: pub.get_subscription_count() >= 1)
            pub.publish(String(data='{"after": true}'))
            assert spin_until(executor, lambda: recorder.writer.message_count >= 1)
            recorder.close()
    finally:
        rclpy.try_shutdown(context=foreign)
    assert [m.topic for m in raw_messages(tmp_path / "bag", [topics.LABEL])] == [topics.LABEL]
