"""``bag_recorder``: records every contract topic of its namespace to a rosbag2 bag.

Messages arrive serialized (raw subscriptions) and are written as they are, with the node's
clock as log time (simulation time under ``use_sim_time``), through
:class:`tail_beam_sim.bags.write.SegmentedBagWriter`: a SIGINT or SIGTERM closes a valid bag, a
SIGKILL loses only what came after the open segment's last flush (``flush_s``), and
``tail-beam bag repair`` salvages the rest of that segment. Topics are stored under their fully
qualified names (``/support_07/imu``, ``/imu`` in the root namespace), as rosbag2 stores them;
bag_replay and ``tail-beam identify`` find the contract topics under any namespace. Every
parameter is read at start-up only, so changes at run time (``use_sim_time`` included, which
would rewrite the log times) are refused.

Like ``ros2 bag record``: a new file every ``max_bag_duration_s`` of log time (at least 1 s) or
``max_bag_size_bytes`` (at least 1 MiB; 0 = never: a smaller split would write a file per
message and lose most of them), mcap chunks zstd-compressed (``compression``), and a count
of messages lost, reported on exit and kept in the bag's metadata (``custom_data``,
LOST_KEYS): the vibration samples missing from the running index, the jack_pressure and imu
samples missing from their stamp grid (tail_beam_sim.ros.grid_gaps: a reader's overflowing
history is reported by no middleware event), and the middleware's message-lost events.

The sensor topics (jack_pressure, imu, vibration) are subscribed with the reliability their
publishers offer (tail_beam_sim.ros.follow_qos): best effort from a paced sim_node, whose slow
readers cannot hold it up; reliable from an as-fast-as-possible one or a replay, whose flow
control then keeps the recorder from losing anything.

Samples are counted missing only within one consistent block stream (stamps that agree with
the running index, one sample period): a block of another source on the topic (stamped far
ahead with a huge index, a second publisher's interleaved stream) or of another sample period
is recorded, counted apart and warned of (the first, then every WARN_EVERY_BLOCKS-th), never
counted as samples lost. Another stream replaces the one followed only once that one has sent
nothing for SWITCH_AFTER_S while the other went on (a restarted or replaced source).

Like rosbag2, it subscribes to the event topics (rebound_velocity, impact_truth, label) with
the durability their publishers offer: transient-local when every publisher offers it (the
suite's nodes do), so that the events published before the recorder matched them are in the
bag too (a label published in the moment before the match included); volatile as soon as one
publisher does not, since a transient-local subscription would not match it. An event
delivered twice across such a switch is written once.
"""

from __future__ import annotations

import hashlib
import math
import sys
import time
from collections import OrderedDict
from pathlib import Path

import numpy as np
from rclpy.event_handler import QoSMessageLostInfo, SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import LaserScan

from tail_beam_sim import topics
from tail_beam_sim.bags.read import PERIOD_RTOL, TIME_JUMP_S
from tail_beam_sim.bags.records import COMPRESSIONS
from tail_beam_sim.bags.write import SegmentedBagWriter
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.sensors import BlockSequencer, IndexSpan, VibrationBlocks
from tail_beam_sim.ros import messages as ros_messages
from tail_beam_sim.ros.grid_gaps import GridGaps, cdr_stamp_s
from tail_beam_sim.ros.params import (
    ALL_PARAMETERS,
    config_defaults,
    declare_and_read,
    refuse_runtime_changes,
)
from tail_beam_sim.ros.spin import ForeignTypeWatch, run_node
from tail_beam_sim.spec import RECORDER

LOST_KEYS = (
    "tail_beam.vibration_lost_samples",
    "tail_beam.messages_lost_events",
    "tail_beam.jack_pressure_lost_samples",
    "tail_beam.imu_lost_samples",
)  # bag metadata custom_data: index gaps, message-lost events, stamp-grid gaps
DISCOVERY_PERIOD_S = 0.1  # how often the event topics' publishers are looked at, s
RECENT_EVENTS = 1000  # events per topic remembered, so that one delivered twice is written once
REDELIVERY_S = (
    2.0  # after re-subscribing, how long an event already written is taken for a repeat, s (wall)
)


SWITCH_AFTER_S = 0.5  # wall s the followed block stream must be silent before another replaces it
WARN_EVERY_BLOCKS = 1000  # a warning of one kind on the first block and every this many after


class _Track:
    """A block stream as the recorder follows it: where its next block is expected (running
    index, stamp s), its sample period (s), the wall clock (s) of its last block, its span."""

    def __init__(self, index: int, stamp_s: float, period_s: float, now_s: float) -> None:
        self.next_index, self.next_stamp_s, self.period_s = index, stamp_s, period_s
        self.last_arrival_s = now_s
        self.blocks = 0
        self.span = IndexSpan()

    def same_period(self, period_s: float) -> bool:
        return abs(period_s - self.period_s) <= PERIOD_RTOL * self.period_s

    def continues(self, index: int, length: int, stamp_s: float, period_s: float) -> bool:
        """Same period, stamp within TIME_JUMP_S of the next expected, and where the index puts
        it (half a block either way; a block behind the index is the stream's late, repeated or
        misindexed block)."""
        if not self.same_period(period_s) or abs(stamp_s - self.next_stamp_s) > TIME_JUMP_S:
            return False
        implied = self.next_stamp_s + (index - self.next_index) * self.period_s
        return index < self.next_index or abs(stamp_s - implied) <= 0.5 * length * self.period_s

    def extend(self, index: int, length: int, stamp_s: float, now_s: float) -> None:
        if index + length > self.next_index:
            self.next_index, self.next_stamp_s = index + length, stamp_s + length * self.period_s
        self.last_arrival_s = now_s
        self.blocks += 1
        self.span.add(index, length)


OUTPUT_DIR = Path("out")  # where commands put what they write by default (ignored by git)


def default_bag_path(prefix: str = "tail_beam") -> Path:
    """out/bags/<prefix>_<UTC date-time> in the working directory."""
    return OUTPUT_DIR / "bags" / time.strftime(f"{prefix}_%Y%m%dT%H%M%SZ", time.gmtime())


class RecorderNode(Node):
    """Writes the suite's topics to a bag until stopped."""

    def __init__(self, **kwargs) -> None:
        super().__init__("tail_beam_recorder", **kwargs)
        params = declare_and_read(self, config_defaults(["recorder.yaml"], with_physics=False))[
            "recorder"
        ]
        checked = RECORDER.check(params)
        segment_s = checked["segment_s"]
        flush_s = checked["flush_s"]
        depth = checked["qos_depth"]
        max_duration_s = checked["max_bag_duration_s"]
        max_size = checked["max_bag_size_bytes"]
        compression = checked["compression"]
        if compression not in COMPRESSIONS:
            raise InputError(
                "recorder.compression", compression, f"must be one of {', '.join(COMPRESSIONS)}"
            )
        path = checked["bag_path"] or default_bag_path()
        self.names = {
            topic: self.resolve_topic_name(topic) for topic in topics.MSG_TYPES
        }  # contract -> fully qualified
        try:
            self.writer = SegmentedBagWriter(
                path,
                checked["storage"],
                {self.names[t]: m for t, m in topics.MSG_TYPES.items()},
                compression=compression,
                max_duration_s=max_duration_s,
                max_size_bytes=max_size,
            )
        except InputError as exc:
            raise InputError(
                "recorder.bag_path" if exc.field == "bag" else f"recorder.{exc.field}",
                exc.value,
                exc.allowed,
            ) from None
        self.bag_path = self.writer.path
        self.vibration = IndexSpan()  # the block stream followed
        self._followed: _Track | None = None
        self._other: _Track | None = None  # the latest other block stream, not counted
        self._lost_before = 0  # samples missing from block streams followed before this one
        self.stray_blocks = 0  # blocks recorded of another source (not counted as lost)
        self.other_period_blocks = 0  # blocks recorded of another sample period (not counted)
        self._sequence = (
            BlockSequencer()
        )  # the blocks in index order, for an index that does not count samples
        self.lost_events = 0
        self.refused_blocks = (
            0  # vibration messages without a readable block index (recorded, not counted)
        )
        self.qos = ros_messages.stream_qos(depth)
        self._events: dict[str, tuple[object, tuple[DurabilityPolicy, ReliabilityPolicy]]] = {}
        self._recent: dict[str, OrderedDict[bytes, None]] = {
            topic: OrderedDict() for topic in ros_messages.EVENT_TOPICS
        }
        self._resubscribed: dict[
            str, float
        ] = {}  # event topic -> when it was last re-subscribed (monotonic s)
        # Samples missing from the pressure and IMU stamp grids (module docstring).
        self.grid_gaps = {topics.JACK_PRESSURE: GridGaps(), topics.IMU: GridGaps()}
        for topic in topics.MSG_TYPES:
            # Reliable first; the event and sensor topics then follow their publishers
            # (tail_beam_sim.ros.follow_qos says why a sensor topic starts reliable).
            subscription = self._subscribe(topic, self.qos)
            if topic in ros_messages.EVENT_TOPICS or topic in ros_messages.SENSOR_TOPICS:
                self._events[topic] = (
                    subscription,
                    (DurabilityPolicy.VOLATILE, ReliabilityPolicy.RELIABLE),
                )
        self.create_timer(DISCOVERY_PERIOD_S, self._follow_event_publishers)
        self._foreign = ForeignTypeWatch(self, topics.MSG_TYPES)
        self.create_timer(segment_s, self.writer.close_segment)
        if flush_s < segment_s:
            self.create_timer(flush_s, self.writer.flush)
        refuse_runtime_changes(
            self,
            ALL_PARAMETERS,
            "the recorder reads its parameters at start-up only (restart it to change them)",
        )
        self.get_logger().info(
            f"recording {', '.join(self.names.values())} to {self.bag_path} "
            f"({self.writer.storage}, compression {compression})"
        )

    def _subscribe(self, topic: str, qos: QoSProfile) -> object:
        return self.create_subscription(
            ros_messages.message_class(topics.MSG_TYPES[topic]),
            topic,
            lambda data, t=topic: self._write(t, data),
            qos,
            raw=True,
            # a publisher of the other QoS is followed (re-subscribing), not warned of: no
            # incompatible-QoS handler, whose event could outlive a replaced subscription
            event_callbacks=SubscriptionEventCallbacks(
                message_lost=self._on_lost, use_default_callbacks=False
            ),
        )

    def _follow_event_publishers(self) -> None:
        """Subscribe to each event topic with the durability and reliability all its publishers
        offer, and to each sensor topic with their reliability (module docstring),
        re-subscribing when they change."""
        for topic in self._events:
            offered = [
                info.qos_profile for info in self.get_publishers_info_by_topic(self.names[topic])
            ]
            if not offered:
                continue
            durable = topic in ros_messages.EVENT_TOPICS and all(
                q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered
            )
            reliable = all(q.reliability == ReliabilityPolicy.RELIABLE for q in offered)
            wanted = (
                DurabilityPolicy.TRANSIENT_LOCAL if durable else DurabilityPolicy.VOLATILE,
                ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
            )
            subscription, current = self._events[topic]
            if wanted == current:
                continue
            self.destroy_subscription(subscription)
            qos = QoSProfile(
                history=self.qos.history,
                depth=self.qos.depth,
                durability=wanted[0],
                reliability=wanted[1],
            )
            self._events[topic] = (self._subscribe(topic, qos), wanted)
            self._resubscribed[topic] = time.monotonic()
            if (
                wanted[0] == DurabilityPolicy.VOLATILE
                and current[0] == DurabilityPolicy.TRANSIENT_LOCAL
            ):
                self.get_logger().info(
                    f"{self.names[topic]}: a publisher offers volatile durability; recording it "
                    "volatile "
                    "(events published before a subscriber matched are not kept)"
                )

    def _write(self, topic: str, data: bytes) -> None:
        recent = self._recent.get(topic)
        if (
            recent is not None
        ):  # an event topic: one delivered again just after re-subscribing is written once
            key = hashlib.blake2b(data, digest_size=16).digest()
            if (
                key in recent
                and time.monotonic() - self._resubscribed.get(topic, -math.inf) < REDELIVERY_S
            ):
                return
            recent[key] = None
            if len(recent) > RECENT_EVENTS:
                recent.popitem(last=False)
        self.writer.write(self.names[topic], self.get_clock().now().nanoseconds, data)
        grid = self.grid_gaps.get(topic)
        if grid is not None:
            stamp = cdr_stamp_s(data)
            if stamp is not None and grid.add((stamp,)):
                if grid.gap_count == 1 or grid.gap_count % WARN_EVERY_BLOCKS == 0:
                    self.get_logger().warning(
                        f"{topic}: samples missing from the stamp grid: {grid.lost_samples} "
                        f"lost in {grid.gap_count} gap(s) so far"
                    )
            return
        if topic == topics.VIBRATION:
            msg = deserialize_message(data, LaserScan)
            try:
                index = topics.index_from_words(msg.angle_min, msg.angle_max)
                length = topics.block_samples(len(msg.ranges))
            except InputError as exc:  # recorded as it came; `tail-beam identify` will name it too
                self.refused_blocks += 1
                if self.refused_blocks == 1 or self.refused_blocks % 1000 == 0:
                    self.get_logger().warning(
                        "vibration: a message that carries no block, recorded but not counted: "
                        f"{exc} "
                        f"({self.refused_blocks} so far)"
                    )
                return
            if self._follow(msg, index, length):
                self._check_index(msg, index)

    def _follow(self, msg: LaserScan, index: int, length: int) -> bool:
        """Count the block in the stream followed (True), or apart as another source's or
        another period's (False, warned of; module docstring)."""
        period = msg.time_increment
        if not (math.isfinite(period) and period > 0.0):
            self.vibration.add(index, length)  # no period to compare: `identify` names it
            return False
        stamp, now = ros_messages.stamp_s(msg.header.stamp), time.monotonic()
        followed = self._followed
        if followed is None:
            followed = self._followed = _Track(index, stamp, period, now)
            followed.span = self.vibration
        if followed.continues(index, length, stamp, period):
            followed.extend(index, length, stamp, now)
            return True
        other = self._other
        if other is None or not other.continues(index, length, stamp, period):
            other = self._other = _Track(index, stamp, period, now)
        other.extend(index, length, stamp, now)
        if other.blocks >= 2 and now - followed.last_arrival_s >= SWITCH_AFTER_S:
            # the stream followed ended and this one went on: a restarted or replaced source
            self._lost_before += self.vibration.lost_samples
            self._followed, self._other, self.vibration = other, None, other.span
            self._sequence.restart()
            return True
        if followed.same_period(period):
            self.stray_blocks += 1
            n, what = self.stray_blocks, (
                f"running index {index} at stamp {stamp:.6f} s is not the stream recorded "
                f"(next index {followed.next_index} at {followed.next_stamp_s:.6f} s): another "
                "source's block"
            )
        else:
            self.other_period_blocks += 1
            n, what = self.other_period_blocks, (
                f"sample period {period:g} s (time_increment) is not the stream's "
                f"{followed.period_s:g} s: reading this bag sets it aside"
            )
        if n == 1 or n % WARN_EVERY_BLOCKS == 0:
            self.get_logger().warning(
                f"vibration: the block stamped {stamp:.6f} s: {what}; recorded, not counted as "
                f"samples lost ({n} such blocks so far)"
            )
        return False

    def _check_index(self, msg: LaserScan, index: int) -> None:
        """Warn when the block's index is behind the stream's while its stamp is not (a publisher
        whose index words do not count samples: reading the bag will refuse it, naming them),
        first and every 1000th time; a stream whose stamps go back by more than TIME_JUMP_S
        started again (a restarted source) and is followed afresh."""
        period = msg.time_increment
        if not (math.isfinite(period) and period > 0.0):
            return  # no block's period: `tail-beam identify` names it when it reads the bag
        stamp = ros_messages.stamp_s(msg.header.stamp)
        sequence = self._sequence
        samples = np.frombuffer(msg.ranges, dtype=np.float32)
        block = VibrationBlocks(
            np.array([index], dtype=np.int64),
            np.array([samples.size], dtype=np.int64),
            np.array([stamp]),
            samples,
            float(period),
            math.inf,
        )
        if sequence.push(block).misindexed and (
            sequence.misindexed_blocks == 1 or sequence.misindexed_blocks % 1000 == 0
        ):
            self.get_logger().warning(
                f"vibration: the block stamped {stamp:.6f} s has running index {index}, behind "
                "the samples already "
                "recorded while its stamp is not: the publisher's index (angle_min, angle_max) "
                "must count the samples "
                "(docs/interface.md); reading this bag will refuse it "
                f"({sequence.misindexed_blocks} such blocks so far)"
            )

    @property
    def misindexed_blocks(self) -> int:
        """Vibration blocks recorded whose index is behind the stream's while their stamps are
        not."""
        return self._sequence.misindexed_blocks

    @property
    def vibration_lost_samples(self) -> int:
        """Samples missing from the running index of the block streams followed."""
        return self._lost_before + self.vibration.lost_samples

    def _on_lost(self, info: QoSMessageLostInfo) -> None:
        self.lost_events += info.total_count_change

    def loss_report(self) -> str:
        """One line: vibration samples and blocks recorded, samples missing, message-lost
        events."""
        v, grid = self.vibration, self.grid_gaps
        return (
            f"vibration {v.samples} samples in {v.blocks} blocks, {self.vibration_lost_samples} "
            "samples lost (index gaps); "
            f"{self.stray_blocks + self.other_period_blocks} blocks of another source or "
            f"period not counted; jack_pressure {grid[topics.JACK_PRESSURE].lost_samples}, "
            f"imu {grid[topics.IMU].lost_samples} samples lost (stamp-grid gaps); "
            f"{self.lost_events} messages lost (middleware events)"
        )

    def close(self) -> None:
        """Close the bag (every message received so far is in it), with the loss counts."""
        self.writer.set_custom_data(LOST_KEYS[0], str(self.vibration_lost_samples))
        self.writer.set_custom_data(LOST_KEYS[1], str(self.lost_events))
        for key, topic in zip(LOST_KEYS[2:], (topics.JACK_PRESSURE, topics.IMU)):
            self.writer.set_custom_data(key, str(self.grid_gaps[topic].lost_samples))
        self.writer.close()
        print(
            f"bag_recorder: closed {self.bag_path}: {self.writer.message_count} messages; "
            f"{self.loss_report()}",
            file=sys.stderr,
        )


def main(args: list[str] | None = None) -> int:
    """Record until SIGINT or SIGTERM, then close the bag."""
    return run_node(RecorderNode, "bag_recorder", args)


if __name__ == "__main__":
    sys.exit(main())
