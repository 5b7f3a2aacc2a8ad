"""Test helpers for real rclpy nodes: a private context, a probe node that records topics and
sends commands, and spinning until a condition holds (with a deadline, never a timed assert)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import rclpy
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from std_msgs.msg import String

from tail_beam_id.stream.label import Label
from tail_beam_sim.ros import messages as ros_messages
from tail_beam_sim.ros.follow_qos import FollowingSubscription, follow_publishers
from tail_beam_sim.ros.spin import spin_once

RELIABLE = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)


@contextmanager
def ros_context() -> Iterator[tuple[rclpy.Context, EventsExecutor]]:
    """A fresh rclpy context and an EventsExecutor on it; everything is torn down after: every
    node ever added to the executor is destroyed, those a test removed from it too. A node left
    alive keeps its transient-local writers (impact_truth, rebound_velocity, label) in the
    domain, and the next test's late-joining readers would receive its old events."""
    context = rclpy.Context()
    rclpy.init(context=context)
    executor = _TrackingExecutor(context=context)
    try:
        yield context, executor
    finally:
        executor.shutdown()
        for node in executor.ever_added:
            try:
                node.destroy_node()
            except Exception:  # destroyed already by the test
                pass
        rclpy.try_shutdown(context=context)


class _TrackingExecutor:
    """An EventsExecutor that remembers every node it was given (a wrapper: the executor is an
    extension type)."""

    def __init__(self, context: rclpy.Context) -> None:
        self._executor = EventsExecutor(context=context)
        self.ever_added: list[Node] = []

    def add_node(self, node: Node) -> bool:
        if node not in self.ever_added:
            self.ever_added.append(node)
        return self._executor.add_node(node)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._executor, name)


class Probe(Node):
    """Records every message of the given topics and publishes impact commands."""

    def __init__(
        self,
        context: rclpy.Context,
        topics: dict[str, type],
        namespace: str = "",
        name: str = "probe",
    ) -> None:
        super().__init__(name, namespace=namespace, context=context)
        self.messages: dict[str, list[Any]] = {topic: [] for topic in topics}
        following = []
        for topic, msg_type in topics.items():
            record = lambda msg, t=topic: self.messages[t].append(msg)  # noqa: E731
            if topic in ros_messages.SENSOR_TOPICS:  # with the reliability their writers offer
                following.append(FollowingSubscription(self, msg_type, topic, record, 10000))
            else:
                self.create_subscription(msg_type, topic, record, RELIABLE)
        follow_publishers(self, following)
        self.command_pub = self.create_publisher(String, "impact_cmd", RELIABLE)

    def send(self, command: dict[str, Any] | str) -> None:
        text = command if isinstance(command, str) else json.dumps(command)
        self.command_pub.publish(String(data=text))

    def json(self, topic: str) -> list[dict[str, Any]]:
        return [json.loads(m.data) for m in self.messages[topic]]

    def labels(self, topic: str) -> list[Label]:
        """The messages on a label topic, each read as a Label (one that does not read fails the
        test)."""
        return [Label.from_json(m.data) for m in self.messages[topic]]


def spin_until(
    executor: EventsExecutor, condition: Callable[[], bool], timeout_s: float = 30.0
) -> bool:
    """Spin until ``condition()`` holds or the deadline passes; returns the condition."""
    deadline = time.monotonic() + timeout_s
    while not condition() and time.monotonic() < deadline:
        spin_once(executor, 0.05)
    return condition()


def call_until_answered(
    executor: EventsExecutor,
    send: Callable[[], Future],
    what: str,
    timeout_s: float = 30.0,
    resend_s: float = 5.0,
) -> Any:
    """Send a service request with ``send()`` and spin until an answer comes, sending it again
    every ``resend_s``; the first answer's result.

    A server can be ready for a client's requests before it has matched the client's response
    reader; its answer is then dropped with a "failed to send response (timeout)" warning and the
    call hangs (the service discovery race of ros2/ros2#1253). Only for idempotent requests."""
    deadline = time.monotonic() + timeout_s
    futures: list[Future] = []
    while time.monotonic() < deadline:
        futures.append(send())
        window_s = min(resend_s, deadline - time.monotonic())
        if spin_until(executor, lambda: any(f.done() for f in futures), timeout_s=window_s):
            return next(f for f in futures if f.done()).result()
    raise AssertionError(f"{what} never answered {len(futures)} requests in {timeout_s:.0f} s")


def spin_for(executor: EventsExecutor, duration_s: float) -> None:
    """Spin for ``duration_s`` of wall time."""
    deadline = time.monotonic() + duration_s
    while time.monotonic() < deadline:
        spin_once(executor, 0.02)


@contextmanager
def feeding_vibration(bag, intruder: bool = False) -> Iterator[tuple]:
    """id_node and bag_recorder under /feed, a client publishing vibration to both (its /rosout
    subscribed) and, with ``intruder``, a second node publishing vibration too: (executor,
    id_node, recorder, client, publisher, intruder's publisher or None), once all match."""
    from rcl_interfaces.msg import Log
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import LaserScan

    from tail_beam_id.ros.id_node import IdNode
    from tail_beam_sim import topics
    from tail_beam_sim.ros.recorder_node import RecorderNode

    with ros_context() as (context, executor):
        ident = IdNode(
            context=context,
            namespace="/feed",
            parameter_overrides=[Parameter("id_node.poll_period_s", value=0.02)],
        )
        recorder = RecorderNode(
            context=context,
            namespace="/feed",
            parameter_overrides=[Parameter("recorder.bag_path", value=str(bag))],
        )
        feeder = Probe(context, {"/rosout": Log}, namespace="/feed", name="feeder")
        pubs = [feeder.create_publisher(LaserScan, topics.VIBRATION, RELIABLE)]
        nodes = [ident, recorder, feeder]
        if intruder:
            other = Probe(context, {}, namespace="/feed", name="intruder")
            pubs.append(other.create_publisher(LaserScan, topics.VIBRATION, RELIABLE))
            nodes.append(other)
        for node in nodes:
            executor.add_node(node)
        assert spin_until(executor, lambda: all(p.get_subscription_count() >= 2 for p in pubs))
        yield executor, ident, recorder, feeder, pubs[0], (pubs[1] if intruder else None)


BIN = Path(sys.executable).parent  # the suite's executables


class Processes:
    """Starts executables with logs in a directory; stops whatever is left at the end."""

    def __init__(self, log_dir: Path) -> None:
        self.log_dir = log_dir
        self.running: list[subprocess.Popen] = []
        self.logs: dict[int, Path] = {}

    def start(self, exe: str, *params: str, ns: str = "") -> subprocess.Popen:
        """The suite's executable ``exe`` with ``-p`` ``params`` (and a namespace)."""
        args = [str(BIN / exe), "--ros-args"] + [a for p in params for a in ("-p", p)]
        if ns:
            args += ["-r", f"__ns:={ns}"]
        return self.command(f"{exe}{ns.replace('/', '_')}", args)

    def command(self, name: str, args: list[str]) -> subprocess.Popen:
        """Any command, its output logged under ``name``."""
        path = self.log_dir / f"{name}_{len(self.running)}.log"
        with path.open("w") as log:
            proc = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT)
        self.running.append(proc)
        self.logs[proc.pid] = path
        return proc

    def log(self, proc: subprocess.Popen) -> str:
        return self.logs[proc.pid].read_text()

    def stop(
        self, proc: subprocess.Popen, sig: int = signal.SIGINT, timeout_s: float = 30.0
    ) -> int:
        proc.send_signal(sig)
        return proc.wait(timeout=timeout_s)

    def close(self) -> None:
        for proc in self.running:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
