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
        if self.chunks_t:
            self.stamp_s = np.concatenate([self.stamp_s, *self.chunks_t])
            width = self.chunks_v[0].shape[1]
            old = self.values if self.values.shape[1] == width else np.zeros((0, width))
            self.values = np.concatenate([old, *self.chunks_v])
            self.chunks_t, self.chunks_v = [], []

    def trim_before(self, stamp_s: float) -> None:
        """Forget samples older than ``stamp_s`` (keeps absolute indices valid)."""
        drop = int(np.searchsorted(self.stamp_s, stamp_s))
        if drop > 0:
            self.stamp_s = self.stamp_s[drop:]
            self.values = self.values[drop:]
            self.base_index += drop
