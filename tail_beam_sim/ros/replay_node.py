"""``bag_replay``: publishes a bag's messages again with their original timing.

Messages go out in log-time order, each when the wall clock since the start, times ``rate``,
reaches its log time relative to the first message; with ``publish_clock`` the log time is
published on ``/clock``. The recorded bytes are published as they are (serialized), so the
stamps and contents the consumers see are the recorded ones. ``replay.topics`` chooses what is
published: the sensor topics by default, so a replayed bag is identified afresh instead of
echoing the recorded ``label``s (name ``label`` or ``impact_truth`` to publish them too). A bag
that is missing, empty, truncated, not a bag or without any of those topics stops the node at
start-up with one line naming the problem. Every parameter is read at start-up only, so changes
at run time are refused.

Like ``ros2 bag play``: ``rate`` (0.01 to 100 times the recorded speed), ``start_offset_s``
(skip that much log time from the first message; past the bag's end is refused, naming its
duration), ``topics`` (contract names), ``publish_clock`` and ``loop`` (start again at the end;
refused for messages at a single instant, which would replay without pause). The bag's topics are
found under any namespace and published under the node's own (relative names); a bag of several
supports needs ``namespace`` to say which one.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterator

from rclpy.node import Node
from rclpy.task import Future
from rosgraph_msgs.msg import Clock

from tail_beam_sim import topics
from tail_beam_sim.bags.read import RawMessage, open_segments_note, raw_messages
from tail_beam_sim.errors import InputError
from tail_beam_sim.ros import messages as ros_messages
from tail_beam_sim.ros.params import (
    ALL_PARAMETERS,
    config_defaults,
    declare_and_read,
    refuse_runtime_changes,
)
from tail_beam_sim.ros.spin import PublishBacklog, SubscriberGate, drain, run_node
from tail_beam_sim.spec import REPLAY

WAITED_TOPICS = (topics.JACK_PRESSURE, topics.IMU, topics.VIBRATION, topics.REBOUND_VELOCITY)


class ReplayNode(Node):
    """Plays one bag into its namespace."""

    def __init__(self, **kwargs) -> None:
        super().__init__("tail_beam_replay", **kwargs)
        params = declare_and_read(self, config_defaults(["replay.yaml"], with_physics=False))[
            "replay"
        ]
        checked = REPLAY.check(params)
        if not checked["bag_path"]:
            raise InputError(
                "replay.bag_path", params.get("bag_path"), "required: the bag directory to publish"
            )
        self.rate = checked["rate"]
        period = checked["publish_period_s"]
        wait_for = checked["wait_for_subscribers"]
        settle = checked["subscriber_settle_s"]
        depth = checked["qos_depth"]
        chosen = checked["topics"]
        unknown = sorted(set(chosen) - set(topics.MSG_TYPES))
        if unknown or not chosen:
            raise InputError(
                "replay.topics", chosen, f"must name some of {', '.join(topics.MSG_TYPES)}"
            )
        self.start_offset_s = checked["start_offset_s"]
        self.loop = checked["loop"]
        self.namespace = checked["namespace"] or None
        self._chosen = chosen
        self._bag_path = params["bag_path"]
        self._open()  # opens the bag: errors surface here
        if self._next is None and self._skipped_span_s is not None:
            raise InputError(
                "replay.start_offset_s",
                self.start_offset_s,
                f"is past the end of the bag: its messages on replay.topics span "
                f"{self._skipped_span_s:g} s of log time",
            )
        if self._next is None:
            raise InputError(
                "replay.bag_path",
                params["bag_path"],
                f"holds no messages on replay.topics ({', '.join(chosen)})",
            )
        if self.loop and not self._spans_log_time():
            raise InputError(
                "replay.loop",
                True,
                "needs messages on replay.topics that span some log time after start_offset_s; "
                "these are all at one instant, so every pass would start again at once",
            )
        qos = ros_messages.stream_qos(depth)
        self._pubs = {
            topic: self.create_publisher(
                ros_messages.message_class(topics.MSG_TYPES[topic]), topic, qos
            )
            for topic in chosen
        }
        self._clock_pub = (
            self.create_publisher(Clock, "/clock", 10) if params.get("publish_clock") else None
        )
        waited = [self._pubs[t] for t in WAITED_TOPICS if t in self._pubs]
        self._gate = SubscriberGate(waited, wait_for, settle)
        self._origin: tuple[float, int] | None = None  # (wall s, log ns) of the first message
        self.loops = 0
        self.published = 0
        self.exit_status = (
            0  # 1 once the bag turned out damaged part-way (the process's exit status)
        )
        self._backlog = PublishBacklog(self)
        self.finished = Future()
        self.create_timer(period, self._tick)
        refuse_runtime_changes(
            self,
            ALL_PARAMETERS,
            "bag_replay reads its parameters at start-up only (restart it to change them)",
        )
        self.get_logger().info(
            f"replaying {', '.join(chosen)} of {params['bag_path']} at rate {self.rate:g}"
        )
        note = open_segments_note(self._bag_path)
        if note:
            self.get_logger().warning(note)

    def _open(self) -> None:
        """(Re)start at the first message at or after the start offset."""
        self._messages: Iterator[RawMessage] = raw_messages(
            self._bag_path, self._chosen, namespace=self.namespace
        )
        self._next: RawMessage | None = next(self._messages, None)
        self._skipped_span_s: float | None = None  # log time of what the offset skipped, s
        if self._next is not None and self.start_offset_s > 0.0:
            first_ns = last_ns = self._next.log_time_ns
            start_ns = first_ns + int(round(self.start_offset_s * 1e9))
            while self._next is not None and self._next.log_time_ns < start_ns:
                last_ns = self._next.log_time_ns
                self._next = next(self._messages, None)
            if self._next is None:
                self._skipped_span_s = (last_ns - first_ns) * 1e-9
        self._origin = None

    def _spans_log_time(self) -> bool:
        """Whether the messages played (from the start offset on) span more than one instant:
        a looping replay of a single instant would start its next pass at once, forever. Reads
        the bag afresh up to the first message later than the first one played."""
        first_ns = self._next.log_time_ns if self._next is not None else None
        messages = raw_messages(self._bag_path, self._chosen, namespace=self.namespace)
        return any(m.log_time_ns > first_ns for m in messages if first_ns is not None)

    def _tick(self) -> None:
        if not self._backlog.flush():
            return  # a subscriber is behind: wait for it (the timing catches up afterwards)
        if self._next is None and self.loop and self.published:
            self.loops += 1
            try:
                self._open()
            except (
                InputError
            ) as exc:  # the bag went away or was damaged since the last pass: as part-way
                self.get_logger().error(f"replay stopped: pass {self.loops + 1}: {exc}")
                self.exit_status = 1
                self._next = None
                self.loop = False
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
                self._backlog.publish(
                    self._clock_pub, Clock(clock=ros_messages.time_msg(message.log_time_ns * 1e-9))
                )
            try:
                self._next = next(self._messages, None)
            except InputError as exc:  # damaged past its start: say so, stop, exit non-zero
                self.get_logger().error(f"replay stopped: {exc}")
                self.exit_status = 1
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
