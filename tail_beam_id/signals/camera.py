"""The camera's frame period, read from the stamps of its rebounds.

A high-speed camera stamps a rebound with the first frame after the particle left the plate
(docs/interface.md), so every rebound stamp lies on the camera's frame grid and the delay from
an impact's onset to it is the contact duration plus up to one frame period. The statistical
method needs that period to know how much of the delay is the camera's (a 1 kHz camera adds
up to 1 ms, longer than most contacts); a bag does not say it, but its rebound stamps do: every
difference between two of them is a whole number of frames.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence

import numpy as np

# how far a stamp may lie off the frame grid (clock jitter, ns rounding, float epoch stamps), s
GRID_TOLERANCE_S = 1e-6
MIN_PERIOD_S = (
    20e-6  # the fastest camera recognised (50 kHz): below it any stamps fit some grid, s
)
MAX_PERIOD_S = 0.002  # the slowest (500 Hz), s
# Rebounds needed. With 3 differences, twice the true period fits by chance 1 time in 8 (until a
# later stamp falls on an odd frame); that only makes decisions less sure, while the configured
# period, when the camera is slower, makes them surely wrong, so waiting for more rebounds than
# this costs more confident wrong labels than it saves (docs/identification.md).
MIN_REBOUNDS = 4
MAX_REBOUNDS = 64  # rebounds kept for the estimate (the grid does not change)
# The frame (s) of a camera whose MIN_REBOUNDS or more stamps lie on no grid of MIN_PERIOD_S or
# more (module docstring): shorter than any lag the statistical models tell from none (they read
# every frame below their floor, 10 us, alike).
GRIDLESS_PERIOD_S = 1e-6


def frame_period_s(
    stamps_s: Sequence[float], tolerance_s: float = GRID_TOLERANCE_S
) -> float | None:
    """The longest frame period (s) up to ``MAX_PERIOD_S`` on whose grid every stamp lies within
    ``tolerance_s``, or None: too few stamps (< ``MIN_REBOUNDS``), or none of ``MIN_PERIOD_S``
    or more (stamps on no grid: a camera stamped by its host's clock, say).

    The smallest difference between stamps is a whole number n of periods, so the candidates
    are that difference over n = 1, 2, ...; the first that every other difference fits is it.
    Errs long, never short: with few stamps, or impacts on a regular schedule whose contacts all
    end in the same frame of it, a multiple of the frame fits too and is what comes out. A
    period too long only makes the statistical method less sure of a label (it averages over a
    longer lag); one too short (the configured one, when the camera is slower) makes it surely
    wrong."""
    stamps = np.unique(np.asarray(stamps_s, dtype=float))
    if stamps.size < MIN_REBOUNDS or not np.isfinite(stamps).all():
        return None
    diffs = np.diff(stamps)
    smallest = float(diffs.min())
    first = max(1, math.ceil(smallest / MAX_PERIOD_S * (1.0 - 1e-9)))
    last = math.floor(smallest / MIN_PERIOD_S * (1.0 + 1e-9))
    if last < first:
        return None
    periods = smallest / np.arange(first, last + 1)  # longest first
    # Each difference in turn keeps the candidates it lies a whole number of periods from (within
    # the tolerance): the first difference leaves few, so the rest cost little.
    for diff in diffs:
        periods = periods[np.abs(diff - np.round(diff / periods) * periods) <= tolerance_s]
        if not periods.size:
            return None
    return float(periods[0])


def measured_period_s(stamps_s: Sequence[float]) -> float | None:
    """The camera's frame period (s) the rebound stamps say: their grid's
    (:func:`frame_period_s`), GRIDLESS_PERIOD_S when MIN_REBOUNDS or more distinct stamps lie on
    no grid, None from fewer."""
    if len(set(stamps_s)) < MIN_REBOUNDS:
        return None
    return frame_period_s(stamps_s) or GRIDLESS_PERIOD_S


class FramePeriod:
    """The camera's frame period for one stream: from the rebound stamps once enough have come
    (:func:`frame_period_s`), else the configured one (``configured_s``, s; None if unknown).

    A configured frame longer than the stamps' estimate wins while every stamp lies on its grid:
    the stamps are read only up to MAX_PERIOD_S (a slower camera's fit a shorter frame too), so a
    user who says the camera is slower is believed until a stamp says otherwise.

    What an impact's decision uses depends only on the stamps up to its own rebound
    (:meth:`period_at`), so live and offline decisions agree however the rebounds arrive."""

    def __init__(self, configured_s: float | None) -> None:
        self.configured_s = configured_s
        self.stamps_s: list[float] = []
        self.estimates_s: list[float | None] = []  # [k]: the estimate from the first k + 1 stamps
        self.on_configured_grid: list[
            bool
        ] = []  # [k]: the first k + 1 stamps all lie on the configured frame's grid

    def add(self, stamp_s: float) -> None:
        """A rebound's stamp (s), in stamp order (repeats and older ones ignored); estimates
        again until ``MAX_REBOUNDS`` have come. While the stamps fit the last estimate only the
        new difference is checked, so a rebound costs microseconds, not a search."""
        if (
            len(self.stamps_s) >= MAX_REBOUNDS
            or not math.isfinite(stamp_s)
            or (self.stamps_s and stamp_s <= self.stamps_s[-1])
        ):
            return
        self.stamps_s.append(float(stamp_s))
        fits = self.configured_s is not None and _on_grid(
            stamp_s - self.stamps_s[0], self.configured_s
        )
        self.on_configured_grid.append(
            fits and (self.on_configured_grid[-1] if self.on_configured_grid else True)
        )
        last = self.estimates_s[-1] if self.estimates_s else None
        if last is not None and _on_grid(stamp_s - self.stamps_s[-2], last):
            estimate: float | None = last
        else:
            estimate = measured_period_s(self.stamps_s)
        self.estimates_s.append(estimate)

    def measured_at(self, stamp_s: float) -> float | None:
        """The frame period (s) the stamps up to ``stamp_s`` gave (GRIDLESS_PERIOD_S for stamps
        on no grid), or None (fewer than MIN_REBOUNDS): measured only, never the configured
        one."""
        k = bisect.bisect_right(self.stamps_s, stamp_s)
        return self.estimates_s[k - 1] if k else None

    def period_at(self, stamp_s: float) -> float | None:
        """The frame period (s) a rebound stamped ``stamp_s`` is decided with: measured from the
        stamps up to it if they gave one, else configured."""
        k = bisect.bisect_right(self.stamps_s, stamp_s)
        measured = self.estimates_s[k - 1] if k else None
        if measured is None:
            return self.configured_s
        if (
            self.configured_s is not None
            and self.configured_s > measured
            and self.on_configured_grid[k - 1]
        ):
            return self.configured_s
        return measured


def may_be_slower(measured_s: float | None) -> bool:
    """Whether a camera whose stamps gave ``measured_s`` (s; None: not measured) may have a
    longer frame than that: its frame is unknown, or the stamps of a camera slower than
    MAX_PERIOD_S fit a frame between half of it and it (a 240 Hz camera's 4.17 ms reads as
    1.39 ms, a 100 Hz one's as 2 ms), so an estimate there is no proof of a fast camera."""
    return measured_s is None or measured_s > MAX_PERIOD_S / 2.0


def _on_grid(difference_s: float, period_s: float) -> bool:
    """A stamp difference is a whole number of periods, within GRID_TOLERANCE_S."""
    return abs(difference_s - round(difference_s / period_s) * period_s) <= GRID_TOLERANCE_S
