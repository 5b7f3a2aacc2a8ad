"""Running a node as an executable: init, spin until told to stop, shut down.

``EventsExecutor.spin()`` (rclpy 9) does not return when SIGINT or SIGTERM shuts the context
down, so the nodes spin in short slices and check the context between them.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable, Sequence

import rclpy
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.task import Future

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
