"""``sim_node``: a ROS 2 node over :class:`tail_beam_sim.stream.StreamSimulator`.

Takes impacts on ``impact_cmd`` (and a start-up scenario), publishes ``jack_pressure`` and
``imu`` as continuous streams, ``rebound_velocity`` and ``impact_truth`` once per impact, and
``/clock`` on request. A timer advances simulation time by the wall-clock time elapsed times
``realtime_factor`` (0: as fast as possible), at most ``max_chunk_s`` per tick: a short stall
is caught up; when it falls more than ``max_lag_s`` behind it runs slower than real time from
there on. It never skips a sample.
"""

from __future__ import annotations

import json
import math
import sys
import time

import numpy as np
from rclpy.node import Node
from rclpy.task import Future
from geometry_msgs.msg import TwistStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import FluidPressure, Imu
from std_msgs.msg import String

from tail_beam_sim import ros_messages, topics
from tail_beam_sim.errors import InputError, require_range
from tail_beam_sim.node_params import config_defaults, declare_and_read
from tail_beam_sim.ros_spin import ACK_TIMEOUT_S, PublishBacklog, SubscriberGate, drain, run_node
from tail_beam_sim.scenario import load_scenario
from tail_beam_sim.stream import Chunk, QueueFull, StreamSimulator


class SimNode(Node):
    """The simulated support: impacts in, sensor streams out."""

    def __init__(self, **kwargs) -> None:
        super().__init__("tail_beam_sim", **kwargs)
        params = declare_and_read(self, config_defaults(["sim_node.yaml"], with_physics=True))
        node = params["sim_node"]
        self.realtime_factor = require_range("sim_node.realtime_factor", node.get("realtime_factor"), 0.0, 1e6)
        period = require_range("sim_node.publish_period_s", node.get("publish_period_s"), 0.0, 10.0, low_open=True, unit="s")
        self.max_chunk_s = require_range("sim_node.max_chunk_s", node.get("max_chunk_s"), 0.0, 10.0, low_open=True, unit="s")
        self.max_lag_s = require_range("sim_node.max_lag_s", node.get("max_lag_s"), 0.0, 3600.0, unit="s")
        self.exit_after_idle_s = require_range("sim_node.exit_after_idle_s", node.get("exit_after_idle_s"), 0.0, None, unit="s")
        depth = int(require_range("sim_node.qos_depth", node.get("qos_depth"), 0, 1e6))
        wait_for = int(require_range("sim_node.wait_for_subscribers", node.get("wait_for_subscribers"), 0, 1000))
        settle = require_range("sim_node.subscriber_settle_s", node.get("subscriber_settle_s"), 0.0, 60.0, unit="s")
        self.stream = StreamSimulator.from_params(params)
        for planned in load_scenario(params["scenario"], self.stream.materials, self.stream.support):
            self.stream.submit(planned.command, planned.contact_stamp_s)
        self.finished = Future()
        sensor_qos = ros_messages.stream_qos(depth)
        event_qos = ros_messages.EVENT_QOS
        self._pressure_pub = self.create_publisher(FluidPressure, topics.JACK_PRESSURE, sensor_qos)
        self._imu_pub = self.create_publisher(Imu, topics.IMU, sensor_qos)
        self._rebound_pub = self.create_publisher(TwistStamped, topics.REBOUND_VELOCITY, event_qos)
        self._gate = SubscriberGate((self._pressure_pub, self._imu_pub, self._rebound_pub), wait_for, settle)
        self._truth_pub = self.create_publisher(String, topics.IMPACT_TRUTH, event_qos)
        self._clock_pub = self.create_publisher(Clock, "/clock", 10) if node.get("publish_clock") else None
        self.create_subscription(String, topics.IMPACT_CMD, self._on_command, event_qos)
        self._anchor: tuple[float, float] | None = None  # (wall s, simulation s) pacing origin
        self._last_activity_s = 0.0
        self._started = False  # simulation time held at 0 until the subscribers are there
        self._backlog = PublishBacklog(self)  # messages a full writer has not taken yet, in order
        self.create_timer(0.0 if self.realtime_factor == 0.0 else period, self._tick)
        self.get_logger().info(
            f"simulating at realtime_factor {self.realtime_factor:g}: pressure {self.stream.sensors.pressure_rate_hz:g} Hz, "
            f"IMU {self.stream.sensors.imu_rate_hz:g} Hz, {self.stream.queued} impact(s) scheduled"
        )

    def _on_command(self, msg: String) -> None:
        """One impact_cmd: queue it, or log why not (the node keeps running either way)."""
        try:
            command = json.loads(msg.data)
        except json.JSONDecodeError as exc:
            self.get_logger().error(f"impact_cmd rejected: not valid JSON ({exc.msg} at char {exc.pos}): {msg.data[:200]!r}")
            return
        try:
            scheduled = self.stream.submit(command)
        except QueueFull as exc:
            self.get_logger().warning(f"impact_cmd {exc}")
            return
        except InputError as exc:
            self.get_logger().error(f"impact_cmd rejected: {exc}")
            return
        self.get_logger().info(
            f"impact {scheduled.impact_id} queued: contact at {scheduled.contact_stamp_s:.4f} s ({self.stream.queued} queued)"
        )

    def _target_time_s(self, now_s: float) -> float:
        """Simulation time to reach this tick, s."""
        current = self.stream.time_s
        if self.realtime_factor == 0.0:
            return current + self.max_chunk_s
        if self._anchor is None:
            self._anchor = (now_s, current)
        wall0, sim0 = self._anchor
        target = sim0 + (now_s - wall0) * self.realtime_factor
        if target > current + self.max_lag_s:  # too far behind to catch up: slower than real time from here
            self._anchor = (now_s, current)
        return min(target, current + self.max_chunk_s)  # a short stall is caught up, a chunk at a time

    def _tick(self) -> None:
        if not self._started:
            if not self._gate.open():
                return
            self._started = True
        if not self._backlog.flush():
            return  # a subscriber is behind: simulate no further until it has caught up
        chunk = self.stream.advance(self._target_time_s(time.monotonic()))
        self.publish(chunk)
        if self.exit_after_idle_s > 0.0 and self.stream.queued == 0 and not self.finished.done():
            if self.stream.time_s >= self._last_activity_s + self.exit_after_idle_s:
                self.get_logger().info(f"idle for {self.exit_after_idle_s:g} s of simulation time: done")
                self.finished.set_result(True)

    def close(self) -> None:
        """Before exiting: let the subscribers have every message published."""
        deadline = time.monotonic() + ACK_TIMEOUT_S
        while self.context.ok() and not self._backlog.flush() and time.monotonic() < deadline:
            time.sleep(0.01)
        drain(self, (self._pressure_pub, self._imu_pub, self._rebound_pub, self._truth_pub))

    def publish(self, chunk: Chunk) -> None:
        """Publish one chunk: streams in stamp order, then its rebounds and truths."""
        for scheduled in chunk.started:
            self._last_activity_s = max(self._last_activity_s, scheduled.truth_stamp_s)
            self.get_logger().info(
                f"impact {scheduled.impact_id}: {scheduled.impact.material.name} R {scheduled.impact.radius_m * 1e3:.0f} mm "
                f"at {scheduled.contact_stamp_s:.4f} s"
            )
        # Both streams in one stamp order, so that a consumer never sees one run ahead of the other.
        outgoing = [(self._pressure_pub, m) for m in ros_messages.pressure_messages(chunk.pressure)]
        outgoing += [(self._imu_pub, m) for m in ros_messages.imu_messages(chunk.imu)]
        stamps = np.concatenate([chunk.pressure.stamp_s, chunk.imu.stamp_s])
        backlog = self._backlog
        for index in np.argsort(stamps, kind="stable"):
            backlog.publish(*outgoing[index])
        for _, rebound in chunk.rebounds:
            backlog.publish(self._rebound_pub, ros_messages.rebound_message(rebound))
        for _, truth in chunk.truths:
            backlog.publish(self._truth_pub, ros_messages.string_message(truth))
        if self._clock_pub is not None and math.isfinite(chunk.end_s):
            backlog.publish(self._clock_pub, ros_messages.clock_message(chunk.end_s))
        backlog.flush()


def main(args: list[str] | None = None) -> int:
    """Run sim_node until shut down (or idle, with sim_node.exit_after_idle_s)."""
    return run_node(SimNode, "sim_node", args)


if __name__ == "__main__":
    sys.exit(main())
