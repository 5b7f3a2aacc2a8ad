"""``bag_recorder``: records every contract topic of its namespace to a rosbag2 bag.

Messages arrive serialized (raw subscriptions) and are written as they are, with the node's
clock as log time (simulation time under ``use_sim_time``), through
:class:`tail_beam_sim.bagwrite.SegmentedBagWriter`: a SIGINT or SIGTERM closes a valid bag, a
SIGKILL loses at most the open segment (``segment_s``). Topics are stored under their contract
names, so a bag replays into any namespace.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from rclpy.node import Node

from tail_beam_sim import ros_messages, topics
from tail_beam_sim.bagwrite import SegmentedBagWriter
from tail_beam_sim.errors import require_range
from tail_beam_sim.node_params import config_defaults, declare_and_read
from tail_beam_sim.ros_spin import run_node


def default_bag_path() -> Path:
    """bags/tail_beam_<UTC date-time> in the working directory."""
    return Path("bags") / time.strftime("tail_beam_%Y%m%dT%H%M%SZ", time.gmtime())


class RecorderNode(Node):
    """Writes the suite's topics to a bag until stopped."""

    def __init__(self, **kwargs) -> None:
        super().__init__("tail_beam_recorder", **kwargs)
        params = declare_and_read(self, config_defaults(["recorder.yaml"], with_physics=False))["recorder"]
        segment_s = require_range("recorder.segment_s", params.get("segment_s"), 0.0, 3600.0, low_open=True, unit="s")
        depth = int(require_range("recorder.qos_depth", params.get("qos_depth"), 0, 1e6))
        self.bag_path = Path(params.get("bag_path") or default_bag_path())
        self.writer = SegmentedBagWriter(self.bag_path, params.get("storage", "mcap"))
        qos = ros_messages.stream_qos(depth)
        for topic, msgtype in topics.MSG_TYPES.items():
            self.create_subscription(ros_messages.message_class(msgtype), topic, lambda data, t=topic: self._write(t, data), qos, raw=True)
        self.create_timer(segment_s, self.writer.close_segment)
        self.get_logger().info(f"recording {', '.join(topics.MSG_TYPES)} to {self.bag_path} ({self.writer.storage})")

    def _write(self, topic: str, data: bytes) -> None:
        self.writer.write(topic, self.get_clock().now().nanoseconds, data)

    def close(self) -> None:
        """Close the bag (every message received so far is in it)."""
        self.writer.close()
        print(f"bag_recorder: closed {self.bag_path}: {self.writer.message_count} messages", file=sys.stderr)


def main(args: list[str] | None = None) -> int:
    """Record until SIGINT or SIGTERM, then close the bag."""
    return run_node(RecorderNode, "bag_recorder", args)


if __name__ == "__main__":
    sys.exit(main())
