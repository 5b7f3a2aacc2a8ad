"""``sim_node``: a ROS 2 node over :class:`tail_beam_sim.physics.stream.StreamSimulator`.

Takes impacts on ``impact_cmd`` (and a start-up scenario), publishes ``jack_pressure``,
``imu`` and ``vibration`` (the accelerometer's blocks) as continuous streams, ``rebound_velocity``
and ``impact_truth`` once per impact, and ``/clock`` on request. A timer advances simulation time
by the wall-clock time elapsed times ``realtime_factor`` (0: as fast as possible), at most
``max_chunk_s`` per tick: a short stall is caught up; when it falls more than ``max_lag_s`` behind
it runs slower than real time from there on. It never skips a sample.

Every ``impact_cmd`` is either queued (and simulated) or refused with one log line naming the
field and the allowed range, and a running count (:class:`CommandCounts`); the subscription
keeps all messages (reliable, keep-all), so none is dropped unseen however fast they come. A
start-up scenario is fed to the stream as its impacts fall due, never queued whole. Parameters
are read once at start-up: changes at run time are refused with the reason.

With ``scenario.source: flow`` it simulates a drawing opening's flow of lumps
(:class:`tail_beam_sim.physics.flow.FlowRun`, section ``flow``): the window opens and closes on
``window_cmd`` (or at start-up, ``flow.open_at_s``), each lump's truth goes out on
``impact_truth`` and the true gangue share of each interval on ``gangue_share_truth``. A
window command for a window already in that state, or one that is no command, is refused with a
warning naming it.
"""

from __future__ import annotations

import math
import sys
import time
from collections import deque
from dataclasses import dataclass

import numpy as np
from geometry_msgs.msg import TwistStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.task import Future
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import FluidPressure, Imu, LaserScan
from std_msgs.msg import String

from tail_beam_sim import topics
from tail_beam_sim.errors import InputError, shorten
from tail_beam_sim.physics.command import parse_command
from tail_beam_sim.physics.flow import FlowRun, ShareInterval, parse_window_command
from tail_beam_sim.physics.scenario import PlannedImpact, load_scenario
from tail_beam_sim.physics.solvers import SolverError
from tail_beam_sim.physics.stream import Chunk, QueueFull, StreamSimulator
from tail_beam_sim.physics.superpose import FlowSimulator
from tail_beam_sim.ros import messages as ros_messages
from tail_beam_sim.ros.params import config_defaults, declare_and_read
from tail_beam_sim.ros.spin import (
    ACK_TIMEOUT_S,
    ForeignTypeWatch,
    PublishBacklog,
    SubscriberGate,
    drain,
    run_node,
)
from tail_beam_sim.ros.usage import NodeUsage
from tail_beam_sim.spec import SIM_NODE

# exit_after_idle_s -1 (auto): idle time before exiting after a file or generated scenario, s
SCENARIO_IDLE_S = 1.0

USAGE = NodeUsage(
    executable="sim_node",
    summary="The simulated tail beam: takes impacts on impact_cmd (and a start-up scenario) "
    "and publishes "
    "jack_pressure, imu, rebound_velocity and impact_truth (docs/interface.md).",
    config_files=("sim_node.yaml", "flow.yaml"),
    examples=(
        "sim_node                                                  # wait for impact_cmd (see "
        "tail-beam send)",
        "sim_node --ros-args -p scenario.source:=generated -p scenario.count:=40 -p "
        "sim_node.realtime_factor:=0",
        "sim_node --ros-args -p scenario.source:=file -p scenario.file:=impacts.yaml",
        "sim_node --ros-args -p scenario.source:=flow -p flow.lumps_per_s:=200   # open it on "
        "window_cmd",
        "sim_node --ros-args -r __ns:=/support_07 --params-file my.yaml",
    ),
)


# Every line refusing a command starts so: "impact_cmd rejected: ...", "refused", "not simulated".
REFUSAL_PREFIX = "impact_cmd "


def refusal_tag(command: object) -> str:
    """``impact_id '<id>'; `` for a command (a parsed impact_cmd) that carries a string
    impact_id, else "": sim_node puts it in the brackets that end a refusal's log line
    (``[impact_id 'run3-017'; 2 refused so far]``), and ``tail-beam send --wait-truth`` looks for
    it on /rosout. Long ids are cut as every echoed value is
    (:func:`~tail_beam_sim.errors.shorten`)."""
    impact_id = command.get("impact_id") if isinstance(command, dict) else None
    return f"impact_id {shorten(impact_id)}; " if isinstance(impact_id, str) else ""


@dataclass
class CommandCounts:
    """What became of the impact_cmd messages this node received."""

    received: int = 0
    queued: int = 0
    refused: int = 0

    def __str__(self) -> str:
        return f"{self.received} received, {self.queued} queued, {self.refused} refused"


class SimNode(Node):
    """The simulated support: impacts in, sensor streams out."""

    def __init__(self, **kwargs) -> None:
        super().__init__("tail_beam_sim", **kwargs)
        params = declare_and_read(
            self, config_defaults(["sim_node.yaml", "flow.yaml"], with_physics=True)
        )
        node = params["sim_node"]
        checked = SIM_NODE.check(node)
        self.realtime_factor = checked["realtime_factor"]
        period = checked["publish_period_s"]
        self.max_chunk_s = checked["max_chunk_s"]
        self.max_lag_s = checked["max_lag_s"]
        idle = checked["exit_after_idle_s"]
        depth = checked["qos_depth"]
        wait_for = checked["wait_for_subscribers"]
        settle = checked["subscriber_settle_s"]
        scenario_source = params["scenario"].get("source", "none")
        self.flow = self._start_flow(params) if scenario_source == "flow" else None
        self.stream = self.flow.sim if self.flow else StreamSimulator.from_params(params)
        # The scenario is validated whole now, and fed to the stream as its impacts fall due.
        self._planned: deque[PlannedImpact] = deque(
            load_scenario(params["scenario"], self.stream.materials, self.stream.support)
        )
        auto_idle = SCENARIO_IDLE_S if scenario_source not in ("none", "flow") else 0.0
        windows = self.flow.source.windows if self.flow is not None else []
        if windows and math.isfinite(windows[-1][1]):
            auto_idle = SCENARIO_IDLE_S  # a start-up window that closes: exit once it is done
        self.exit_after_idle_s = auto_idle if idle == -1.0 else idle
        # A planned impact goes to the stream while its stamp is still ahead of what the next tick
        # can reach plus the command lead, so it strikes when planned however the node is paced.
        self._feed_horizon_s = self.stream.params.command_lead_s + 2.0 * self.max_chunk_s
        self.commands = CommandCounts()
        self.finished = Future()
        sensor_qos = ros_messages.stream_qos(depth)
        event_qos = ros_messages.EVENT_PUBLISHER_QOS
        self._pressure_pub = self.create_publisher(FluidPressure, topics.JACK_PRESSURE, sensor_qos)
        self._imu_pub = self.create_publisher(Imu, topics.IMU, sensor_qos)
        self._vibration_pub = self.create_publisher(LaserScan, topics.VIBRATION, sensor_qos)
        self._rebound_pub = self.create_publisher(TwistStamped, topics.REBOUND_VELOCITY, event_qos)
        self._gate = SubscriberGate(
            (self._pressure_pub, self._imu_pub, self._vibration_pub, self._rebound_pub),
            wait_for,
            settle,
        )
        self._truth_pub = self.create_publisher(String, topics.IMPACT_TRUTH, event_qos)
        self._share_pub = self.create_publisher(String, topics.GANGUE_SHARE_TRUTH, event_qos)
        self.window_refusals = 0
        self.create_subscription(
            String, topics.WINDOW_CMD, self._on_window_command, ros_messages.COMMAND_QOS
        )
        self._clock_pub = (
            self.create_publisher(Clock, "/clock", 10) if checked["publish_clock"] else None
        )
        # Keep-all: a burst of commands waits in the reader's history instead of overwriting
        # itself.
        self.create_subscription(
            String, topics.IMPACT_CMD, self._on_command, ros_messages.COMMAND_QOS
        )
        self._foreign = ForeignTypeWatch(
            self, {name: topics.MSG_TYPES[name] for name in (topics.IMPACT_CMD, topics.WINDOW_CMD)}
        )
        self._anchor: tuple[float, float] | None = None  # (wall s, simulation s) pacing origin
        self._last_activity_s = 0.0
        self._started = False  # simulation time held at 0 until the subscribers are there
        self._backlog = PublishBacklog(self)  # messages a full writer has not taken yet, in order
        self.create_timer(0.0 if self.realtime_factor == 0.0 else period, self._tick)
        self.add_on_set_parameters_callback(
            self._on_set_parameters
        )  # after declaring: start-up values pass
        self.get_logger().info(
            f"simulating at realtime_factor {self.realtime_factor:g}: pressure "
            f"{self.stream.sensors.pressure_rate_hz:g} Hz, "
            f"IMU {self.stream.sensors.imu_rate_hz:g} Hz, vibration "
            f"{self.stream.sensors.vibration_rate_hz:g} Hz in blocks of "
            f"{self.stream.sensors.vibration_block_samples}, scenario of {len(self._planned)} "
            "impact(s)"
            + (
                f", exiting after {self.exit_after_idle_s:g} s idle"
                if self.exit_after_idle_s > 0.0
                else ""
            )
        )

    def _on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        """Refuse every change at run time: the node reads its parameters once, at start-up, and a
        changed value would be reported by ``ros2 param get`` without being in effect.
        ``use_sim_time`` in particular: the simulator is the source of simulation time, never its
        consumer."""
        names = ", ".join(p.name for p in changes)
        reason = (
            f"{names}: sim_node reads its parameters at start-up only; restart it with --ros-args "
            "-p NAME:=VALUE"
            + (
                "; use_sim_time: the simulator makes simulation time (sim_node.publish_clock), it "
                "never follows /clock"
                if any(p.name == "use_sim_time" for p in changes)
                else ""
            )
        )
        self.get_logger().warning(f"parameter change refused: {reason}")
        return SetParametersResult(successful=False, reason=reason)

    def _on_command(self, msg: String) -> None:
        """One impact_cmd: queue it, or log why not (the node keeps running either way). A
        refusal's line names the command's impact_id when it has one (:func:`refusal_tag`), so
        that a client reading /rosout knows which of its commands was refused."""
        self.commands.received += 1
        command = None
        try:
            command = parse_command(msg.data)
            scheduled = self.stream.submit(command)
        except QueueFull as exc:
            self.commands.refused += 1
            self.get_logger().warning(
                f"impact_cmd refused: {exc} [{refusal_tag(command)}{self.commands.refused} "
                "refused so far]"
            )
            return
        except InputError as exc:
            self.commands.refused += 1
            self.get_logger().error(
                f"impact_cmd rejected: {exc} [{refusal_tag(command)}{self.commands.refused} "
                "refused so far]"
            )
            return
        except SolverError as exc:
            self.commands.refused += 1
            self.get_logger().error(
                f"impact_cmd not simulated: solver failed: {exc} "
                f"[{refusal_tag(command)}{self.commands.refused} refused so far]"
            )
            return
        self.commands.queued += 1
        self.get_logger().info(
            f"impact {scheduled.impact_id!r} queued: contact at {scheduled.contact_stamp_s:.4f} s "
            f"({self.stream.queued} queued)"
        )

    def _start_flow(self, params: dict) -> FlowRun:
        """The flow of ``scenario.source: flow``, its start-up window opened (and closed) as
        ``flow.open_at_s`` / ``flow.duration_s`` say."""
        flow = FlowRun(params, simulator=FlowSimulator.from_params(params))
        if flow.flow.open_at_s >= 0.0:
            flow.command("open", flow.flow.open_at_s)
            if flow.flow.duration_s > 0.0:
                flow.command("close", flow.flow.open_at_s + flow.flow.duration_s)
        return flow

    def _on_window_command(self, msg: String) -> None:
        """One window_cmd: open or close the drawing window at the simulation time reached, or
        log why not (the node keeps running)."""
        try:
            action = parse_window_command(msg.data)
            if self.flow is None:
                raise InputError(
                    "window_cmd",
                    msg.data,
                    "refused: no drawing window here (sim_node runs scenario.source flow for one)",
                )
            stamp = self.flow.command(action)
        except InputError as exc:
            self.window_refusals += 1
            self.get_logger().warning(
                f"window_cmd refused: {exc} [{self.window_refusals} refused so far]"
            )
            return
        self.get_logger().info(
            f"window {'opened' if action == 'open' else 'closed'} at {stamp:.4f} s of simulation "
            f"time ({self.flow.lumps_submitted} lumps so far, "
            f"{self.flow.source.drawn_mass_kg:.0f} kg drawn)"
        )

    def _feed_scenario(self, until_s: float) -> None:
        """Hand the stream the planned impacts due before ``until_s`` plus the feed horizon, s
        (one without a stamp is due at once), as long as the queue has room."""
        limit = self.stream.params.max_queued_impacts
        while self._planned and self.stream.queued < limit:
            planned = self._planned[0]
            if (
                planned.contact_stamp_s is not None
                and planned.contact_stamp_s > until_s + self._feed_horizon_s
            ):
                return
            self._planned.popleft()
            try:
                self.stream.submit(planned.command, planned.contact_stamp_s)
            except InputError as exc:  # an impact_id a command took first
                self.get_logger().error(f"scenario impact skipped: {exc}")
            except SolverError as exc:
                self.get_logger().error(f"scenario impact not simulated: solver failed: {exc}")

    def _target_time_s(self, now_s: float) -> float:
        """Simulation time to reach this tick, s."""
        current = self.stream.time_s
        if self.realtime_factor == 0.0:
            return current + self.max_chunk_s
        if self._anchor is None:
            self._anchor = (now_s, current)
        wall0, sim0 = self._anchor
        target = sim0 + (now_s - wall0) * self.realtime_factor
        if (
            target > current + self.max_lag_s
        ):  # too far behind to catch up: slower than real time from here
            self._anchor = (now_s, current)
        return min(
            target, current + self.max_chunk_s
        )  # a short stall is caught up, a chunk at a time

    def _tick(self) -> None:
        if not self._started:
            if not self._gate.open():
                return
            self._started = True
        if not self.context.ok() or not self._backlog.flush():
            # shutting down, or a subscriber is behind: simulate no further until it has caught up
            return
        target = self._target_time_s(time.monotonic())
        self._feed_scenario(target)
        if self.flow is not None:
            part = self.flow.advance(target, lead_s=self._feed_horizon_s)
            self.publish(part.chunk, part.shares)
        else:
            self.publish(self.stream.advance(target))
        flow_done = self.flow is None or (not self.flow.is_open and self.flow.source.exhausted)
        if (
            self.exit_after_idle_s > 0.0
            and self.stream.queued == 0
            and not self._planned
            and flow_done
            and not self.finished.done()
        ):
            if self.stream.time_s >= self._last_activity_s + self.exit_after_idle_s:
                self.get_logger().info(
                    f"idle for {self.exit_after_idle_s:g} s of simulation time: done"
                )
                self.finished.set_result(True)

    def close(self) -> None:
        """Before exiting: say what became of the commands; let the subscribers have every message
        published."""
        self.get_logger().info(
            f"impact_cmd: {self.commands}; {len(self._planned)} scenario impact(s) not started"
        )
        if self.flow is not None:
            self.get_logger().info(
                f"flow: {self.flow.lumps_submitted} lumps simulated, "
                f"{len(self.flow.skipped)} skipped, {self.flow.source.drawn_mass_kg:.0f} kg drawn"
            )
        deadline = time.monotonic() + ACK_TIMEOUT_S
        while self.context.ok() and not self._backlog.flush() and time.monotonic() < deadline:
            time.sleep(0.01)
        drain(
            self,
            (
                self._pressure_pub,
                self._imu_pub,
                self._vibration_pub,
                self._rebound_pub,
                self._truth_pub,
                self._share_pub,
            ),
        )

    def publish(self, chunk: Chunk, shares: list[ShareInterval] | tuple = ()) -> None:
        """Publish one chunk: streams in stamp order, then its rebounds and truths (and a flow's
        share intervals). A flow's lumps are not logged one by one (hundreds a second): its
        share intervals are."""
        for scheduled in chunk.started:
            self._last_activity_s = max(self._last_activity_s, scheduled.truth_stamp_s)
            if self.flow is not None:
                continue
            self.get_logger().info(
                f"impact {scheduled.impact_id}: {scheduled.impact.material.name} R "
                f"{scheduled.impact.radius_m * 1e3:.0f} mm "
                f"at {scheduled.contact_stamp_s:.4f} s"
            )
        # The streams in one stamp order (a vibration block at its first sample's stamp), so that
        # a consumer never sees one run ahead of the others.
        outgoing = [
            (self._pressure_pub, m) for m in ros_messages.pressure_messages(chunk.pressure)
        ]
        outgoing += [(self._imu_pub, m) for m in ros_messages.imu_messages(chunk.imu)]
        outgoing += [
            (self._vibration_pub, m) for m in ros_messages.vibration_messages(chunk.vibration)
        ]
        stamps = np.concatenate(
            [chunk.pressure.stamp_s, chunk.imu.stamp_s, chunk.vibration.stamp_s]
        )
        backlog = self._backlog
        for index in np.argsort(stamps, kind="stable"):
            backlog.publish(*outgoing[index])
        for _, rebound in chunk.rebounds:
            backlog.publish(self._rebound_pub, ros_messages.rebound_message(rebound))
        for _, truth in chunk.truths:
            backlog.publish(self._truth_pub, ros_messages.string_message(truth))
        for share in shares:
            backlog.publish(self._share_pub, ros_messages.string_message(share.to_json()))
            by_mass = "-" if share.share_by_mass is None else f"{share.share_by_mass:.3f}"
            self.get_logger().info(
                f"gangue share [{share.start_stamp_s:g}, {share.end_stamp_s:g}) s: {by_mass} by "
                f"mass, {share.lumps} lumps, {share.mass_kg:.1f} kg"
            )
        if self._clock_pub is not None and math.isfinite(chunk.end_s):
            backlog.publish(self._clock_pub, ros_messages.clock_message(chunk.end_s))
        backlog.flush()


def main(args: list[str] | None = None) -> int:
    """Run sim_node until shut down (or idle, with sim_node.exit_after_idle_s)."""
    return run_node(SimNode, USAGE, args)


if __name__ == "__main__":
    sys.exit(main())
