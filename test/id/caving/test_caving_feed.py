"""The controller's reading of its topics as closing-rule events, and a rule fed offline."""

from __future__ import annotations

import json
import math

import pytest

from tail_beam_id.caving.events import LabelEvent
from tail_beam_id.caving.feed import (
    decision_json,
    label_event,
    offline_decision,
    share_event,
    truth_event,
)
from tail_beam_id.caving.rules import FirstGangue, FixedTime, Oracle, ShareEstimateLevel
from tail_beam_id.stream.label import Label
from tail_beam_id.stream.share import GangueShare
from tail_beam_sim.errors import InputError


def label(stamp_s: float, material: str, confidence: float = 0.9, **kw) -> Label:
    return Label(stamp_s, material, confidence, "threshold", **kw)


def share(end_s: float, value: float | None, low: float, high: float) -> GangueShare:
    return GangueShare(end_s - 1.0, end_s, value, low, high, None, 5, 1, 0, "labels", ())


def test_a_label_is_known_its_data_latency_after_its_impact_and_a_revision_is_no_event():
    """A label's event is known at impact stamp + data_latency_ms (stamp time, not compute
    time); a revision of an impact already labelled gives none."""
    event = label_event(label(2.0, "gangue", data_latency_ms=12.0, latency_ms=900.0))
    assert event == LabelEvent(2.0, "gangue", 0.9, 2.012)
    assert label_event(label(2.0, "coal", revises=2.0)) is None
    assert label_event(label(3.0, "coal")).known_s == 3.0


def test_shares_and_truths_without_a_share_give_no_event_and_bad_ones_name_the_field():
    """An interval with nothing in it gives no event; a truth whose share or stamp is not a
    number in range is refused naming gangue_share_truth.<field>."""
    assert share_event(share(4.0, None, 0.0, 1.0)) is None
    event = share_event(share(4.0, 0.4, 0.2, 0.6))
    assert (event.stamp_s, event.low, event.interval_s) == (4.0, 0.2, 1.0)
    assert truth_event({"end_stamp_s": 3.0, "share_by_mass": None}) is None
    assert truth_event(json.dumps({"end_stamp_s": 3.0, "share_by_mass": 0.25})).share == 0.25
    for bad, field in (
        ({"end_stamp_s": 3.0, "share_by_mass": 1.5}, "share_by_mass"),
        ({"end_stamp_s": "x", "share_by_mass": 0.5}, "end_stamp_s"),
        ({"share_by_mass": 0.5}, "end_stamp_s"),
        ({"end_stamp_s": math.nan, "share_by_mass": 0.5}, "end_stamp_s"),
        ("[1]", "gangue_share_truth"),
        ("{", "gangue_share_truth"),
    ):
        with pytest.raises(InputError, match=field):
            truth_event(bad)


def test_offline_decision_reads_each_topic_and_leaves_out_what_came_before_the_opening():
    """first_gangue closes on the first gangue label after the opening, at the time it was
    known; the share rule on the first estimate whose lower bound reaches its level; the oracle
    on the truth; fixed_time at opening + its time even when the last event is later."""
    labels = [
        label(0.5, "gangue", data_latency_ms=5.0),  # before the window opened
        label(1.5, "coal"),
        label(2.5, "gangue", 0.7, data_latency_ms=20.0),
        label(3.0, "gangue", 0.95),
    ]
    shares = [share(2.0, 0.3, 0.1, 0.5), share(3.0, 0.5, 0.3, 0.7)]
    truths = [
        {"end_stamp_s": 2.0, "share_by_mass": 0.1},
        {"end_stamp_s": 3.0, "share_by_mass": 0.4},
    ]
    decision = offline_decision(FirstGangue(0.0), 1.0, labels, shares, truths)
    assert (decision.stamp_s, decision.rule) == (2.52, "first_gangue")
    assert offline_decision(FirstGangue(0.9), 1.0, labels).stamp_s == 3.0
    assert offline_decision(ShareEstimateLevel(0.2), 1.0, labels, shares, truths).stamp_s == 3.0
    assert offline_decision(Oracle(0.3), 1.0, labels, shares, truths).stamp_s == 3.0
    assert offline_decision(FixedTime(5.0), 1.0, labels, end_s=9.0).stamp_s == 6.0
    assert offline_decision(FixedTime(5.0), 1.0, labels, end_s=5.5) is None


def test_the_decision_message_lists_what_the_rule_rested_on():
    """caving_decision JSON: support, window, stamps, rule, reason and each event's fields."""
    rule = FirstGangue(0.0)
    decision = offline_decision(rule, 0.0, [label(1.0, "gangue", 0.8)], end_s=2.0)
    obj = json.loads(decision_json(decision, "/support_002", 0.0, 1))
    assert obj["support"] == "/support_002" and obj["window"] == 1
    assert obj["stamp_s"] == 1.0 and obj["rule"] == "first_gangue" and obj["closed_by"] == "rule"
    assert obj["evidence"] == [
        {
            "kind": "label",
            "impact_stamp_s": 1.0,
            "label": "gangue",
            "confidence": 0.8,
            "known_s": 1.0,
        }
    ]
