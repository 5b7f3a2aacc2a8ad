"""The caving window's closing rules: one interface, ``feed(event) -> Decision | None``.

A rule is made for one window: fed the window's :class:`~tail_beam_id.caving.events.Opened`
and then its events in the order they become known, it gives at most one decision, the first
time its condition holds, and None for every other event. Events stamped before the window
opened (a late label of the previous window) are left out; labels are taken in impact-stamp
order however late they come.

The rules (docs/caving.md):

- :class:`FixedTime`: close after a fixed drawing time.
- :class:`FirstGangue`: close at the first gangue label ("see gangue, close the window").
- :class:`ShareOfLastLabels`: close when gangue is at least a level (1/3, 1/5) of the last K
  labels.
- :class:`Sprt`: Wald's sequential probability ratio test (Wald, Ann. Math. Stat. 16, 117,
  1945) on each label, weighted by its confidence: the window's gangue share is ``p0`` (still
  coal) against ``p1`` (close). A label of confidence ``c`` says gangue with probability
  ``p c + (1 - p)(1 - c)`` when the share is ``p``; the log likelihood ratio adds up label by
  label; above ``log((1 - beta) / alpha)`` the window closes, below ``log(beta / (1 - alpha))``
  the stretch so far is taken as coal and the test starts again (a repeated SPRT, Page's
  CUSUM in spirit).
- :class:`ShareEstimateLevel`: close when a ``gangue_share`` estimate's interval lies above a
  level (its lower bound reaches it).
- :class:`ShareCrossing`: close when the share's crossing rule
  (:mod:`tail_beam_id.stream.share_alarm`) rises at that level: measured from the window's
  first seconds of top coal, over consecutive estimates.
- :class:`Oracle`: close when the true instantaneous share reaches a level: the upper bound,
  fed by the simulation's truth.

Parameters are checked against the ``caving`` section (tail_beam_sim.spec); a value out of
range is an InputError naming ``caving.<field>`` and the range.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable, Mapping
from typing import Any

from tail_beam_id.caving.events import (
    Decision,
    Event,
    LabelEvent,
    Opened,
    ShareEstimate,
    TrueShare,
)
from tail_beam_id.stream.share import ShareConfig
from tail_beam_id.stream.share_alarm import ShareAlarm
from tail_beam_sim.errors import InputError
from tail_beam_sim.spec import CAVING

__all__ = [
    "FirstGangue",
    "FixedTime",
    "Oracle",
    "Rule",
    "ShareCrossing",
    "ShareEstimateLevel",
    "ShareOfLastLabels",
    "Sprt",
    "rule_factories",
]

CONFIDENCE_FLOOR = 1e-6  # a label of confidence 1 (or 0) would end the test on its own


def _check(name: str, value: Any, **context: Any) -> Any:
    """``value`` as the ``caving`` section's field ``name`` allows it, or InputError."""
    return CAVING.check({name: value}, only=[name], context=context)[name]


class Rule:
    """One window's closing rule: feed it events, it answers the first time it would close."""

    name = "rule"

    def __init__(self) -> None:
        self.opened_s = -math.inf
        self.decision: Decision | None = None

    def feed(self, event: Event) -> Decision | None:
        """The decision this event brings, or None (also after the rule has decided)."""
        if self.decision is not None:
            return None
        if isinstance(event, Opened):
            self.opened_s = event.stamp_s
            return None
        if event.stamp_s < self.opened_s:
            return None  # of an earlier window
        self.decision = self._consider(event)
        return self.decision

    def _consider(self, event: Event) -> Decision | None:
        raise NotImplementedError

    def _decide(self, event: Event, reason: str, evidence: tuple[Event, ...]) -> Decision:
        return Decision(event.known_s, self.name, reason, evidence)


class FixedTime(Rule):
    """Close once ``drawing_time_s`` has passed since the window opened (any event at or after
    that time says so; without an :class:`Opened` event it never closes)."""

    name = "fixed_time"

    def __init__(self, drawing_time_s: float) -> None:
        super().__init__()
        self.drawing_time_s = _check("fixed_time_s", drawing_time_s)

    def _consider(self, event: Event) -> Decision | None:
        if math.isinf(self.opened_s):
            return None
        due = self.opened_s + self.drawing_time_s
        if event.known_s < due:
            return None
        return Decision(due, self.name, f"drawn {self.drawing_time_s:g} s", (event,))


class FirstGangue(Rule):
    """Close at the first gangue label whose confidence is at least ``min_confidence``."""

    name = "first_gangue"

    def __init__(self, min_confidence: float = 0.0) -> None:
        super().__init__()
        self.min_confidence = _check("first_gangue_min_confidence", min_confidence)

    def _consider(self, event: Event) -> Decision | None:
        if isinstance(event, LabelEvent) and event.gangue:
            if event.confidence >= self.min_confidence:
                return self._decide(
                    event, f"gangue label of confidence {event.confidence:.2f}", (event,)
                )
        return None


class ShareOfLastLabels(Rule):
    """Close when at least ``level`` of the last ``last_labels`` labels (by impact stamp) are
    gangue; not before that many labels are in."""

    def __init__(self, level: float, last_labels: int) -> None:
        super().__init__()
        self.level = _check("share_levels", [level])[0]
        self.last_labels = _check("last_labels", last_labels)
        self.name = f"share_{self.level:.3g}"
        self._labels: list[LabelEvent] = []
        self._stamps: list[float] = []

    def _consider(self, event: Event) -> Decision | None:
        if not isinstance(event, LabelEvent):
            return None
        k = bisect.bisect_right(self._stamps, event.stamp_s)
        self._stamps.insert(k, event.stamp_s)
        self._labels.insert(k, event)
        if len(self._labels) < self.last_labels:
            return None
        last = tuple(self._labels[-self.last_labels :])
        gangue = sum(label.gangue for label in last)
        if gangue < self.level * self.last_labels - 1e-9:
            return None
        return self._decide(event, f"{gangue} of the last {self.last_labels} labels gangue", last)


class Sprt(Rule):
    """Wald's SPRT on the labels and their confidences: share ``share_low`` (coal) against
    ``share_high`` (close), false-alarm chance ``alpha``, miss chance ``beta``; restarted each
    time the stretch is taken as coal."""

    name = "sprt"

    def __init__(self, share_low: float, share_high: float, alpha: float, beta: float) -> None:
        super().__init__()
        self.share_low = _check("sprt_share_low", share_low)
        self.share_high = _check("sprt_share_high", share_high, sprt_share_low=self.share_low)
        if self.share_high <= self.share_low:
            # The range check allows equality; a test needs two different shares.
            raise InputError(
                "caving.sprt_share_high",
                share_high,
                f"must be > caving.sprt_share_low ({self.share_low:g})",
            )
        self.alpha = _check("sprt_alpha", alpha)
        self.beta = _check("sprt_beta", beta)
        self.upper = math.log((1.0 - self.beta) / self.alpha)
        self.lower = math.log(self.beta / (1.0 - self.alpha))
        self.llr = 0.0
        self._stretch: list[LabelEvent] = []

    def _consider(self, event: Event) -> Decision | None:
        if not isinstance(event, LabelEvent):
            return None
        # A label of confidence c is right with chance c: it says gangue with chance
        # p c + (1 - p)(1 - c) when the share is p, coal with (1 - p) c + p (1 - c).
        c = min(max(event.confidence, CONFIDENCE_FLOOR), 1.0 - CONFIDENCE_FLOOR)
        p1, p0 = self.share_high, self.share_low
        if event.gangue:
            self.llr += math.log((p1 * c + (1 - p1) * (1 - c)) / (p0 * c + (1 - p0) * (1 - c)))
        else:
            self.llr += math.log(((1 - p1) * c + p1 * (1 - c)) / ((1 - p0) * c + p0 * (1 - c)))
        self._stretch.append(event)
        if self.llr >= self.upper:
            return self._decide(
                event,
                f"log likelihood ratio {self.llr:.2f} >= {self.upper:.2f} over "
                f"{len(self._stretch)} labels",
                tuple(self._stretch),
            )
        if self.llr <= self.lower:
            self.llr = 0.0
            self._stretch = []
        return None


class ShareEstimateLevel(Rule):
    """Close when a ``gangue_share`` estimate's lower bound reaches ``level``."""

    name = "share_estimate"

    def __init__(self, level: float) -> None:
        super().__init__()
        self.level = _check("estimate_level", level)

    def _consider(self, event: Event) -> Decision | None:
        if isinstance(event, ShareEstimate) and event.low >= self.level:
            return self._decide(
                event,
                f"gangue share {event.share:.2f} in [{event.low:.2f}, {event.high:.2f}]",
                (event,),
            )
        return None


class ShareCrossing(Rule):
    """Close when the share's crossing rule at ``level`` rises (``config``: the
    ``identification.gangue_share`` section's alarm fields): its reference is the window's
    first ``alarm_reference_s`` from the opening, and estimates without a standard error count
    as exact."""

    name = "share_alarm"

    def __init__(self, level: float, config: ShareConfig) -> None:
        super().__init__()
        self.level = _check("estimate_level", level)
        self.alarm = ShareAlarm.of(self.level, config)

    def feed(self, event: Event) -> Decision | None:
        if isinstance(event, Opened):
            self.alarm.open(event.stamp_s)  # unopened, from the first estimate's interval
        return super().feed(event)

    def _consider(self, event: Event) -> Decision | None:
        if not isinstance(event, ShareEstimate):
            return None
        start = event.stamp_s - event.interval_s
        if self.alarm.observe(start, event.stamp_s, event.share, event.standard_error):
            return self._decide(
                event,
                f"gangue share {event.share:.2f}, {self.level:g} measured from the window's top "
                f"coal at {self.alarm.measured_level():.2f}",
                (event,),
            )
        return None


class Oracle(Rule):
    """Close when the true instantaneous gangue share reaches ``level`` (the upper bound)."""

    name = "oracle"

    def __init__(self, level: float) -> None:
        super().__init__()
        self.level = _check("oracle_level", level)

    def _consider(self, event: Event) -> Decision | None:
        if isinstance(event, TrueShare) and event.share >= self.level:
            return self._decide(event, f"true gangue share {event.share:.2f}", (event,))
        return None


def rule_factories(
    caving: Mapping[str, Any], gangue_share: Mapping[str, Any] | None = None
) -> dict[str, Callable[[], Rule]]:
    """Every rule of a ``caving`` section (checked whole first), by name, as a maker of a fresh
    rule for each window; ``gangue_share``: the ``identification.gangue_share`` section whose
    crossing rule ``share_alarm`` runs (None: its built-in defaults, config/'s values)."""
    c = CAVING.check(caving)
    alarm = ShareConfig.from_params(gangue_share)
    makers: dict[str, Callable[[], Rule]] = {
        "fixed_time": lambda: FixedTime(c["fixed_time_s"]),
        "first_gangue": lambda: FirstGangue(c["first_gangue_min_confidence"]),
    }
    for level in c["share_levels"]:
        rule = ShareOfLastLabels(level, c["last_labels"])
        makers[rule.name] = lambda level=level: ShareOfLastLabels(level, c["last_labels"])
    makers["sprt"] = lambda: Sprt(
        c["sprt_share_low"], c["sprt_share_high"], c["sprt_alpha"], c["sprt_beta"]
    )
    makers["share_estimate"] = lambda: ShareEstimateLevel(c["estimate_level"])
    makers["share_alarm"] = lambda: ShareCrossing(c["estimate_level"], alarm)
    makers["oracle"] = lambda: Oracle(c["oracle_level"])
    return makers
