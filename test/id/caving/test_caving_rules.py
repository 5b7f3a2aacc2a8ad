"""The caving window's closing rules on hand-made label sequences: when each closes, on what it
rests, a wrong confident label, a late label, and parameters out of range."""

from __future__ import annotations

import math

import pytest

from tail_beam_id.caving.events import (
    LabelEvent,
    Opened,
    ShareEstimate,
    Tick,
    TrueShare,
)
from tail_beam_id.caving.rules import (
    FirstGangue,
    FixedTime,
    Oracle,
    ShareCrossing,
    ShareEstimateLevel,
    ShareOfLastLabels,
    Sprt,
    rule_factories,
)
from tail_beam_id.stream.label import Label
from tail_beam_id.stream.share import ShareConfig
from tail_beam_sim.config import default_config_dir, read_parameter_file
from tail_beam_sim.errors import InputError


def coal(stamp_s: float, confidence: float = 0.9, arrival_s: float | None = None) -> LabelEvent:
    return LabelEvent(stamp_s, "coal", confidence, arrival_s)


def gangue(stamp_s: float, confidence: float = 0.9, arrival_s: float | None = None) -> LabelEvent:
    return LabelEvent(stamp_s, "gangue", confidence, arrival_s)


def first_decision(rule, events):
    """The first decision ``rule`` gives on ``events``, and how many events it took."""
    for n, event in enumerate(events, 1):
        decision = rule.feed(event)
        if decision is not None:
            return decision, n
    return None, len(events)


def sprt() -> Sprt:
    return Sprt(share_low=0.05, share_high=0.3, alpha=0.01, beta=0.1)


def test_first_gangue_closes_on_the_first_gangue_label_when_it_is_known():
    """The decision is the first gangue label's, stamped when the label arrived (its impact
    stamp plus the identifier's latency), and rests on that label."""
    events = [Opened(0.0), coal(1.0), coal(1.5), gangue(2.0, 0.6, arrival_s=2.3), gangue(2.5)]
    decision, n = first_decision(FirstGangue(), events)
    assert n == 4 and decision.stamp_s == 2.3 and decision.rule == "first_gangue"
    assert decision.evidence == (events[3],)
    decision, n = first_decision(FirstGangue(min_confidence=0.8), events)
    assert n == 5 and decision.evidence == (events[4],)


def test_a_rule_decides_once_per_window():
    """After its decision a rule answers None to whatever follows."""
    rule = FirstGangue()
    assert rule.feed(gangue(1.0)) is not None
    assert rule.feed(gangue(2.0)) is None


def test_a_wrong_confident_label_closes_first_gangue_but_not_the_sprt_or_the_share_rules():
    """A coal stream with one gangue label of confidence 0.99 (a wrong label): first gangue
    closes on it; the SPRT and the 1/3-of-12 rule keep drawing, and close only once real
    gangue labels come."""
    stream = [Opened(0.0)] + [coal(0.1 * k) for k in range(1, 11)]
    stream += [gangue(1.1, 0.99)] + [coal(1.1 + 0.1 * k) for k in range(1, 21)]
    wrong = stream[11]
    decision, _ = first_decision(FirstGangue(), stream)
    assert decision.evidence == (wrong,)
    for rule in (sprt(), ShareOfLastLabels(1 / 3, 12)):
        assert first_decision(rule, stream)[0] is None
        onset = [gangue(3.2 + 0.1 * k) for k in range(12)]
        decision, n = first_decision(rule, onset)
        assert decision is not None and decision.evidence[-1] is onset[n - 1]


def test_the_sprt_closes_after_the_number_of_labels_walds_bounds_give():
    """From a fresh start, n gangue labels of confidence c close the test when n log(L1/L0)
    first reaches log((1 - beta) / alpha), L = p c + (1 - p)(1 - c) for p = 0.3 and 0.05."""
    for c in (0.7, 0.9, 0.99):
        step = math.log((0.3 * c + 0.7 * (1 - c)) / (0.05 * c + 0.95 * (1 - c)))
        expected = math.ceil(math.log(0.9 / 0.01) / step)
        decision, n = first_decision(sprt(), [gangue(0.1 * k, c) for k in range(1, 40)])
        assert n == expected and len(decision.evidence) == expected


def test_the_sprt_starts_again_after_a_coal_stretch():
    """A long coal stretch does not bank evidence against later gangue: after it the test
    closes as soon as after a fresh start (the stretch was taken as coal and forgotten)."""
    rule = sprt()
    long_coal = [coal(0.1 * k, 0.95) for k in range(1, 200)]
    assert first_decision(rule, long_coal)[0] is None
    assert rule.llr > rule.lower
    onset = [gangue(20.0 + 0.1 * k, 0.9) for k in range(40)]
    fresh = first_decision(sprt(), onset)[1]
    assert first_decision(rule, onset)[1] <= fresh + 1


def test_a_late_label_counts_in_impact_stamp_order():
    """K=3 at 2/3: coal at 1, gangue at 2, coal at 4 do not close; the gangue label of the
    impact at 3, arriving late at 5, makes the last three by stamp 2 gangue of 3: the decision
    is stamped 5 and rests on the impacts at 2, 3, 4."""
    rule = ShareOfLastLabels(2 / 3, 3)
    late = gangue(3.0, arrival_s=5.0)
    events = [Opened(0.0), coal(1.0), gangue(2.0), coal(4.0), late]
    decision, n = first_decision(rule, events)
    assert n == 5 and decision.stamp_s == 5.0
    assert [e.stamp_s for e in decision.evidence] == [2.0, 3.0, 4.0]


def test_a_late_label_of_the_previous_window_is_left_out():
    """A gangue label whose impact came before this window opened does not close it."""
    rule = FirstGangue()
    assert rule.feed(Opened(10.0)) is None
    assert rule.feed(gangue(9.5, 0.99, arrival_s=10.2)) is None
    assert rule.feed(gangue(10.5)) is not None


def test_the_share_rules_need_their_k_labels_and_reach_their_level():
    """1/5 of 10: one gangue label among ten is not enough, two are; none before ten labels."""
    rule = ShareOfLastLabels(0.2, 10)
    events = [gangue(0.1), gangue(0.2)] + [coal(0.2 + 0.1 * k) for k in range(1, 8)]
    assert first_decision(rule, events)[0] is None  # nine labels
    decision = rule.feed(coal(1.1))
    assert decision is not None and len(decision.evidence) == 10
    rule = ShareOfLastLabels(0.2, 10)
    events = [gangue(0.1)] + [coal(0.1 + 0.1 * k) for k in range(1, 20)]
    assert first_decision(rule, events)[0] is None


def test_fixed_time_closes_at_its_time_after_the_opening():
    """Opened at 100 s with 60 s to draw: a tick at 159.9 s does not close, one at 160.2 s
    does, and the decision is stamped 160 s."""
    rule = FixedTime(60.0)
    assert rule.feed(Opened(100.0)) is None
    assert rule.feed(Tick(159.9)) is None
    decision = rule.feed(Tick(160.2))
    assert decision is not None and decision.stamp_s == 160.0


def test_the_estimate_rule_waits_for_the_lower_bound():
    """A share of 0.30 in [0.15, 0.45] does not cross 0.2; 0.35 in [0.22, 0.50] does."""
    rule = ShareEstimateLevel(0.2)
    assert rule.feed(ShareEstimate(1.0, 0.30, 0.15, 0.45, 1.0)) is None
    decision = rule.feed(ShareEstimate(2.0, 0.35, 0.22, 0.50, 1.0, arrival_s=2.4))
    assert decision is not None and decision.stamp_s == 2.4


def estimates(opened_s: float, shares: list[float], se: float = 0.05) -> list[ShareEstimate]:
    """1 s estimates every 0.5 s, the first ending 1 s after ``opened_s``."""
    return [
        ShareEstimate(
            opened_s + 1.0 + 0.5 * k,
            v,
            max(v - 0.1, 0.0),
            min(v + 0.1, 1.0),
            1.0,
            standard_error=se,
        )
        for k, v in enumerate(shares)
    ]


def test_the_crossing_rule_measures_its_level_from_the_windows_opening():
    """A window opened at 100 s whose top coal reads 0.3 (a support's own bias): its first 3 s
    of estimates are the reference, 0.2 measured from it is 0.44 (+ 0.05 margin), so 0.45 does
    not close it and the second of two estimates at 0.55 does, naming the measured level."""
    rule = ShareCrossing(0.2, ShareConfig())
    rule.feed(Opened(100.0))
    events = estimates(100.0, [0.3] * 5 + [0.45, 0.45, 0.55, 0.55])
    decisions = [rule.feed(e) for e in events]
    assert decisions[:-1] == [None] * 8
    assert decisions[-1] is not None and decisions[-1].stamp_s == events[-1].stamp_s
    assert "0.44" in decisions[-1].reason
    # Without the window's opening the reference starts at the first estimate's interval.
    late = ShareCrossing(0.2, ShareConfig())
    assert all(late.feed(e) is None for e in estimates(100.0, [0.3] * 5 + [0.45] * 4))


def test_the_oracle_closes_on_the_true_share_only():
    """Labels do not move the oracle; the first true share at its level does."""
    rule = Oracle(0.3)
    assert rule.feed(gangue(1.0, 1.0)) is None
    assert rule.feed(TrueShare(1.0, 0.29)) is None
    assert rule.feed(TrueShare(1.2, 0.31)).stamp_s == 1.2


def test_rule_parameters_out_of_range_are_named():
    """Each refusal names the caving field and its range."""
    with pytest.raises(
        InputError, match=r"caving\.fixed_time_s = -1\.0: must be in \(0, 10000\] s"
    ):
        FixedTime(-1.0)
    with pytest.raises(InputError, match=r"caving\.last_labels = 0: must be an integer in"):
        ShareOfLastLabels(0.2, 0)
    with pytest.raises(InputError, match=r"caving\.share_levels\[0\] = 1\.5"):
        ShareOfLastLabels(1.5, 10)
    with pytest.raises(InputError, match=r"caving\.sprt_share_high = 0\.05: must be > caving"):
        Sprt(0.05, 0.05, 0.01, 0.1)
    with pytest.raises(InputError, match=r"caving\.sprt_alpha = 0\.6"):
        Sprt(0.05, 0.3, 0.6, 0.1)
    with pytest.raises(InputError, match=r"caving\.oracle_level = 0"):
        Oracle(0.0)
    with pytest.raises(InputError, match=r"label = 'rock'"):
        LabelEvent(1.0, "rock", 0.9)
    with pytest.raises(InputError, match=r"gangue_share\.low = -0\.1"):
        ShareEstimate(1.0, 0.1, -0.1, 0.2)
    # A negative or undefined standard error would count as evidence it is not.
    for bad in (-0.1, math.nan):
        with pytest.raises(InputError, match=r"gangue_share\.standard_error"):
            ShareEstimate(1.0, 0.1, 0.0, 0.2, standard_error=bad)


def test_the_shipped_rules_and_an_identifier_label():
    """config/face.yaml makes the eight rules; an identifier's Label becomes an event."""
    caving = read_parameter_file(default_config_dir() / "face.yaml")["caving"]
    assert list(rule_factories(caving)) == [
        "fixed_time",
        "first_gangue",
        "share_0.333",
        "share_0.2",
        "sprt",
        "share_estimate",
        "share_alarm",
        "oracle",
    ]
    label = Label(12.5, "gangue", 0.8, "statistical")
    event = LabelEvent.of(label, arrival_s=12.7)
    assert (event.stamp_s, event.gangue, event.confidence, event.known_s) == (
        12.5,
        True,
        0.8,
        12.7,
    )
