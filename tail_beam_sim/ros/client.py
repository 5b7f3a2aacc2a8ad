"""The ROS side of ``tail-beam send``: hand impact commands to a running simulator, reliably.

A command published right after discovery can be lost without a trace: DDS discovery is
asymmetric, so the client's writer may count the simulator's reader before that reader has
matched the writer, and the reader drops what comes in between; the writer would repair it
later, but a client that publishes and exits is gone by then.
:func:`send_commands` therefore

1. waits, up to ``timeout_s``, until a *simulator* is on the graph: a node that subscribes to
   ``impact_cmd`` and publishes ``impact_truth`` in the namespace (a recorder or a probe that
   only listens does not count), and until the client's writer has matched it;
2. waits ``settle_s`` more (``sim_node.subscriber_settle_s``, the wait the nodes use:
   :class:`~tail_beam_sim.ros.spin.SubscriberGate`);
3. publishes on a reliable keep-all writer and waits until the simulator has acknowledged every
   command (:func:`~tail_beam_sim.ros.spin.drain`);
4. on request, waits for each command's ``impact_truth`` (matched by ``impact_id``) and for
   sim_node's refusals, which it logs, naming the impact_id
   (:func:`~tail_beam_sim.ros.sim_node.refusal_tag`),
   and which reach a client on ``/rosout``.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import rclpy
from rcl_interfaces.msg import Log
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.validate_namespace import validate_namespace
from std_msgs.msg import String

from tail_beam_sim import topics
from tail_beam_sim.errors import InputError
from tail_beam_sim.ros import messages as ros_messages
from tail_beam_sim.ros.sim_node import REFUSAL_PREFIX, refusal_tag
from tail_beam_sim.ros.spin import ACK_TIMEOUT_S, PublishBacklog, SubscriberGate, drain

SPIN_SLICE_S = 0.05  # longest wait between two looks at the graph and the clock, s
# The name the graph gives a subscription's node before discovery has brought the node itself.
UNKNOWN_NODE_NAME = "_NODE_NAME_UNKNOWN_"
UNNAMED_LISTENER = "a node not yet named on the graph"
NAMING_S = 2.0  # after the timeout, how long discovery may take to name a listener, s
KEEP_ALL = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
ROSOUT_QOS = QoSProfile(
    depth=1000, reliability=ReliabilityPolicy.RELIABLE
)  # volatile: no other run's old lines


class NoSimulator(Exception):
    """No simulator appeared within the timeout (the message is one line saying what was seen)."""


class NotAcknowledged(Exception):
    """The simulator did not acknowledge the commands within ``ACK_TIMEOUT_S``."""


@dataclass
class SendOutcome:
    """What became of the commands: the simulator(s) that took them, each truth and refusal
    by impact_id, and the ids with neither when the wait for truths ended."""

    simulators: list[str]
    truths: dict[str, dict[str, Any]] = field(default_factory=dict)
    refused: dict[str, str] = field(default_factory=dict)
    missing: list[str] = field(default_factory=list)


def check_namespace(namespace: str) -> str:
    """``namespace`` as a ROS namespace (``""`` or ``/`` is the root; a leading ``/`` is added),
    or InputError naming ``--namespace``."""
    name = "/" + namespace.strip().strip("/") if namespace.strip().strip("/") else "/"
    try:
        validate_namespace(name)
    except Exception as exc:  # rclpy's InvalidNamespaceException
        reason = str(exc).splitlines()[0] if str(exc) else "not a valid ROS namespace"
        raise InputError(
            "--namespace", namespace, f"must be a ROS namespace such as /support_07 ({reason})"
        ) from None
    return name


def logger_name(node_fqn: str) -> str:
    """The logger name a node logs under on /rosout: ``/support_07/tail_beam_sim`` ->
    ``support_07.tail_beam_sim``."""
    return node_fqn.strip("/").replace("/", ".")


class SendClient(Node):
    """A short-lived node: a reliable keep-all ``impact_cmd`` writer and, when truths are wanted,
    readers of ``impact_truth`` and ``/rosout``."""

    def __init__(self, context: rclpy.Context, namespace: str, want_truths: bool) -> None:
        super().__init__(f"tail_beam_send_{os.getpid()}", namespace=namespace, context=context)
        self.command_pub = self.create_publisher(
            String, topics.IMPACT_CMD, ros_messages.COMMAND_QOS
        )
        self.command_topic = self.resolve_topic_name(topics.IMPACT_CMD)
        self.truth_topic = self.resolve_topic_name(topics.IMPACT_TRUTH)
        self.want_truths = want_truths
        self.truths: list[dict[str, Any]] = []
        self.log_lines: list[Log] = []
        self.truth_sub = None
        if want_truths:
            self.truth_sub = self.create_subscription(
                String, topics.IMPACT_TRUTH, self._on_truth, KEEP_ALL
            )
            self.create_subscription(Log, "/rosout", self.log_lines.append, ROSOUT_QOS)

    def _on_truth(self, msg: String) -> None:
        try:
            truth = json.loads(msg.data)
        except (ValueError, RecursionError):
            return  # not the suite's JSON: another participant's message, not a truth of ours
        if isinstance(truth, dict):
            self.truths.append(truth)

    def simulators(self) -> list[str]:
        """Fully qualified names of the nodes that subscribe to impact_cmd and publish
        impact_truth here: the simulators (sim_node, under any node name)."""

        def nodes(infos: Sequence[Any]) -> set[str]:
            return {f"{i.node_namespace.rstrip('/')}/{i.node_name}" for i in infos}

        return sorted(
            nodes(self.get_subscriptions_info_by_topic(self.command_topic))
            & nodes(self.get_publishers_info_by_topic(self.truth_topic))
        )

    def listeners(self) -> list[str]:
        """Every node subscribing to impact_cmd (for the message when none is a simulator); one
        whose name discovery has not brought yet is "a node not yet named on the graph"."""
        return sorted(
            {
                UNNAMED_LISTENER
                if i.node_name == UNKNOWN_NODE_NAME
                else f"{i.node_namespace.rstrip('/')}/{i.node_name}"
                for i in self.get_subscriptions_info_by_topic(self.command_topic)
            }
        )

    def listeners_named(self) -> bool:
        """Whether discovery has named every node subscribing to impact_cmd."""
        return UNNAMED_LISTENER not in self.listeners()

    def ready(self) -> bool:
        """A simulator is on the graph and, when truths are wanted, its truth writer has matched
        our reader."""
        if not self.simulators():
            return False
        return self.truth_sub is None or self.truth_sub.get_publisher_count() >= 1


def _spin_until(
    executor: EventsExecutor,
    context: rclpy.Context,
    condition: Callable[[], bool],
    deadline: float,
) -> bool:
    """Spin until ``condition()`` or the monotonic ``deadline``; Ctrl-C (the context shut down)
    raises KeyboardInterrupt."""
    while not condition():
        if not context.ok():
            raise KeyboardInterrupt
        if time.monotonic() >= deadline:
            return False
        try:
            executor.spin_once(timeout_sec=SPIN_SLICE_S)
        except ExternalShutdownException:
            raise KeyboardInterrupt from None
    return True


def send_commands(
    commands: Sequence[Mapping[str, Any]],
    *,
    namespace: str = "/",
    timeout_s: float,
    settle_s: float,
    truth_timeout_s: float | None = None,
    on_truth: Callable[[dict[str, Any]], None] | None = None,
    on_refusal: Callable[[str, str], None] | None = None,
) -> SendOutcome:
    """Send ``commands`` (validated impact_cmd objects) to the simulator in ``namespace``.

    Waits at most ``timeout_s`` (wall clock, s) for a simulator (:class:`NoSimulator`
    otherwise), ``settle_s`` more, publishes, and waits until every command is acknowledged
    (:class:`NotAcknowledged` otherwise). With ``truth_timeout_s`` (s), then waits for each
    command's impact_truth or refusal, calling ``on_truth(truth)`` / ``on_refusal(impact_id,
    log line)`` as they come, until none is outstanding or none came for ``truth_timeout_s``;
    every command must then carry an impact_id.
    """
    want_truths = truth_timeout_s is not None
    ids = [str(c["impact_id"]) for c in commands] if want_truths else []
    context = rclpy.Context()
    rclpy.init(context=context, args=[])
    executor = EventsExecutor(context=context)
    client = SendClient(context, namespace, want_truths)
    executor.add_node(client)
    try:
        gate = SubscriberGate((client.command_pub,), 1, settle_s, ready=client.ready)
        start = time.monotonic()
        if not _spin_until(executor, context, gate.open, start + timeout_s) and not gate.seen:
            # A subscription's endpoint can come before its node's name: wait a little for it.
            _spin_until(executor, context, client.listeners_named, time.monotonic() + NAMING_S)
            listeners = client.listeners()
            verbs = (
                "subscribes to it but publishes"
                if len(listeners) == 1
                else "subscribe to it but publish"
            )
            seen = f"; {', '.join(listeners)} {verbs} no impact_truth" if listeners else ""
            raise NoSimulator(
                f"no simulator subscribed to {client.command_topic} within {timeout_s:g} s{seen}: "
                "start sim_node in namespace "
                f"{namespace} and ROS_DOMAIN_ID {os.environ.get('ROS_DOMAIN_ID', '0')}, or raise "
                "--timeout-s"
            )
        _spin_until(
            executor, context, gate.open, time.monotonic() + settle_s + 1.0
        )  # the settle time, once seen
        outcome = SendOutcome(client.simulators())
        backlog = PublishBacklog(client)
        for command in commands:
            backlog.publish(client.command_pub, String(data=json.dumps(dict(command))))
        _spin_until(executor, context, backlog.flush, time.monotonic() + ACK_TIMEOUT_S)
        if backlog.pending or not drain(client, (client.command_pub,)):
            if not context.ok():
                raise KeyboardInterrupt
            raise NotAcknowledged(
                f"{len(commands)} command(s) published on {client.command_topic} but not all "
                "acknowledged within "
                f"{ACK_TIMEOUT_S:g} s by {', '.join(outcome.simulators)} (it left, or is "
                "overloaded)"
            )
        if not want_truths:
            return outcome
        pending = dict.fromkeys(ids)
        tags = {i: f"[{refusal_tag({'impact_id': i})}" for i in ids}
        loggers = {logger_name(name) for name in outcome.simulators}

        def progress() -> bool:
            """Take the truths and refusals that came; True when a command was settled."""
            settled = False
            while client.truths:
                truth = client.truths.pop(0)
                impact_id = truth.get("impact_id")
                if impact_id in pending:
                    del pending[impact_id]
                    outcome.truths[impact_id] = truth
                    settled = True
                    if on_truth:
                        on_truth(truth)
            while client.log_lines:
                line = client.log_lines.pop(0)
                if line.name not in loggers or not line.msg.startswith(REFUSAL_PREFIX):
                    continue
                for impact_id in [i for i in pending if tags[i] in line.msg]:
                    del pending[impact_id]
                    outcome.refused[impact_id] = line.msg
                    settled = True
                    if on_refusal:
                        on_refusal(impact_id, line.msg)
            return settled

        while pending:
            if not _spin_until(executor, context, progress, time.monotonic() + truth_timeout_s):
                break
        outcome.missing = list(pending)
        return outcome
    finally:
        executor.shutdown()
        client.destroy_node()
        rclpy.try_shutdown(context=context)


__all__ = ["NoSimulator", "NotAcknowledged", "SendOutcome", "check_namespace", "send_commands"]
