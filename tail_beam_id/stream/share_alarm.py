"""A crossing rule on the gangue share's intervals: when a window controller should take the
share as having reached a level (1/5, 1/3), with a minimum of evidence and hysteresis, so that
one noisy interval in pure coal does not close a window.

A caving window opens on top coal. The intervals ending within ``alarm_reference_s`` of its
opening (:meth:`ShareAlarm.open`; without it, the first interval's start) are the window's
reference: what the estimator reads of pure coal on this
support (its mean ``b``, where another support's labels err more or less than training's).
The level ``L`` is then measured from it, ``b + L (1 - b)``: the reading a share of ``L`` gives
if the support's error shifts every reading alike. The alarm cannot rise during the reference;
after it, it rises once ``alarm_intervals`` consecutive intervals each read at least
``alarm_margin`` above that level and at least ``alarm_z`` standard errors (the estimator's:
statistical and, for the mixture estimate, systematic) above ``L`` itself; it clears once an
interval's share falls below the measured level. An interval with no estimate (no impact)
neither raises nor clears it, and breaks a run. With ``alarm_reference_s`` 0 there is no
reference: the level is ``L`` and the margin unused.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from tail_beam_id.stream.share import GangueShare, ShareConfig
from tail_beam_sim.errors import InputError


def evidence_above(
    share: float | None, standard_error: float | None, level: float, z: float
) -> bool:
    """An interval's ``share`` lies at least ``z`` standard errors above ``level`` (no standard
    error, none of its labels disagreeing: the share itself reaches it; no share: no evidence)."""
    return share is not None and share - z * (standard_error or 0.0) >= level


@dataclass
class ShareAlarm:
    """The crossing rule at one level (module docstring); :meth:`update` takes the intervals in
    stamp order, from the window's opening."""

    level: float
    z: float = ShareConfig.alarm_z
    intervals: int = ShareConfig.alarm_intervals
    reference_s: float = ShareConfig.alarm_reference_s
    margin: float = ShareConfig.alarm_margin
    raised: bool = False
    _run: int = 0
    _opened_s: float | None = None
    _reference: list[float] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not 0.0 < self.level < 1.0:
            raise InputError("alarm level", self.level, "must be in (0, 1)")
        if self.intervals < 1:
            raise InputError("alarm_intervals", self.intervals, "must be at least 1")
        if self.reference_s < 0.0:
            raise InputError("alarm_reference_s", self.reference_s, "must be >= 0 s")
        if not 0.0 <= self.margin <= 1.0:
            raise InputError("alarm_margin", self.margin, "must be in [0, 1]")

    @classmethod
    def of(cls, level: float, config: ShareConfig) -> ShareAlarm:
        return cls(
            level,
            config.alarm_z,
            config.alarm_intervals,
            config.alarm_reference_s,
            config.alarm_margin,
        )

    def measured_level(self) -> float:
        """The level as the estimator reads it on this support: ``level`` measured from the
        reference's mean reading (``level`` itself without a reference, or before one)."""
        if not self._reference:
            return self.level
        base = sum(self._reference) / len(self._reference)
        return base + self.level * (1.0 - base)

    def open(self, stamp_s: float) -> None:
        """The window opened at ``stamp_s`` (s): the reference is counted from it (without this
        call, from the first interval's start)."""
        self._opened_s = stamp_s

    def update(self, share: GangueShare) -> bool:
        """Take the next interval; whether the alarm is raised after it."""
        return self.observe(
            share.start_stamp_s, share.end_stamp_s, share.share, share.standard_error
        )

    def observe(
        self,
        start_s: float,
        end_s: float,
        share: float | None,
        standard_error: float | None,
    ) -> bool:
        """Take the next interval, [``start_s``, ``end_s``) (s), its estimated ``share`` (None:
        no estimate) and standard error; whether the alarm is raised after it."""
        if self._opened_s is None:
            self._opened_s = start_s
        if end_s <= self._opened_s + self.reference_s:
            if share is not None:
                self._reference.append(share)
            return self.raised
        if share is None:
            self._run = 0
            return self.raised
        level = self.measured_level()
        margin = self.margin if self.reference_s > 0.0 else 0.0
        if share >= level + margin and evidence_above(share, standard_error, self.level, self.z):
            self._run += 1
            if self._run >= self.intervals:
                self.raised = True
        else:
            self._run = 0
            if share < level:
                self.raised = False
        return self.raised


def alarm_states(shares: Iterable[GangueShare], level: float, config: ShareConfig) -> list[bool]:
    """Whether the alarm at ``level`` is raised after each interval, in order (the first one
    starting as the window opens)."""
    alarm = ShareAlarm.of(level, config)
    return [alarm.update(s) for s in shares]
