"""A crossing rule on the gangue share's intervals: when a window controller should take the
share as having reached a level (1/5, 1/3), with a minimum of evidence and hysteresis, so that
one noisy interval in pure coal does not close a window.

The alarm rises once ``alarm_intervals`` consecutive intervals each put the share at least
``alarm_z`` standard errors above the level (the estimator's standard error: statistical and,
for the mixture estimate, systematic); it clears once an interval's share falls below the
level. An interval with no estimate (no impact) neither raises nor clears it, and breaks a run.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from tail_beam_id.stream.share import GangueShare, ShareConfig
from tail_beam_sim.errors import InputError


def evidence_above(share: GangueShare, level: float, z: float) -> bool:
    """The interval puts the share at least ``z`` standard errors above ``level`` (an interval
    with no standard error, none of its labels disagreeing: the share itself reaches it)."""
    if share.share is None:
        return False
    return share.share - z * (share.standard_error or 0.0) >= level


@dataclass
class ShareAlarm:
    """The crossing rule at one level (module docstring); :meth:`update` takes the intervals in
    stamp order."""

    level: float
    z: float = ShareConfig.alarm_z
    intervals: int = ShareConfig.alarm_intervals
    raised: bool = False
    _run: int = 0

    def __post_init__(self) -> None:
        if not 0.0 < self.level < 1.0:
            raise InputError("alarm level", self.level, "must be in (0, 1)")
        if self.intervals < 1:
            raise InputError("alarm_intervals", self.intervals, "must be at least 1")

    @classmethod
    def of(cls, level: float, config: ShareConfig) -> ShareAlarm:
        return cls(level, config.alarm_z, config.alarm_intervals)

    def update(self, share: GangueShare) -> bool:
        """Take the next interval; whether the alarm is raised after it."""
        if share.share is None:
            self._run = 0
            return self.raised
        if evidence_above(share, self.level, self.z):
            self._run += 1
            if self._run >= self.intervals:
                self.raised = True
        else:
            self._run = 0
            if share.share < self.level:
                self.raised = False
        return self.raised


def alarm_states(shares: Iterable[GangueShare], level: float, config: ShareConfig) -> list[bool]:
    """Whether the alarm at ``level`` is raised after each interval, in order."""
    alarm = ShareAlarm.of(level, config)
    return [alarm.update(s) for s in shares]
