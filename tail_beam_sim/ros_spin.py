"""Running a node as an executable: init, spin until told to stop, shut down.

``EventsExecutor.spin()`` (rclpy 9) does not return when SIGINT or SIGTERM shuts the context
down, so the nodes spin in short slices and check the context between them.
"""

from __future__ import annotations

import sys
import time
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import rclpy
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.task import Future
from rclpy._rclpy_pybind11 import RCLError

from tail_beam_sim.errors import InputError

SLICE_S = 0.1  # longest wait between two checks of the context, s
ACK_TIMEOUT_S = 10.0  # how long a closing publisher waits for its subscribers to have everything, s


def spin(node: Node, done: Future | None = None) -> None:
    """Spin ``node`` on an EventsExecutor until shutdown (SIGINT, SIGTERM) or ``done``."""
    executor: Executor = EventsExecutor(context=node.context)
    executor.add_node(node)
    try:
        while rclpy.ok(context=node.context) and not (done is not None and done.done()):
            executor.spin_once(timeout_sec=SLICE_S)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
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
            except RCLError:
                if not self._held:
                    self._node.get_logger().warning(
                        f"a subscriber of {publisher.topic_name} is behind: holding {len(self._queue)} messages until it catches up"
                    )
                self._held = True
                return False
            self._queue.popleft()
        self._held = False
        return True


class SubscriberGate:
    """Opens once every publisher has ``count`` subscribers and ``settle_s`` (wall clock) has
    passed since: DDS discovery is asymmetric, so a publisher counts a subscriber before that
    subscriber has matched the publisher, and a volatile reader loses what is sent in between."""

    def __init__(self, publishers: Sequence[Publisher], count: int, settle_s: float) -> None:
        self._publishers = publishers
        self._count = count
        self._settle_s = settle_s
        self._seen_at: float | None = None

    def open(self) -> bool:
        if self._count == 0:
            return True
        if self._seen_at is None:
            if not all(p.get_subscription_count() >= self._count for p in self._publishers):
                return False
            self._seen_at = time.monotonic()
        return time.monotonic() - self._seen_at >= self._settle_s


def drain(node: Node, publishers: Iterable[Publisher]) -> None:
    """Before exiting: wait until the subscribers have every message published (unless the
    process was told to stop, which shuts the middleware down)."""
    if not node.context.ok():
        return
    for publisher in publishers:
        publisher.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT_S))


def run_node(make: Callable[[], Node], executable: str, args: Sequence[str] | None = None) -> int:
    """The ``main`` of every executable: build the node, spin it, close and shut down.

    The node may have a ``finished`` future (spinning stops when it is done) and a ``close()``
    method (called on the way out). Bad parameters end it with one line and exit status 2.
    """
    rclpy.init(args=args)
    try:
        node = make()
    except InputError as exc:
        print(f"{executable}: error: {exc}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    try:
        spin(node, getattr(node, "finished", None))
    finally:
        close = getattr(node, "close", None)
        if close is not None:
            close()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
