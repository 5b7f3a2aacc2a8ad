"""``id_node``: a ROS 2 node over :class:`tail_beam_id.identifier.StreamIdentifier`.

Subscribes to ``jack_pressure``, ``imu``, ``vibration`` and ``rebound_velocity`` (never ``impact_truth``),
buffers what arrives, and every ``poll_period_s`` hands the buffers to the identifier and
publishes its labels on ``label``. The identifier decides from stamps and contents only, so
the labels do not depend on how the topics interleave on arrival. When no sensor message has
come for ``flush_after_idle_s`` (the data ended, or every stream stopped) the pending impacts
are decided from what there is. Spun by ``rclpy.experimental.EventsExecutor``, which keeps
up with thousands of messages per second where the default executor loses some.

The ``vibration`` blocks are decoded with numpy and kept in running-index order by a
:class:`tail_beam_sim.physics.sensors.BlockSequencer`: a jump in the index is a lost block,
logged with the count of samples missing; a block that comes after a later one was handed on
is refused and counted (``vibration_lost_samples``, ``vibration_late_blocks``).
"""

from __future__ import annotations

import sys
import math
import time

import numpy as np
from geometry_msgs.msg import TwistStamped
from rclpy.node import Node
from sensor_msgs.msg import FluidPressure, Imu, LaserScan
from std_msgs.msg import String

from tail_beam_id.identifier import StreamIdentifier
from tail_beam_sim import topics
from tail_beam_sim.ros import messages as ros_messages
from tail_beam_sim.errors import require_range
from tail_beam_sim.physics.sensors import BlockSequencer
from tail_beam_sim.ros.params import ALL_PARAMETERS, config_defaults, declare_and_read, refuse_runtime_changes
from tail_beam_sim.ros.spin import run_node


class IdNode(Node):
    """Labels each impact in the sensor streams coal or gangue."""

    def __init__(self, **kwargs) -> None:
        super().__init__("tail_beam_id", **kwargs)
        params = declare_and_read(self, config_defaults(["id_node.yaml"], with_physics=True))
        node = params["id_node"]
        period = require_range("id_node.poll_period_s", node.get("poll_period_s"), 0.0, 10.0, low_open=True, unit="s")
        self.flush_after_idle_s = require_range("id_node.flush_after_idle_s", node.get("flush_after_idle_s"), 0.0, None, low_open=True, unit="s")
        depth = int(require_range("id_node.qos_depth", node.get("qos_depth"), 0, 1e6))
        self.identifier = StreamIdentifier(params.get("method") or None, params=params["identification"], model_params=params)
        self._pressure: list[FluidPressure] = []
        self._imu: list[Imu] = []
        self._rebounds: list[TwistStamped] = []
        self._vibration: list[LaserScan] = []
        self._vib_stamps: list[np.ndarray] = []  # vibration samples sequenced, not yet given to the identifier
        self._vib_values: list[np.ndarray] = []
        self.sequencer = BlockSequencer()
        self._last_arrival_s = time.monotonic()
        self._unflushed = False
        self.received = {topics.JACK_PRESSURE: 0, topics.IMU: 0, topics.VIBRATION: 0, topics.REBOUND_VELOCITY: 0}
        self.published = 0
        sensor_qos = ros_messages.stream_qos(depth)
        event_qos = ros_messages.EVENT_QOS
        self._label_pub = self.create_publisher(String, topics.LABEL, event_qos)
        self.create_subscription(FluidPressure, topics.JACK_PRESSURE, self._on_pressure, sensor_qos)
        self.create_subscription(Imu, topics.IMU, self._on_imu, sensor_qos)
        self.create_subscription(LaserScan, topics.VIBRATION, self._on_vibration, sensor_qos)
        self.create_subscription(TwistStamped, topics.REBOUND_VELOCITY, self._on_rebound, event_qos)
        self.create_timer(period, self._tick)
        refuse_runtime_changes(self, ALL_PARAMETERS, "id_node reads its parameters at start-up only (restart it to change them)")
        self.get_logger().info(f"identifying with method {self.identifier.method.name}")

    def _arrived(self, topic: str) -> None:
        self.received[topic] += 1
        self._last_arrival_s = time.monotonic()
        self._unflushed = True

    def _on_pressure(self, msg: FluidPressure) -> None:
        self._pressure.append(msg)
        self._arrived(topics.JACK_PRESSURE)

    def _on_imu(self, msg: Imu) -> None:
        self._imu.append(msg)
        self._arrived(topics.IMU)

    def _on_vibration(self, msg: LaserScan) -> None:
        self._vibration.append(msg)
        self._arrived(topics.VIBRATION)

    @property
    def vibration_lost_samples(self) -> int:
        return self.sequencer.lost_samples

    @property
    def vibration_late_blocks(self) -> int:
        return self.sequencer.late_blocks

    def _take_vibration(self) -> None:
        """Decode the buffered blocks, put them in index order, report gaps and late blocks."""
        if not self._vibration:
            return
        report = self.sequencer.push(ros_messages.vibration_blocks(self._vibration))
        self._vibration = []
        if report.gaps:
            missing = sum(n for _, n in report.gaps)
            self.get_logger().warning(
                f"vibration: {len(report.gaps)} gap(s), {missing} samples lost (first missing index {report.gaps[0][0]}); "
                f"{self.sequencer.lost_samples} lost in all"
            )
        if report.late:
            self.get_logger().warning(
                f"vibration: {report.late} block(s) arrived after a later one and were refused; {self.sequencer.late_blocks} in all"
            )
        self._feed_vibration(report.accepted)

    def _feed_vibration(self, blocks) -> None:
        """Queue the accepted blocks (in index order) for the identifier's high-rate channel."""
        if blocks.count:
            self._vib_stamps.append(blocks.sample_stamps_s())
            self._vib_values.append(blocks.accel_mps2.astype(float))

    def _release_vibration(self, everything: bool) -> None:
        """Hand the identifier the queued vibration samples no later than the per-sample streams
        it has (jack pressure, IMU) plus half the stream timeout. A few large vibration blocks
        arrive ahead, in wall time, of thousands of small per-sample messages; fed at once they
        would make those streams look stopped (their stamps lagging the newest by more than
        ``stream_timeout_s``), a decision that depends on arrival, not on the data."""
        if not self._vib_stamps:
            return
        stamps, values = np.concatenate(self._vib_stamps), np.concatenate(self._vib_values)
        seen = [s for s in (self.identifier.pressure.latest_s, self.identifier.imu.latest_s) if s > -math.inf]
        limit = math.inf if everything or not seen else min(seen) + 0.5 * self.identifier.config.stream_timeout_s
        take = stamps <= limit
        if take.any():
            self.identifier.add_vibration(stamps[take], values[take])
        self._vib_stamps, self._vib_values = ([stamps[~take]], [values[~take]]) if not take.all() else ([], [])

    def _on_rebound(self, msg: TwistStamped) -> None:
        self._rebounds.append(msg)
        self._arrived(topics.REBOUND_VELOCITY)

    def _tick(self) -> None:
        """Hand the buffered samples to the identifier; publish what it can decide."""
        if self._pressure:
            self.identifier.add_pressure(*ros_messages.pressure_arrays(self._pressure))
            self._pressure = []
        if self._imu:
            self.identifier.add_imu(*ros_messages.imu_arrays(self._imu))
            self._imu = []
        self._take_vibration()
        idle = self._unflushed and time.monotonic() - self._last_arrival_s > self.flush_after_idle_s
        self._release_vibration(everything=idle)
        for msg in self._rebounds:
            self.identifier.add_rebound(*ros_messages.rebound_values(msg))
        self._rebounds = []
        labels = self.identifier.poll()
        if self._unflushed and time.monotonic() - self._last_arrival_s > self.flush_after_idle_s:
            labels += self.identifier.flush()
            self._unflushed = False
        for label in labels:
            self._label_pub.publish(ros_messages.string_message(label))
            self.published += 1
            self.get_logger().info(
                f"impact at {label['impact_stamp']:.4f} s: {label['label']} ({label['confidence']:.2f}, {label['method']}, "
                f"signals {', '.join(label.get('signals', []))})"
            )


def main(args: list[str] | None = None) -> int:
    """Run id_node until shut down."""
    return run_node(IdNode, "id_node", args)


if __name__ == "__main__":
    sys.exit(main())
