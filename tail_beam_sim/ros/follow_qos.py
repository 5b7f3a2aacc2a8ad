"""Sensor-topic subscriptions that take the reliability their publishers offer.

sim_node publishes the sensor topics best effort when paced and reliable when as fast as
possible (tail_beam_sim.ros.messages.sensor_writer_qos); bag_replay and foreign drivers may
offer either. A reliable reader never matches a best-effort writer, and a best-effort reader of
a reliable writer gives up the writer's flow control (it loses what it cannot take). So the
consumers that must keep everything (id_node, bag_recorder) subscribe as rosbag2 does: reliable
when every publisher offers reliable, best effort otherwise, re-subscribing when that changes.
They start reliable: a reliable writer then never sees them best effort (no switch, nothing
lost across one), and a best-effort writer never matches them before they have switched (its
subscriber count, which sim_node waits for, counts only the best-effort subscription).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import ReliabilityPolicy

from tail_beam_sim.ros import messages as ros_messages

FOLLOW_PERIOD_S = 0.1  # how often the publishers' offered QoS is looked at, s
RELIABLE_READER_CHECK_S = 1.0  # how often a best-effort writer looks for reliable readers, s
RELIABLE_READER_GRACE_S = 2.0  # a reliable reader there this long (wall s) is warned of


class FollowingSubscription:
    """One sensor topic's subscription, re-made with the reliability every publisher offers
    (:meth:`follow`, called on a timer: :func:`follow_publishers`)."""

    def __init__(
        self,
        node: Node,
        msg_type: type,
        topic: str,
        callback: Callable[[Any], None],
        depth: int,
        **kwargs: Any,
    ) -> None:
        self._node = node
        self._msg_type = msg_type
        self.topic = topic
        self._callback = callback
        self._depth = depth
        self._kwargs = kwargs
        self._name = node.resolve_topic_name(topic)
        self.reliable = True
        self.resubscribed = 0  # times the subscription was re-made
        self.subscription = self._create()

    def _create(self) -> Any:
        # A publisher of the other reliability is expected (this subscription follows it): no
        # incompatible-QoS event handler (rclpy's default one warns), the switch is logged
        # instead. An event queued for a subscription destroyed by the switch would make
        # EventsExecutor raise InvalidHandle (tail_beam_sim.ros.spin.spin_once).
        kwargs = {
            "event_callbacks": SubscriptionEventCallbacks(use_default_callbacks=False),
            **self._kwargs,
        }
        return self._node.create_subscription(
            self._msg_type,
            self.topic,
            self._callback,
            ros_messages.sensor_reader_qos(self._depth, self.reliable),
            **kwargs,
        )

    def follow(self) -> bool:
        """Re-subscribe if the publishers now offer another reliability; True if it did."""
        offered = [
            info.qos_profile.reliability
            for info in self._node.get_publishers_info_by_topic(self._name)
        ]
        if not offered:
            return False
        reliable = all(r == ReliabilityPolicy.RELIABLE for r in offered)
        if reliable == self.reliable:
            return False
        self._node.destroy_subscription(self.subscription)
        self.reliable = reliable
        self.subscription = self._create()
        self.resubscribed += 1
        return True


def follow_publishers(node: Node, subscriptions: list[FollowingSubscription]) -> None:
    """Keep ``subscriptions`` following their publishers, every FOLLOW_PERIOD_S."""

    def follow() -> None:
        for subscription in subscriptions:
            if subscription.follow():
                node.get_logger().info(
                    f"{subscription.topic}: subscribed "
                    f"{'reliable' if subscription.reliable else 'best effort'}, as its "
                    "publishers offer"
                )

    node.create_timer(FOLLOW_PERIOD_S, follow)


class ReliableReaderWatch:
    """A best-effort sensor writer's check for reliable readers, which it never serves: each
    one still there RELIABLE_READER_GRACE_S after it was first seen (id_node and bag_recorder
    start reliable and switch within FOLLOW_PERIOD_S) is warned of once, with its node, and
    counted (``count``)."""

    def __init__(self, node: Node, topics: Sequence[str]) -> None:
        self._node = node
        self._topics = [node.resolve_topic_name(t) for t in topics]
        self._first_seen: dict[tuple[str, str], float] = {}
        self._said: set[tuple[str, str]] = set()
        self.count = 0
        node.create_timer(RELIABLE_READER_CHECK_S, self.check)

    def check(self) -> None:
        now = time.monotonic()
        for topic in self._topics:
            for info in self._node.get_subscriptions_info_by_topic(topic):
                if info.qos_profile.reliability != ReliabilityPolicy.RELIABLE:
                    continue
                key = (topic, bytes(info.endpoint_gid).hex())
                first = self._first_seen.setdefault(key, now)
                if key in self._said or now - first < RELIABLE_READER_GRACE_S:
                    continue
                self._said.add(key)
                self.count += 1
                reader = f"{info.node_namespace.rstrip('/')}/{info.node_name}"
                self._node.get_logger().warning(
                    f"{topic}: a reader (node {reader}) asks for reliable delivery, which this "
                    "best-effort sensor writer does not offer: it gets no data until it "
                    "subscribes best effort (qos_profile_sensor_data-like, docs/nodes.md); "
                    f"{self.count} such reader(s) so far"
                )
