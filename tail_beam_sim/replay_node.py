"""``bag_replay``: publishes a bag's messages again with their original timing.

Messages go out in log-time order, each when the wall clock since the start, times ``rate``,
reaches its log time relative to the first message; with ``publish_clock`` the log time is
published on ``/clock``. The recorded bytes are published as they are (serialized), so the
stamps and contents the consumers see are the recorded ones. A bag that is missing, empty,
truncated or not a bag stops the node at start-up with one line naming the problem.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterator

from rclpy.node import Node
from rclpy.task import Future
from rosgraph_msgs.msg import Clock

from tail_beam_sim import ros_messages, topics
from tail_beam_sim.bagread import RawMessage, raw_messages
from tail_beam_sim.errors import InputError, require_range
from tail_beam_sim.node_params import config_defaults, declare_and_read
from tail_beam_sim.ros_spin import PublishBacklog, SubscriberGate, drain, run_node

WAITED_TOPICS = (topics.JACK_PRESSURE, topics.IMU, topics.REBOUND_VELOCITY)


class ReplayNode(Node):
    """Plays one bag into its namespace."""

    def __init__(self, **kwargs) -> None:
        super().__init__("tail_beam_replay", **kwargs)
        params = declare_and_read(self, config_defaults(["replay.yaml"], with_physics=False))["replay"]
        if not params.get("bag_path"):
            raise InputError("replay.bag_path", params.get("bag_path"), "required: the bag directory to publish")
        self.rate = require_range("replay.rate", params.get("rate"), 0.0, 1e6, low_open=True)
        period = require_range("replay.publish_period_s", params.get("publish_period_s"), 0.0, 10.0, low_open=True, unit="s")
        wait_for = int(require_range("replay.wait_for_subscribers", params.get("wait_for_subscribers"), 0, 1000))
        settle = require_range("replay.subscriber_settle_s", params.get("subscriber_settle_s"), 0.0, 60.0, unit="s")
        depth = int(require_range("replay.qos_depth", params.get("qos_depth"), 0, 1e6))
        chosen = list(params.get("topics") or [])
        unknown = sorted(set(chosen) - set(topics.MSG_TYPES))
        if unknown or not chosen:
            raise InputError("replay.topics", chosen, f"must name some of {', '.join(topics.MSG_TYPES)}")
        self._messages: Iterator[RawMessage] = raw_messages(params["bag_path"], chosen)
        self._next: RawMessage | None = next(self._messages)  # opens the bag: errors surface here
        qos = ros_messages.stream_qos(depth)
        self._pubs = {
            topic: self.create_publisher(ros_messages.message_class(topics.MSG_TYPES[topic]), topic, qos) for topic in chosen
        }
        self._clock_pub = self.create_publisher(Clock, "/clock", 10) if params.get("publish_clock") else None
        waited = [self._pubs[t] for t in WAITED_TOPICS if t in self._pubs]
        self._gate = SubscriberGate(waited, wait_for, settle)
        self._origin: tuple[float, int] | None = None  # (wall s, log ns) of the first message
        self.published = 0
        self._backlog = PublishBacklog(self)
        self.finished = Future()
        self.create_timer(period, self._tick)
        self.get_logger().info(f"replaying {params['bag_path']} at rate {self.rate:g}")

    def _tick(self) -> None:
        if not self._backlog.flush():
            return  # a subscriber is behind: wait for it (the timing catches up afterwards)
        if self._next is None:
            if not self.finished.done():
                self.get_logger().info(f"replay done: {self.published} messages")
                self.finished.set_result(True)
            return
        if not (self._origin or self._gate.open()):
            return
        now = time.monotonic()
        if self._origin is None:
            self._origin = (now, self._next.log_time_ns)
        wall0, log0 = self._origin
        due_ns = log0 + int((now - wall0) * self.rate * 1e9)
        while self._next is not None and self._next.log_time_ns <= due_ns:
            message = self._next
            self._backlog.publish(self._pubs[message.topic], message.data)
            self.published += 1
            if self._clock_pub is not None:
                self._backlog.publish(self._clock_pub, Clock(clock=ros_messages.time_msg(message.log_time_ns * 1e-9)))
            try:
                self._next = next(self._messages, None)
            except InputError as exc:  # damaged past its start: say so and stop
                self.get_logger().error(f"replay stopped: {exc}")
                self._next = None
            if not self._backlog.flush():
                return

    def close(self) -> None:
        """Before exiting: let the subscribers have every message published."""
        drain(self, self._pubs.values())


def main(args: list[str] | None = None) -> int:
    """Replay the bag, then exit."""
    return run_node(ReplayNode, "bag_replay", args)


if __name__ == "__main__":
    sys.exit(main())
