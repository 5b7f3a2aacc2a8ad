"""Samples missing from a sensor stream on a fixed grid, counted from the stamps alone.

Pressure and IMU samples are stamped k / rate (docs/interface.md): a step between two
consecutive stamps of more than one sample period is a gap, whatever the middleware reported
(a best-effort reader's history overflowing is reported by no DDS event). The period is read
from the stamps (the smallest step seen), never assumed.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable

GAP_FACTOR = 1.5  # a step longer than this many periods is a gap
WARMUP_STEPS = 16  # steps seen before gaps are counted (the period estimate settles), count
JUMP_S = 1.0  # a step longer than this (s) is a new time base (a restart, a looped replay)


class GridGaps:
    """Counts the samples missing between consecutive stamps of one stream (``lost_samples``,
    ``gap_count``); :meth:`add` returns each gap found as (stamp before, stamp after, samples
    missing). A stamp going back, or ahead by more than ``jump_s``, starts the stream anew."""

    def __init__(self, jump_s: float = JUMP_S) -> None:
        self.jump_s = jump_s
        self.period_s = math.inf
        self.lost_samples = 0
        self.gap_count = 0
        self._last_s: float | None = None
        self._steps = 0

    def add(self, stamps_s: Iterable[float]) -> list[tuple[float, float, int]]:
        gaps: list[tuple[float, float, int]] = []
        last = self._last_s
        for stamp in stamps_s:
            if last is not None:
                step = stamp - last
                if 0.0 < step <= self.jump_s:
                    self._steps += 1
                    if step < self.period_s:
                        self.period_s = step
                    if self._steps > WARMUP_STEPS and step > GAP_FACTOR * self.period_s:
                        missing = round(step / self.period_s) - 1
                        gaps.append((last, stamp, missing))
                        self.lost_samples += missing
                        self.gap_count += 1
                elif step == 0.0:
                    continue  # a repeated sample: not a step
            last = stamp
        self._last_s = last
        return gaps


def cdr_stamp_s(data: bytes) -> float | None:
    """``header.stamp`` of a serialized message whose first field is a std_msgs/Header
    (FluidPressure, Imu), s; None if it is too short to hold one."""
    if len(data) < 12:
        return None
    order = "<" if data[1] & 1 else ">"  # CDR encapsulation: 0x0001 little endian, 0x0000 big
    sec, nanosec = struct.unpack_from(order + "iI", data, 4)
    return sec + nanosec * 1e-9
