"""The decision's shortcuts leave every label as the straightforward reading gives it: the
samples about the pulse cut out of the buffers before the read-outs
(tail_beam_id.stream.decision.around), the contact fit's first-pass refinement left out where
it can change nothing (tail_beam_id.signals.contact_fit.one_second_ring_down), the pressure
response's peak worked out once per window (BeamModel.pressure_peak). Compared on supports
drawn from the ``structures`` ranges (the evaluation's held-out set; seeds it does not use), at
the shipped layout and with sensors drawn with the support (1-50 kHz accelerometers)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tail_beam_id.signals import contact_fit
from tail_beam_id.signals.features import BeamModel
from tail_beam_id.stream import decision
from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.replay import point_tuples, replay
from tail_beam_id.study.dataset import settings, support_streams
from tail_beam_id.study.runs import true_profile_section

IMPACTS = 8  # impacts per drawn support
SEED = 9176  # no evaluation or training set uses it; its drawn sensors: a 48 kHz accelerometer


def _labels(params, recorded) -> list:
    """Every label of one recorded support stream, identified knowing the support; the compute
    time left out (it is the one field that may differ)."""
    known = {**recorded.params, "calibration": true_profile_section(recorded.params)}
    identifier = StreamIdentifier("statistical", params["identification"], known)
    labels = replay(
        identifier,
        recorded.pressure,
        recorded.imu,
        recorded.rebounds,
        vibration=recorded.vibration,
        points=point_tuples(recorded.points),
    )
    return [dataclasses.replace(label, latency_ms=None) for label in labels]


def _straightforward(monkeypatch) -> None:
    """The decision without its shortcuts: the whole buffers to the read-outs, the first pass
    always refined."""
    monkeypatch.setattr(decision, "around", lambda stamp_s, values, *_: (stamp_s, values))
    monkeypatch.setattr(contact_fit, "one_second_ring_down", lambda *_: False)


@pytest.mark.parametrize("sensors", ["shipped", "drawn"])
def test_the_shortcuts_change_no_label_or_feature(params, monkeypatch, sensors):
    """Each label (stamp, material, confidence, features, signals, what it says of itself) is
    the same with and without the shortcuts, and the refinement was left out for some impact
    (else this would test nothing)."""
    setting = settings(params, [1.0], ["shipped"])[0] if sensors == "shipped" else None
    recorded = next(support_streams(params, 1, IMPACTS, SEED, which="structures", setting=setting))
    best_calls = []
    real_best = contact_fit._best

    def counted(*args):
        best_calls.append(args)
        return real_best(*args)

    monkeypatch.setattr(contact_fit, "_best", counted)
    fast = _labels(params, recorded)
    with_shortcuts = len(best_calls)
    best_calls.clear()
    _straightforward(monkeypatch)
    straightforward = _labels(params, recorded)
    assert len(fast) >= IMPACTS - 1
    assert fast == straightforward
    assert any("contact_duration_s" in label.features for label in fast)
    assert with_shortcuts < len(best_calls)


def test_the_pressure_peak_is_the_responses_largest_value(params):
    """BeamModel.pressure_peak: the largest |response| over 200 points of the window, the same
    on asking again and for each window apart."""
    model = BeamModel.from_params(params)
    for window_s in (0.012, 0.006, 0.012):
        response = model.pressure_response(np.linspace(0.0, window_s, 200))
        assert model.pressure_peak(window_s) == float(np.max(np.abs(response)))
