"""A recording whose sensor clocks are offset (tail_beam_id.timing): one impact cannot show it,
a recording can; its labels that use the delay from onset to camera stamp are then capped."""

from __future__ import annotations

import copy
from dataclasses import replace

import pytest

from tail_beam_id.dataset import settings, support_streams
from tail_beam_id.identifier import StreamIdentifier
from tail_beam_id.replay import replay
from tail_beam_id.runs import foreign_records
from tail_beam_id.timing import OUTSIDE_NAME, UNUSUAL, SensorTiming, TimingConfig

CONFIG = TimingConfig(min_impacts=10, unusual_fraction=0.2, confidence_cap=0.6)


def test_a_recording_is_suspect_only_with_enough_impacts_and_enough_unusual_ones():
    """1 unusual impact in 10 (about what agreeing clocks give: 1 %, and foreign supports' up to
    5 %) is not enough; 2 in 10 are; 9 unusual in 9 are not yet (too few impacts to judge)."""
    timing = SensorTiming(CONFIG)
    for k in range(10):
        timing.add(k == 3)
    assert not timing.suspect
    timing.add(True)
    timing.add(True)
    assert timing.suspect and timing.checked == 12 and timing.unusual == 3
    early = SensorTiming(CONFIG)
    for _ in range(9):
        early.add(True)
    assert not early.suspect


@pytest.fixture(scope="module")
def face(params):
    """The foreign set's first support (seed 41004, shipped sensors), 20 impacts as one stream."""
    (recorded,) = support_streams(params, 1, 20, 41004, setting=settings(params, [1.0], ["shipped"])[0])
    return recorded


def _late_camera(recorded, late_s):
    return replace(recorded, rebounds=[replace(r, stamp_s=r.stamp_s + late_s) for r in recorded.rebounds])


def _labels(params, recorded):
    identifier = StreamIdentifier("statistical", params["identification"], params)
    return identifier, replay(identifier, recorded.pressure, recorded.imu, recorded.rebounds, vibration=recorded.vibration)


def test_agreeing_clocks_are_not_suspect(params, face):
    """As simulated: every impact is checked, few are unusual, no label is capped for timing."""
    identifier, labels = _labels(params, face)
    assert len(labels) == 20 and all(UNUSUAL in label.features for label in labels)
    assert not identifier.timing.suspect
    assert not any(OUTSIDE_NAME in label.outside_training for label in labels)


def test_a_camera_half_a_millisecond_late_makes_the_recording_suspect_and_caps_its_labels(params, face):
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
    late = list(foreign_records(params, copy.deepcopy(_late_camera(face, 5e-4)), 0, 20, ["statistical"], ["self-calibrated"], "late"))
    assert all(r.label is not None and OUTSIDE_NAME in r.label.outside_training and r.label.confidence <= 0.6 for r in late)
    plain = list(foreign_records(params, copy.deepcopy(face), 0, 20, ["statistical"], ["self-calibrated"], "plain"))
    assert not any(OUTSIDE_NAME in r.label.outside_training for r in plain if r.label is not None)
