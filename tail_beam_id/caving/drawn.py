"""What a window drew from a flow of lumps, and what the oracle rule would have drawn.

A flow's lumps depend only on its seed and its window's opening and closing stamps
(:class:`tail_beam_sim.physics.lumps.LumpSource`), so the lumps a live window drew are drawn again
here from a fresh source with the same seed and the same stamps, without the sensors; and so are
the lumps of the same window closed where the oracle rule would have closed it: at the end of
the first interval of ``interval_s`` (on the grid ``k interval_s`` of stamp time, lumps counted by
the stamp they strike at, as ``gangue_share_truth`` counts them) whose gangue share by mass
reaches ``level``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.lumps import Lump, LumpSource

__all__ = ["Drawn", "drawn_between", "oracle_close_s"]


@dataclass(frozen=True)
class Drawn:
    """Lumps drawn through one window: how many, their mass and its gangue part, kg."""

    lumps: int
    mass_kg: float
    gangue_kg: float

    @property
    def coal_kg(self) -> float:
        return self.mass_kg - self.gangue_kg

    @property
    def gangue_content(self) -> float:
        """Gangue mass over drawn mass (0 when nothing was drawn)."""
        return self.gangue_kg / self.mass_kg if self.mass_kg > 0.0 else 0.0

    @classmethod
    def of(cls, lumps: list[Lump]) -> Drawn:
        return cls(
            len(lumps),
            sum(lump.mass_kg for lump in lumps),
            sum(lump.mass_kg for lump in lumps if lump.is_gangue),
        )


def drawn_between(source: LumpSource, opened_s: float, closed_s: float) -> Drawn:
    """The lumps a fresh ``source`` releases while its window is open from ``opened_s`` to
    ``closed_s`` (s; those released before the closing land after it and count)."""
    if not closed_s >= opened_s:
        raise InputError("closed_s", closed_s, f"must be >= the opening ({opened_s:g} s)")
    source.open(opened_s)
    source.close(closed_s)
    return Drawn.of(source.take_until(math.inf))


def oracle_close_s(
    source: LumpSource, opened_s: float, interval_s: float, level: float, limit_s: float
) -> float | None:
    """Where the oracle closes a window of a fresh ``source`` opened at ``opened_s``: the end of
    the first interval whose gangue share by mass reaches ``level``; None if none does within
    ``limit_s`` of the opening (s)."""
    if not (math.isfinite(interval_s) and interval_s > 0.0):
        raise InputError("interval_s", interval_s, "must be > 0 s")
    source.open(opened_s)
    end = (math.floor(opened_s / interval_s) + 1) * interval_s
    pending: list[Lump] = []
    while end <= opened_s + limit_s + interval_s:
        pending += source.take_until(end)
        inside = [lump for lump in pending if lump.contact_stamp_s < end]
        pending = [lump for lump in pending if lump.contact_stamp_s >= end]
        drawn = Drawn.of(inside)
        if drawn.mass_kg > 0.0 and drawn.gangue_content >= level:
            return end
        end += interval_s
    return None
