"""Stream buffers of the identifier: one continuous stream's samples (stamps, values), appended
in chunks as they arrive and joined only when the identifier looks at them."""

from __future__ import annotations

import math

import numpy as np


class Series:
    """One continuous stream's samples, appended in chunks and joined lazily.

    ``stamp_s``: stamps (s, increasing); ``values``: one row per stamp; ``base_index``: the
    absolute index of row 0 after :meth:`trim_before` dropped older rows (detectors keep
    absolute indices)."""

    def __init__(self) -> None:
        self.chunks_t: list[np.ndarray] = []
        self.chunks_v: list[np.ndarray] = []
        self.stamp_s = np.zeros(0)
        self.values = np.zeros((0, 1))
        self.base_index = 0  # absolute index of element 0 (after trimming)
        # ``stamp_s`` and ``values`` are views of rows [start, stop) of these, which have room
        # for more: a join copies the new chunks only, not the whole buffer again. Rows the
        # views show are never written again (a view handed out keeps its contents).
        self._stamp_store = self.stamp_s
        self._value_store = self.values
        self._start = self._stop = 0

    @property
    def seen(self) -> bool:
        """Any sample has arrived (joined or not)."""
        return bool(self.chunks_t) or self.stamp_s.size > 0

    def append(self, stamp_s: np.ndarray, values: np.ndarray) -> None:
        """Add samples (stamps s, one row of values each); a stamp not after every one before it
        (the latest buffered, and those earlier in this chunk) is dropped: a repeat (a topic
        recorded twice) would give a zero sample period."""
        previous = np.maximum.accumulate(np.concatenate([[self.latest_s], stamp_s]))[:-1]
        keep = stamp_s > previous  # per-topic order is preserved; drop repeats
        if keep.any():
            self.chunks_t.append(stamp_s[keep])
            self.chunks_v.append(values[keep])

    @property
    def latest_s(self) -> float:
        """The newest stamp (s), joined or not; -inf before any sample."""
        if self.chunks_t:
            return float(self.chunks_t[-1][-1])
        return float(self.stamp_s[-1]) if self.stamp_s.size else -math.inf

    def join(self) -> None:
        """Move the appended chunks into ``stamp_s`` and ``values``."""
        if not self.chunks_t:
            return
        width = self.chunks_v[0].shape[1]
        if self.values.shape[1] != width:  # the first samples: the width they come with
            self._value_store = np.zeros((0, width))
            self._start = self._stop = 0
        incoming = sum(chunk.size for chunk in self.chunks_t)
        if self._stop + incoming > self._stamp_store.size:
            # Out of room: the rows still shown move to new stores twice their new size.
            kept = self._stop - self._start
            room = 2 * (kept + incoming)
            stamps, values = np.empty(room), np.empty((room, width))
            stamps[:kept] = self._stamp_store[self._start : self._stop]
            values[:kept] = self._value_store[self._start : self._stop]
            self._stamp_store, self._value_store = stamps, values
            self._start, self._stop = 0, kept
        for chunk_t, chunk_v in zip(self.chunks_t, self.chunks_v):
            self._stamp_store[self._stop : self._stop + chunk_t.size] = chunk_t
            self._value_store[self._stop : self._stop + chunk_t.size] = chunk_v
            self._stop += chunk_t.size
        self.stamp_s = self._stamp_store[self._start : self._stop]
        self.values = self._value_store[self._start : self._stop]
        self.chunks_t, self.chunks_v = [], []

    def trim_before(self, stamp_s: float) -> None:
        """Forget samples older than ``stamp_s`` (keeps absolute indices valid)."""
        drop = int(np.searchsorted(self.stamp_s, stamp_s))
        if drop > 0:
            self.stamp_s = self.stamp_s[drop:]
            self.values = self.values[drop:]
            self.base_index += drop
            self._start += drop
