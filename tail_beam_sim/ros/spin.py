"""Running a node as an executable: init, spin until told to stop, shut down.

``EventsExecutor.spin()`` (rclpy 9) does not return when SIGINT or SIGTERM shuts the context
down, so the nodes spin in short slices and check between them. An executable takes SIGINT and
SIGTERM itself (:class:`StopRequest`) instead of rclpy's handlers: those shut the context down
and raise KeyboardInterrupt wherever the signal lands, inside a callback too, which the
executor then logged as a FATAL exception with its traceback on an ordinary Ctrl-C.
"""

from __future__ import annotations

import os
import re
import signal
import sys
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any, Protocol, runtime_checkable

import rclpy
from rclpy.duration import Duration
from rclpy.exceptions import InvalidHandle
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future

from tail_beam_sim.errors import InputError
from tail_beam_sim.ros.start import STOP_SIGNALS
from tail_beam_sim.ros.usage import NodeUsage, asks_for_help


@runtime_checkable
class FinishingNode(Protocol):
    """A node that knows when its work is done (a scenario played, a bag replayed):
    :func:`run_node` stops spinning when ``finished`` is done."""

    finished: Future


@runtime_checkable
class ClosingNode(Protocol):
    """A node with resources to close on the way out (a bag writer)."""

    def close(self) -> None: ...


@runtime_checkable
class HostingNode(Protocol):
    """A node that builds other nodes of its process (face_host: several supports' nodes):
    they spin on its executor and are closed and destroyed with it, before it."""

    members: list[Node]


def with_members(node: Node) -> list[Node]:
    """``node``'s hosted nodes (a :class:`HostingNode`'s), then ``node`` itself."""
    return [*(node.members if isinstance(node, HostingNode) else []), node]


def overrides(values: Mapping[str, Any]) -> list[Parameter]:
    """``parameter_overrides`` for a node built in-process, from a flat {dotted name: value}."""
    return [Parameter(name, value=value) for name, value in values.items()]


SLICE_S = 0.1  # longest wait between two checks of the context, s
ACK_TIMEOUT_S = (
    10.0  # how long a closing publisher waits for its subscribers to have everything, s
)


def spin_once(executor: Executor, timeout_s: float) -> None:
    """One ``spin_once`` of ``executor``, through an event of an entity destroyed meanwhile.

    A subscription replaced while the middleware had an event queued for it (the recorder
    re-subscribing an event topic when a publisher with other durability appears: an
    incompatible-QoS event of the old one) makes ``EventsExecutor`` raise ``InvalidHandle``
    taking that event. The entity is gone and its event with it; rclpy's own executors skip
    such an event the same way (``rclpy.executors``: "the entity has already been destroyed")."""
    try:
        executor.spin_once(timeout_sec=timeout_s)
    except InvalidHandle:
        pass


class StopRequest:
    """SIGINT and SIGTERM as a request to stop, honoured between two callbacks.

    The first signal only sets ``requested``: the callback it lands in finishes, the spin loop
    sees the flag and returns, and :func:`run_node` shuts the context down and closes the node
    (which, told to stop, does not wait for its subscribers). A second signal raises
    KeyboardInterrupt, for a stop that hangs."""

    def __init__(self) -> None:
        self.requested = False

    def install(self) -> None:
        for sig in STOP_SIGNALS:
            signal.signal(sig, self._handle)

    def _handle(self, signum: int, frame: object) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True


def spin(node: Node, done: Future | None = None, stop: StopRequest | None = None) -> None:
    """Spin ``node`` on an EventsExecutor until ``stop`` is requested, the context is shut down
    (rclpy's own signal handlers, where the caller kept them) or ``done``.

    A context shut down from a signal handler while a callback is publishing makes that
    callback fail ("publisher's context is invalid"). Such a failure is the shutdown itself,
    not an error, and ends the spin quietly.
    """
    executor: Executor = EventsExecutor(context=node.context)
    for member in with_members(node):
        executor.add_node(member)
    try:
        while (
            rclpy.ok(context=node.context)
            and not (stop is not None and stop.requested)
            and not (done is not None and done.done())
        ):
            spin_once(executor, SLICE_S)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if rclpy.ok(context=node.context):
            raise
    finally:
        executor.shutdown()


class PublishBacklog:
    """Publishes messages in order; when a reliable keep-all writer is full (a slow subscriber on
    a busy machine: Fast DDS then fails the publish after its blocking time), keeps the rest for
    the next ``flush``, so that the caller's timer returns, the executor spins, and nothing is
    lost or reordered. Callers stop producing while ``pending`` is not zero."""

    def __init__(self, node: Node) -> None:
        self._node = node
        self._queue: deque[tuple[Publisher, Any]] = deque()
        self._held = False  # whether the last flush was refused (warned once per episode)

    @property
    def pending(self) -> int:
        return len(self._queue)

    def publish(self, publisher: Publisher, msg: Any) -> None:
        """Queue ``msg`` behind everything pending (call ``flush`` to send)."""
        self._queue.append((publisher, msg))

    def flush(self) -> bool:
        """Send what the writers accept, in order; True when nothing is left."""
        while self._queue:
            publisher, msg = self._queue[0]
            try:
                publisher.publish(msg)
            except (
                RuntimeError
            ):  # rclpy raises its RCLError, a RuntimeError, when the writer refuses
                if not self._node.context.ok():
                    return False  # shutting down: the writer is gone, nobody is behind
                if not self._held:
                    self._node.get_logger().warning(
                        f"a subscriber of {publisher.topic_name} is behind: holding "
                        f"{len(self._queue)} messages until it catches up"
                    )
                self._held = True
                return False
            self._queue.popleft()
        self._held = False
        return True


FOREIGN_TYPE_PERIOD_S = (
    1.0  # how often a node looks for publishers of another type on its topics, s
)


class ForeignTypeWatch:
    """Warns once per publisher that offers another message type on one of ``node``'s topics
    (``{relative name: 'pkg/msg/Type'}``). DDS never matches the two, so none of its messages
    arrives, and the Fast DDS of the pip wheels raises no incompatible-type event: without this,
    a client publishing the wrong type would see its messages vanish without a word."""

    def __init__(self, node: Node, expected: Mapping[str, str]) -> None:
        self._node = node
        self._expected = {
            node.resolve_topic_name(topic): msgtype for topic, msgtype in expected.items()
        }
        self._said: set[tuple[str, str, str, str]] = set()
        node.create_timer(FOREIGN_TYPE_PERIOD_S, self.check)

    def check(self) -> None:
        for topic, msgtype in self._expected.items():
            for info in self._node.get_publishers_info_by_topic(topic):
                if info.topic_type == msgtype:
                    continue
                publisher = f"{info.node_namespace.rstrip('/')}/{info.node_name}"
                key = (topic, info.topic_type, publisher, bytes(info.endpoint_gid).hex())
                if key in self._said:
                    continue
                self._said.add(key)
                self._node.get_logger().warning(
                    f"{topic}: a publisher (node {publisher}) offers {info.topic_type}, not "
                    f"{msgtype}: "
                    "none of its messages can reach this node"
                )


class SubscriberGate:
    """Opens once every publisher has ``count`` subscribers (and ``ready()``, when given, holds)
    and ``settle_s`` (wall clock) has passed since: DDS discovery is asymmetric, so a publisher
    counts a subscriber before that subscriber has matched the publisher, and a volatile reader
    loses what is sent in between."""

    def __init__(
        self,
        publishers: Sequence[Publisher],
        count: int,
        settle_s: float,
        ready: Callable[[], bool] | None = None,
    ) -> None:
        self._publishers = publishers
        self._count = count
        self._settle_s = settle_s
        self._ready = ready
        self._seen_at: float | None = None

    @property
    def seen(self) -> bool:
        """Whether the subscribers are there (the settle time may still be running)."""
        return self._seen_at is not None

    def open(self) -> bool:
        if self._count == 0:
            return True
        if self._seen_at is None:
            if not all(p.get_subscription_count() >= self._count for p in self._publishers):
                return False
            if self._ready is not None and not self._ready():
                return False
            self._seen_at = time.monotonic()
        return time.monotonic() - self._seen_at >= self._settle_s


def drain(node: Node, publishers: Iterable[Publisher]) -> bool:
    """Before exiting: wait until the subscribers have every message published (unless the
    process was told to stop, which shuts the middleware down), at most ``ACK_TIMEOUT_S`` per
    publisher. True when every publisher's messages were acknowledged."""
    if not node.context.ok():
        return False
    acked = True
    for publisher in publishers:
        acked = publisher.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT_S)) and acked
    return acked


class NodeGroup:
    """Several nodes in one process, one context and one EventsExecutor: the demo and the node
    benchmark use it so that code outside ``tail_beam_sim.ros`` never touches rclpy itself."""

    def __init__(self) -> None:
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.executor = EventsExecutor(context=self.context)
        self.nodes: list[Node] = []

    def add(self, node: Node) -> Node:
        """Spin ``node`` with the group (built with ``context=group.context``); returns it."""
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def listener(
        self,
        name: str,
        namespace: str,
        topics: Mapping[str, Callable[[str], None]],
        depth: int = 1000,
    ) -> Node:
        """A plain node that hands the ``data`` of each ``std_msgs/String`` on ``topics`` to its
        callback."""
        from std_msgs.msg import String

        node = rclpy.create_node(name, context=self.context, namespace=namespace)
        for topic, callback in topics.items():
            node.create_subscription(String, topic, lambda msg, cb=callback: cb(msg.data), depth)
        return self.add(node)

    def spin_once(self, timeout_s: float) -> None:
        spin_once(self.executor, timeout_s)

    def close(self) -> None:
        """Close each node that has ``close()``, destroy them all and shut the context down."""
        for node in self.nodes:
            if isinstance(node, ClosingNode):
                node.close()
        self.executor.shutdown()
        for node in self.nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def rcl_error_line(exc: BaseException) -> str:
    """An RCLError's message as one line, without rcl's source locations (``, at
    /project/src/parse.c:835``)."""
    text = " ".join(str(exc).split())
    return re.sub(r",? at /\S+:\d+", "", text).strip(" ,")


def parameters_given(args: Sequence[str]) -> list[str]:
    """The parameter names (``-p NAME:=VALUE``) and parameter files (``--params-file FILE``) of
    a command line's ROS arguments, in order."""
    given: list[str] = []
    for flag, value in zip(args, args[1:]):
        if flag in ("-p", "--param"):
            given.append(value.split(":=", 1)[0])
        elif flag == "--params-file":
            given.append(f"--params-file {value}")
    return given


def run_node(
    make: Callable[[], Node], usage: NodeUsage | str, args: Sequence[str] | None = None
) -> int:
    """The ``main`` of every executable: build the node, spin it, close and shut down.

    ``-h``/``--help`` prints ``usage`` and exits 0 before ROS starts (no node, no file). A
    :class:`FinishingNode` stops spinning when its ``finished`` future is done; a
    :class:`ClosingNode` is closed on the way out. Bad parameters end it with one line and exit
    status 2, as do arguments rcl refuses (a --params-file that is no YAML or missing, a trailing
    ``-p``) and any other failure to build the node from its parameters (a model that cannot take
    a value: the line names the parameters set); SIGINT and SIGTERM end it with status 0; a node
    that sets ``exit_status`` (a replay that met a damaged bag) exits with it. A
    :class:`HostingNode`'s members spin on the same executor and close with it.
    """
    if isinstance(usage, str):
        usage = NodeUsage(usage, (make.__doc__ or "").strip().split("\n\n")[0])
    executable = usage.executable
    if asks_for_help(list(sys.argv[1:] if args is None else args)):
        try:
            print(usage.text(), flush=True)
        except BrokenPipeError:  # `... -h | head`: the reader left; not an error
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    stop = StopRequest()
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        stop.install()
    except (
        RuntimeError
    ) as exc:  # rcl's RCLError: a --params-file that is no YAML or missing, a trailing -p, ...
        print(f"{executable}: error: --ros-args: {rcl_error_line(exc)}", file=sys.stderr)
        return 2
    try:
        node = make()
    except InputError as exc:
        print(f"{executable}: error: {exc}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    # a value of the right kind that a model cannot take (1e308 Hz: its matrices overflow)
    except Exception as exc:
        given = ", ".join(parameters_given(list(sys.argv[1:] if args is None else args))) or "none"
        print(
            f"{executable}: error: the parameters do not make a working node "
            f"({type(exc).__name__}: "
            f"{' '.join(str(exc).split())[:200]}); set on the command line: {given}",
            file=sys.stderr,
        )
        rclpy.try_shutdown()
        return 2
    try:
        spin(node, node.finished if isinstance(node, FinishingNode) else None, stop)
    finally:
        # told to stop: close without waiting on subscribers (drain), as a shut-down context tells
        # the node
        if stop.requested:
            rclpy.try_shutdown()
        try:
            for member in with_members(node):
                if isinstance(member, ClosingNode):
                    member.close()
                member.destroy_node()
        except Exception:
            if rclpy.ok():
                # a real failure; one on a context SIGINT already invalidated is the shutdown
                raise
        rclpy.try_shutdown()
    return int(getattr(node, "exit_status", 0))
