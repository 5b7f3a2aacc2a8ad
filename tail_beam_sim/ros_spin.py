"""Spinning a node until the process is told to stop, for the suite's executables.

``EventsExecutor.spin()`` (rclpy 9) does not return when SIGINT or SIGTERM shuts the context
down, so the nodes spin in short slices and check the context between them.
"""

from __future__ import annotations

import rclpy
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.task import Future

SLICE_S = 0.1  # longest wait between two checks of the context, s


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
