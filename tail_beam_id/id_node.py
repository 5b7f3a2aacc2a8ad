"""``id_node``: a ROS 2 node over :class:`tail_beam_id.identifier.StreamIdentifier`.

Subscribes to ``jack_pressure``, ``imu`` and ``rebound_velocity`` (never ``impact_truth``),
buffers what arrives, and every ``poll_period_s`` hands the buffers to the identifier and
publishes its labels on ``label``. The identifier decides from stamps and contents only, so
the labels do not depend on how the topics interleave on arrival. When no sensor message has
come for ``flush_after_idle_s`` (the data ended, or every stream stopped) the pending impacts
are decided from what there is. Spun by ``rclpy.experimental.EventsExecutor``, which keeps
up with thousands of messages per second where the default executor loses some.
"""

from __future__ import annotations

import sys
import time

from geometry_msgs.msg import TwistStamped
from rclpy.node import Node
from sensor_msgs.msg import FluidPressure, Imu
from std_msgs.msg import String

from tail_beam_id.identifier import StreamIdentifier
from tail_beam_sim import ros_messages, topics
from tail_beam_sim.errors import require_range
from tail_beam_sim.node_params import config_defaults, declare_and_read
from tail_beam_sim.ros_spin import run_node


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
        self._last_arrival_s = time.monotonic()
        self._unflushed = False
        self.received = {topics.JACK_PRESSURE: 0, topics.IMU: 0, topics.REBOUND_VELOCITY: 0}
        self.published = 0
        sensor_qos = ros_messages.stream_qos(depth)
        event_qos = ros_messages.EVENT_QOS
        self._label_pub = self.create_publisher(String, topics.LABEL, event_qos)
        self.create_subscription(FluidPressure, topics.JACK_PRESSURE, self._on_pressure, sensor_qos)
        self.create_subscription(Imu, topics.IMU, self._on_imu, sensor_qos)
        self.create_subscription(TwistStamped, topics.REBOUND_VELOCITY, self._on_rebound, event_qos)
        self.create_timer(period, self._tick)
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
