"""The crossing rule on the gangue share (tail_beam_id.stream.share_alarm): a minimum of
evidence before it rises, hysteresis before it clears."""

from __future__ import annotations

import pytest

from tail_beam_id.stream.share import GangueShare, ShareConfig
from tail_beam_id.stream.share_alarm import ShareAlarm, alarm_states, evidence_above
from tail_beam_sim.errors import InputError

CONFIG = ShareConfig()  # alarm_z 1.5, alarm_intervals 2


def share(value: float | None, se: float | None = 0.05, end_s: float = 1.0) -> GangueShare:
    method = "none" if value is None else "mixture"
    return GangueShare(end_s - 1.0, end_s, value, 0.0, 1.0, se, 10, 0, 0, method, ())


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
    assert not evidence_above(share(0.24, 0.05), 0.2, 1.0)
    assert evidence_above(share(0.24, 0.03), 0.2, 1.0)
    assert not evidence_above(share(None, None), 0.2, 1.0)
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
