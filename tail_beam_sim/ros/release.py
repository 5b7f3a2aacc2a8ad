"""Messages held until simulation time reaches the moment a real sensor would send them.

sim_node computes its streams a timer tick at a time (``publish_period_s``, 10 ms). Published
whole, a tick's messages all leave together, up to a tick after the samples they carry were
taken; a real sensor sends each message as soon as its last sample is in. With a release
period, sim_node computes one tick ahead and hands every message here with its release stamp
(the stamp of its last sample, s of simulation time); a faster timer takes out what is due.

Pure Python, no ROS: the node and the tests drive the same class.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from typing import Any


class StampedRelease:
    """A queue of messages in release-stamp order (stamps s of simulation time)."""

    def __init__(self) -> None:
        self._queue: deque[tuple[float, Any]] = deque()

    def __len__(self) -> int:
        return len(self._queue)

    def add(self, items: Iterable[tuple[float, Any]]) -> None:
        """Queue (release stamp s, item) pairs, a tick's items sorted. An item stamped before one
        already queued goes out with it: the order in which items were added is never changed
        (a tick's items all end after the previous tick's end, so this does not happen)."""
        newest = self._queue[-1][0] if self._queue else float("-inf")
        for stamp, item in items:
            newest = max(newest, stamp)
            self._queue.append((newest, item))

    def due(self, now_s: float) -> list[Any]:
        """The items whose release stamp is at or before ``now_s`` (s), in order, taken out."""
        out = []
        while self._queue and self._queue[0][0] <= now_s:
            out.append(self._queue.popleft()[1])
        return out

    def drain(self) -> list[Any]:
        """Every item still queued, in order, taken out (on exit: nothing is lost)."""
        out = [item for _, item in self._queue]
        self._queue.clear()
        return out
