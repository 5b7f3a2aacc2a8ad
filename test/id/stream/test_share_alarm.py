"""The crossing rule on the gangue share (tail_beam_id.stream.share_alarm): a minimum of
evidence before it rises, hysteresis before it clears."""

from __future__ import annotations

import pytest

from tail_beam_id.stream.share import GangueShare, ShareConfig
from tail_beam_id.stream.share_alarm import ShareAlarm, alarm_states, evidence_above
from tail_beam_sim.errors import InputError

# The rule without a reference: the level itself, 1.5 standard errors, two intervals.
CONFIG = ShareConfig(alarm_z=1.5, alarm_intervals=2, alarm_reference_s=0.0)
SHIPPED = ShareConfig()  # config/'s: a 3 s reference, margin 0.05, 0.5 errors, two intervals


def share(value: float | None, se: float | None = 0.05, end_s: float = 1.0) -> GangueShare:
    method = "none" if value is None else "mixture"
    return GangueShare(end_s - 1.0, end_s, value, 0.0, 1.0, se, 10, 0, 0, method, ())


def flow(values: list[float | None], se: float = 0.05) -> list[GangueShare]:
    """Intervals of 1 s every 0.5 s from the window's opening at 0 s."""
    return [share(v, se, 1.0 + 0.5 * k) for k, v in enumerate(values)]


def test_pure_coal_with_a_stray_interval_never_raises():
    """Pure coal (share 0) with one interval reading 0.5 now and then: one interval is no
    evidence, the alarm never rises."""
    values = [0.0, 0.0, 0.5, 0.0, 0.1, 0.5, 0.0, 0.0] * 8
    assert not any(alarm_states([share(v) for v in values], 0.2, CONFIG))


def test_two_intervals_with_evidence_raise_and_a_fall_below_clears():
    """The alarm rises on the second consecutive interval a standard error above the level,
    stays up while the share stays at or above it (even without the evidence), and clears
    once it falls below."""
    values = [0.1, 0.3, 0.3, 0.22, 0.19, 0.3]
    states = alarm_states([share(v) for v in values], 0.2, CONFIG)
    assert states == [False, False, True, True, False, False]


def test_a_share_within_its_error_of_the_level_is_no_evidence():
    """0.24 with a standard error of 0.05 is not one error above 0.2; with 0.03 it is; an
    interval with no estimate is none and breaks a run."""
    assert not evidence_above(0.24, 0.05, 0.2, 1.0)
    assert evidence_above(0.24, 0.03, 0.2, 1.0)
    assert not evidence_above(None, None, 0.2, 1.0)
    states = alarm_states([share(0.5), share(None, None), share(0.5), share(0.5)], 0.2, CONFIG)
    assert states == [False, False, False, True]


def test_bad_levels_are_refused_by_name():
    """A level outside (0, 1) and a run of no intervals are refused, naming the field."""
    with pytest.raises(InputError, match="alarm level"):
        ShareAlarm(1.5)
    with pytest.raises(InputError, match="alarm_intervals"):
        ShareAlarm(0.2, 1.0, 0)
    with pytest.raises(InputError, match="alarm_intervals"):
        ShareConfig.from_params({"alarm_intervals": 0})


def test_a_support_that_reads_its_top_coal_high_raises_no_alarm_measured_from_it():
    """A support whose pure coal the estimator reads at 0.3 (a bias of its own): without a
    reference every interval is evidence at 1/5 and the alarm rises; measured from the window's
    first 3 s of top coal, the level is 0.3 + 0.2 x 0.7 = 0.44 and it never does."""
    values = [0.3, 0.28, 0.32, 0.3, 0.31, 0.29] + [0.3, 0.33, 0.27, 0.35, 0.3] * 6
    assert any(alarm_states(flow(values), 0.2, CONFIG))
    assert not any(alarm_states(flow(values), 0.2, SHIPPED))


def test_gangue_after_the_reference_raises_it_on_the_measured_level_plus_the_margin():
    """Top coal read at 0.3, then 0.48 (above the measured level 0.44, within its margin: no
    evidence), then 0.55 twice: the alarm rises on the second 0.55 and clears at 0.43."""
    alarm = ShareAlarm.of(0.2, SHIPPED)
    states = [alarm.update(s) for s in flow([0.3] * 5 + [0.48, 0.48, 0.55, 0.55, 0.45, 0.43])]
    assert alarm.measured_level() == pytest.approx(0.44)
    assert states == [False] * 8 + [True, True, False]


def test_the_alarm_cannot_rise_during_the_reference_and_counts_from_the_first_interval():
    """Gangue at once (the window opening on it): the five intervals ending within 3 s of the
    first one's start raise nothing and become the reference, so the level measured from it is
    0.9 + 0.2 x 0.1 = 0.92 and 0.95 is no evidence, 0.98 is; a stream that starts late counts
    its reference from its own first interval."""
    states = alarm_states(flow([0.9] * 5 + [0.95, 0.95, 0.98, 0.98]), 0.2, SHIPPED)
    assert states == [False] * 8 + [True]
    late = [share(v, 0.05, 100.0 + 0.5 * k) for k, v in enumerate([0.0] * 5 + [0.6, 0.6])]
    assert alarm_states(late, 0.2, SHIPPED) == [False] * 6 + [True]


def test_bad_reference_and_margin_are_refused_by_name():
    """A negative reference span or a margin outside [0, 1] is refused, naming the field."""
    with pytest.raises(InputError, match="alarm_reference_s"):
        ShareConfig.from_params({"alarm_reference_s": -1.0})
    with pytest.raises(InputError, match="alarm_margin"):
        ShareConfig.from_params({"alarm_margin": 1.5})
    with pytest.raises(InputError, match="alarm_reference_s"):
        ShareAlarm(0.2, 1.0, 2, -1.0)
