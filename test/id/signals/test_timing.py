"""A recording whose sensor clocks are offset (tail_beam_id.signals.timing): one impact cannot show
it, a recording can; its labels that use the delay from onset to camera stamp are then decided
without the delay and capped."""

from __future__ import annotations

import copy
from dataclasses import replace

import pytest

from tail_beam_id.signals.timing import (
    DELAY_UNTRUSTED,
    OUTSIDE_NAME,
    UNUSUAL,
    SensorTiming,
    TimingConfig,
    judge,
)
from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.replay import replay
from tail_beam_id.study.dataset import settings, support_streams
from tail_beam_id.study.runs import foreign_records
from tail_beam_sim.errors import InputError

CONFIG = TimingConfig(min_impacts=10, agreeing_rate=0.03, false_alarm=1e-3, confidence_cap=0.6)


def test_a_recording_is_suspect_only_with_enough_impacts_and_enough_unusual_ones():
    """2 unusual impacts in 10 are what agreeing clocks on a support unlike training's give now
    and then (a foreign set's base rate is up to 2.4 %: P(>= 2 of 10) = 3.5 % at the 3 % the
    rule allows) and are not enough; 4 in 12 are (P = 0.0003 < 0.001); 9 unusual in 9 are not
    yet (too few impacts to judge); and once suspect, a recording stays so."""
    timing = SensorTiming(CONFIG)
    for k in range(10):
        timing.add(k in (3, 7))
    assert not timing.suspect and timing.unusual == 2
    timing.add(True)
    assert not timing.suspect  # 3 of 11: P = 0.004
    timing.add(True)
    assert timing.suspect and timing.checked == 12 and timing.unusual == 4  # P = 0.0003
    for _ in range(30):
        timing.add(False)
    assert timing.suspect
    early = SensorTiming(CONFIG)
    for _ in range(9):
        early.add(True)
    assert not early.suspect


@pytest.mark.parametrize(("checked", "fewest"), [(10, 4), (20, 5), (40, 7), (100, 10)])
def test_the_unusual_count_a_recording_needs_follows_the_binomial_tail(checked, fewest):
    """The fewest unusual delays that make a recording of ``checked`` impacts suspect are the
    smallest k with P(X >= k) < 0.001 for X ~ Binomial(checked, 0.03), computed by hand:
    P(X >= 4 | 10) = 1.5e-4 but P(X >= 3 | 10) = 2.8e-3; P(X >= 5 | 20) = 2.6e-4, P(>= 4) =
    2.7e-3."""
    assert not judge(checked, fewest - 1, CONFIG)
    assert judge(checked, fewest, CONFIG)


def test_a_bad_timing_section_is_refused_by_name():
    """A rate of 0 or above 0.5, or a false-alarm rate of 0, names its field."""
    for field, value in (("agreeing_rate", 0.0), ("agreeing_rate", 0.7), ("false_alarm", 0.0)):
        with pytest.raises(InputError, match=f"identification.sensor_timing.{field}"):
            TimingConfig.from_params({field: value})


@pytest.mark.parametrize("command", ["identify", "calibrate"])
def test_identify_and_calibrate_refuse_a_bad_timing_section_before_they_read_the_bag(
    tmp_path, capsys, command
):
    """tail-beam identify and calibrate name a bad identification.sensor_timing value before
    they read and self-calibrate the bag (they said so only after that pass): the bag here does
    not exist, so an error naming the field can only come from a check made first."""
    from tail_beam_sim.cli import main

    config = tmp_path / "bad.yaml"
    config.write_text(
        "/**:\n  ros__parameters:\n    identification:\n      sensor_timing:\n        "
        "agreeing_rate: 0.7\n"
    )
    assert main([command, str(tmp_path / "no_such_bag"), "--config", str(config)]) == 2
    error = capsys.readouterr().err
    assert "identification.sensor_timing.agreeing_rate" in error and "no_such_bag" not in error


@pytest.fixture(scope="module")
def face(params):
    """The foreign set's first support (seed 41004, shipped sensors), 20 impacts as one stream."""
    (recorded,) = support_streams(
        params, 1, 20, 41004, setting=settings(params, [1.0], ["shipped"])[0]
    )
    return recorded


def _late_camera(recorded, late_s):
    return replace(
        recorded, rebounds=[replace(r, stamp_s=r.stamp_s + late_s) for r in recorded.rebounds]
    )


def _labels(params, recorded):
    identifier = StreamIdentifier("statistical", params["identification"], params)
    return identifier, replay(
        identifier,
        recorded.pressure,
        recorded.imu,
        recorded.rebounds,
        vibration=recorded.vibration,
    )


def test_agreeing_clocks_are_not_suspect(params, face):
    """As simulated: every impact is checked, few are unusual, no label is capped for timing."""
    identifier, labels = _labels(params, face)
    assert len(labels) == 20 and all(UNUSUAL in label.features for label in labels)
    assert not identifier.timing.suspect
    assert not any(OUTSIDE_NAME in label.outside_training for label in labels)
    assert not any(DELAY_UNTRUSTED in label.features for label in labels)


def test_a_camera_half_a_millisecond_late_makes_the_recording_suspect_and_caps_its_labels(
    params, face
):
    """The camera's stamps 0.5 ms late: from the impact at which enough unusual delays have
    come, every label that uses the delay is capped and says sensor_timing; those before are
    not (a live node cannot know the future), and no label is otherwise changed in its material."""
    identifier, labels = _labels(params, _late_camera(face, 5e-4))
    assert identifier.timing.suspect
    flagged = [OUTSIDE_NAME in label.outside_training for label in labels]
    first = flagged.index(True)
    assert first >= CONFIG.min_impacts - 1 and all(flagged[first:])
    assert all(label.confidence <= 0.6 for label in labels[first:])
    _, plain = _labels(params, face)
    assert len(plain) == len(labels)


def test_self_calibration_finds_it_first_and_caps_every_label(params, face):
    """Identified as `tail-beam identify` does (a self-calibration pass first), the pass's count
    goes into the profile and the identifier caps from the first impact on; on the recording as
    simulated nothing is capped."""
    late = list(
        foreign_records(
            params,
            copy.deepcopy(_late_camera(face, 5e-4)),
            0,
            20,
            ["statistical"],
            ["self-calibrated"],
            "late",
        )
    )
    assert all(
        r.label is not None
        and OUTSIDE_NAME in r.label.outside_training
        and r.label.confidence <= 0.6
        for r in late
    )
    plain = list(
        foreign_records(
            params, copy.deepcopy(face), 0, 20, ["statistical"], ["self-calibrated"], "plain"
        )
    )
    assert not any(OUTSIDE_NAME in r.label.outside_training for r in plain if r.label is not None)


def _right(records) -> int:
    return sum(r.label is not None and (r.label.material == "coal") == r.is_coal for r in records)


def test_a_suspect_recording_is_decided_without_the_delay_and_keeps_its_accuracy(params, face):
    """An offset shifts every delay one way, so a label read from it goes one way too; the other
    signals still tell the materials apart. With the camera 0.5 ms late, every label of a
    self-calibrated pass says delay_untrusted, its probability does not move when the delay is
    moved by another 0.5 ms (the twin without the delay decided it), and it is right about as
    often as on the recording as simulated (within 2 of 20)."""
    late = list(
        foreign_records(
            params,
            copy.deepcopy(_late_camera(face, 5e-4)),
            0,
            20,
            ["statistical"],
            ["self-calibrated"],
            "late",
        )
    )
    plain = list(
        foreign_records(
            params, copy.deepcopy(face), 0, 20, ["statistical"], ["self-calibrated"], "plain"
        )
    )
    assert all(r.label is not None and r.label.features.get(DELAY_UNTRUSTED) == 1.0 for r in late)
    assert all(UNUSUAL in r.label.features for r in late)  # the check itself still counted
    assert _right(late) >= _right(plain) - 2
    identifier = StreamIdentifier("statistical", params["identification"], params)
    for record in late:
        features = dict(record.label.features)
        moved = {**features, "rebound_delay_s": features["rebound_delay_s"] + 5e-4}
        assert identifier.method.decide(moved).confidence == pytest.approx(
            identifier.method.decide(features).confidence, abs=1e-12
        )


def _with_clean_gap(params, gap_s):
    changed = copy.deepcopy(params)
    changed["identification"]["sensor_timing"]["clean_gap_s"] = gap_s
    return changed


def test_only_impacts_clear_of_others_are_evidence_on_the_clocks(params, face):
    """At the shipped clean_gap_s (0.25 s) every impact of the stream (0.3 s apart or more) is
    checked; with the gap as wide as the identifier allows (0.4 s) only those with none that
    long before, as the impacts' spacing says (in a dense flow, onsets and delays read in
    another impact's response are unusual more often whatever the clocks)."""
    identifier, labels = _labels(params, face)
    assert identifier.timing.checked == len(labels) == 20
    onsets = sorted(label.impact_stamp_s for label in labels)
    alone = [t for t in onsets if not any(0.0 < t - u < 0.4 for u in onsets)]
    assert 0 < len(alone) < 20
    identifier, labels = _labels(_with_clean_gap(params, 0.4), face)
    assert identifier.timing.checked == len(alone)


def test_a_clean_gap_wider_than_the_onsets_kept_is_refused_by_name(params):
    """The identifier keeps decided onsets 0.448 s (at config/'s values: 4 x the pressure's
    0.1 s background and 12 ms window): a longer gap could not be judged alike live and
    offline."""
    from tail_beam_id.stream.config import IdentifierConfig

    with pytest.raises(InputError, match=r"sensor_timing.clean_gap_s = 0.5: must be <= 0.448 s"):
        IdentifierConfig.from_params(_with_clean_gap(params, 0.5)["identification"])


def test_self_calibration_counts_the_isolated_labels_only():
    """The calibration pass's count (its profile's delay_checked_impacts) takes the labels with
    none within the gap before nor the overlap window after: the pair 0.1 s apart goes with the
    gap after as long as the one before, only its second with a short one after."""
    from tail_beam_id.calibration.offline import isolated
    from tail_beam_id.stream.label import Label

    labels = [
        Label(impact_stamp_s=t, material="coal", confidence=0.9, method="statistical")
        for t in (1.0, 1.1, 2.0, 3.0)
    ]
    assert [label.impact_stamp_s for label in isolated(labels, 0.25, 0.25)] == [2.0, 3.0]
    assert [label.impact_stamp_s for label in isolated(labels, 0.25, 0.01)] == [1.0, 2.0, 3.0]
    assert [label.impact_stamp_s for label in isolated(labels, 0.05, 0.01)] == [
        1.0,
        1.1,
        2.0,
        3.0,
    ]
