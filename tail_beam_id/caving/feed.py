"""The topics a window controller hears, as closing-rule events, and a rule fed offline.

One reading for the live controller (``caving_node``) and for a recorded bag's offline labels
(``tail-beam identify``), so that both feed a rule the same events:

- a ``label`` (:class:`~tail_beam_id.stream.label.Label`) is a
  :class:`~tail_beam_id.caving.events.LabelEvent` known ``data_latency_ms`` after its impact
  stamp (the stamp time the identifier's decision needed its data up to; wall-clock compute
  time is left out, so that live and offline stamps agree); a revision of an impact already
  labelled is no new lump and gives no event;
- a ``gangue_share`` estimate is a :class:`~tail_beam_id.caving.events.ShareEstimate` known at
  its interval's end; one with no share (nothing struck) gives no event;
- a ``gangue_share_truth`` object is a :class:`~tail_beam_id.caving.events.TrueShare` of its
  share by mass at its interval's end; one with no share gives no event.

A decision goes out as one JSON object (:func:`decision_json`, docs/interface.md).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from typing import Any

from tail_beam_id.caving.events import (
    Decision,
    Event,
    LabelEvent,
    Opened,
    ShareEstimate,
    Tick,
    TrueShare,
)
from tail_beam_id.caving.rules import Rule
from tail_beam_id.stream.label import Label
from tail_beam_id.stream.share import GangueShare
from tail_beam_sim.errors import InputError

__all__ = [
    "decision_json",
    "event_dict",
    "label_event",
    "offline_decision",
    "share_event",
    "truth_event",
]


def label_event(label: Label) -> LabelEvent | None:
    """The event of one ``label`` message; None for a revision (its impact already counted)."""
    if label.revises is not None:
        return None
    latency_s = (label.data_latency_ms or 0.0) * 1e-3
    if not (math.isfinite(latency_s) and latency_s >= 0.0):
        raise InputError("label.data_latency_ms", label.data_latency_ms, "must be >= 0 ms")
    return LabelEvent(
        label.impact_stamp_s, label.material, label.confidence, label.impact_stamp_s + latency_s
    )


def share_event(share: GangueShare) -> ShareEstimate | None:
    """The event of one ``gangue_share`` estimate; None when it holds no share."""
    if share.share is None:
        return None
    return ShareEstimate(
        share.end_stamp_s,
        float(share.share),
        float(share.low),
        float(share.high),
        share.end_stamp_s - share.start_stamp_s,
        standard_error=share.standard_error,
    )


def _finite(obj: Mapping[str, Any], key: str) -> float:
    value = obj.get(key)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputError(f"gangue_share_truth.{key}", value, "must be a finite number")
    return float(value)


def truth_event(obj: object) -> TrueShare | None:
    """The event of one ``gangue_share_truth`` object (a dict, or its JSON text); None when the
    interval holds no lump. InputError naming the field for anything else."""
    if isinstance(obj, str | bytes):
        try:
            obj = json.loads(obj)
        except ValueError as exc:
            raise InputError(
                "gangue_share_truth", str(obj)[:60], f"must be JSON ({exc})"
            ) from None
    if not isinstance(obj, Mapping):
        raise InputError("gangue_share_truth", str(obj)[:60], "must be a JSON object")
    end_s = _finite(obj, "end_stamp_s")
    if obj.get("share_by_mass") is None:
        return None
    share = _finite(obj, "share_by_mass")
    if not 0.0 <= share <= 1.0:
        raise InputError("gangue_share_truth.share_by_mass", share, "must be in [0, 1] or null")
    return TrueShare(end_s, share)


def event_dict(event: Event) -> dict[str, Any]:
    """One event as the ``caving_decision`` JSON lists it (``kind`` and its fields)."""
    if isinstance(event, LabelEvent):
        return {
            "kind": "label",
            "impact_stamp_s": event.stamp_s,
            "label": event.material,
            "confidence": event.confidence,
            "known_s": event.known_s,
        }
    if isinstance(event, ShareEstimate):
        return {
            "kind": "gangue_share",
            "end_stamp_s": event.stamp_s,
            "share": event.share,
            "low": event.low,
            "high": event.high,
            "interval_s": event.interval_s,
        }
    if isinstance(event, TrueShare):
        return {"kind": "gangue_share_truth", "end_stamp_s": event.stamp_s, "share": event.share}
    kind = "opened" if isinstance(event, Opened) else "tick"
    return {"kind": kind, "stamp_s": event.stamp_s}


def decision_json(
    decision: Decision, support: str, opened_s: float, window: int, closed_by: str = "rule"
) -> str:
    """The ``caving_decision`` message of one decision (docs/interface.md)."""
    return json.dumps(
        {
            "support": support,
            "window": window,
            "stamp_s": decision.stamp_s,
            "opened_stamp_s": opened_s,
            "rule": decision.rule,
            "closed_by": closed_by,
            "reason": decision.reason,
            "evidence": [event_dict(e) for e in decision.evidence],
        }
    )


def offline_decision(
    rule: Rule,
    opened_s: float,
    labels: Iterable[Label] = (),
    shares: Iterable[GangueShare] = (),
    truths: Iterable[Mapping[str, Any]] = (),
    end_s: float = math.inf,
) -> Decision | None:
    """The decision ``rule`` gives a window opened at ``opened_s`` when fed a recording's labels,
    gangue-share estimates and share truths, each topic in its own order (as published), then a
    tick at ``end_s`` (s). Every rule reads one kind of event (``fixed_time`` only the clock),
    so how the topics interleave does not change its decision."""
    rule.feed(Opened(opened_s))
    events: list[Event | None] = [label_event(x) for x in labels]
    events += [share_event(x) for x in shares]
    events += [truth_event(x) for x in truths]
    if math.isfinite(end_s):
        events.append(Tick(end_s))
    for event in events:
        if event is None:
            continue
        decision = rule.feed(event)
        if decision is not None:
            return decision
    return None
