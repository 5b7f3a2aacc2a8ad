"""Where the particle struck, as the rebound camera reports it (topic ``impact_point``): taking
the points in, refusing what is no point on the plate, and pairing each with its rebound.

A point carries its impact's rebound stamp (docs/interface.md), so a rebound's point is the one
stamped within STAMP_MATCH_S of it. The camera may send the two in either order: a point is kept
until a rebound of its stamp comes, and set aside (counted, ``no rebound at its stamp``) once
the streams have passed its stamp by ``camera_timeout_s`` without one; a rebound without a
point is decided as it always was. A message that is no point on this support's plate (another
frame, a coordinate not finite, z other than 0, off the plate's length or width:
:func:`tail_beam_sim.topics.impact_point_xy`) is refused by name and counted by reason; a
point at a stamp that already has one is a repeat and ignored.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from tail_beam_id.methods.inputs import IMPACT_X, IMPACT_Y
from tail_beam_sim import topics
from tail_beam_sim.errors import InputError

STAMP_MATCH_S = 1e-6  # a point and a rebound stamped this close (s) are of one impact
NO_REBOUND = "no rebound at its stamp"  # why an unpaired point is set aside


class ImpactPoints:
    """The points waiting for their rebound and those refused (module docstring)."""

    def __init__(self, plate_m: Callable[[], tuple[float, float]], timeout_s: float) -> None:
        """``plate_m()``: the plate's (length from the hinge, width), m, of the support as the
        identifier knows it now; ``timeout_s``: how long past its stamp (stamp time, s) a point
        waits for a rebound."""
        self.plate_m = plate_m
        self.timeout_s = timeout_s
        self.points: dict[float, tuple[float, float]] = {}  # stamp s -> (x m, y m)
        self.unpaired: set[float] = set()  # stamps of points no rebound has claimed yet
        # Messages refused or set aside, by "field: what is allowed" or NO_REBOUND.
        self.refused: dict[str, int] = {}
        self._rebounds: list[float] = []  # rebound stamps not yet paired with a point, s

    @property
    def refused_count(self) -> int:
        """Points refused or set aside, in all."""
        return sum(self.refused.values())

    def add(self, stamp_s: float, point_m: np.ndarray, frame_id: str) -> str | None:
        """One point: its stamp (s), (x, y, z) in m and frame. Returns why it was refused
        (``field = value: what is allowed``; counted by field and rule), or None when it is
        kept."""
        try:
            if not math.isfinite(stamp_s):
                raise InputError("impact_point.header.stamp", stamp_s, "must be a finite time, s")
            values = np.asarray(point_m, dtype=float).reshape(3)
            length_m, width_m = self.plate_m()
            xy = topics.impact_point_xy(frame_id, *values.tolist(), length_m, width_m)
        except InputError as exc:
            # Counted by field and rule, not by value: a flood of bad values is a few counts.
            reason = f"{exc.field}: {exc.allowed}"
            self.refused[reason] = self.refused.get(reason, 0) + 1
            return str(exc)
        if _near(stamp_s, self.points) is not None:
            return None  # a repeat
        stamp = float(stamp_s)
        self.points[stamp] = xy
        rebound = _near(stamp, self._rebounds)
        if rebound is None:
            self.unpaired.add(stamp)
        else:
            self._rebounds.remove(rebound)
        return None

    def add_rebound(self, stamp_s: float) -> None:
        """A rebound's stamp (s): the point of that stamp, come or to come, is its impact's."""
        point = _near(stamp_s, self.unpaired)
        if point is None:
            self._rebounds.append(float(stamp_s))
        else:
            self.unpaired.discard(point)

    def point_of(self, rebound_stamp_s: float) -> tuple[float, float] | None:
        """The (x, y) point (m) stamped as the rebound at ``rebound_stamp_s`` (s), or None."""
        key = _near(rebound_stamp_s, self.points)
        return None if key is None else self.points[key]

    def expire(self, newest_s: float) -> int:
        """Set aside the points the streams (newest stamp ``newest_s``, s) have passed by
        ``timeout_s`` without a rebound of their stamp; returns how many."""
        horizon = newest_s - self.timeout_s
        old = [t for t in self.unpaired if t < horizon]
        for stamp in old:
            self.unpaired.discard(stamp)
            del self.points[stamp]
        if old:
            self.refused[NO_REBOUND] = self.refused.get(NO_REBOUND, 0) + len(old)
        self._rebounds = [t for t in self._rebounds if t >= horizon]
        return len(old)

    def flush(self) -> int:
        """End of data: every point still without a rebound is set aside; returns how many."""
        return self.expire(math.inf)

    def forget_before(self, stamp_s: float) -> None:
        """Drop the paired points older than ``stamp_s`` (s): their impacts are decided."""
        self.points = {
            t: xy for t, xy in self.points.items() if t >= stamp_s or t in self.unpaired
        }


def _near(stamp_s: float, stamps: object) -> float | None:
    """The first of ``stamps`` (s) within STAMP_MATCH_S of ``stamp_s`` (s), or None."""
    for key in stamps:  # type: ignore[attr-defined]
        if abs(key - stamp_s) <= STAMP_MATCH_S:
            return key
    return None


__all__ = ["IMPACT_X", "IMPACT_Y", "NO_REBOUND", "STAMP_MATCH_S", "ImpactPoints"]
