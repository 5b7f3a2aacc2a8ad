"""Self-calibration reads the support's contact hysteresis from its recording: a
support whose law under-damps low restitutions (Hunt-Crossley) and one that does not (Flores),
each recording the paper scene, are told apart without labels, and the labels use it."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from tail_beam_id.calibration.offline import calibrate, with_profile
from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.label import match, match_tolerance_s
from tail_beam_id.stream.replay import replay
from tail_beam_id.study.dataset import settings, support_streams

IMPACTS = 16


def _recording(params, law: str, seed: int):
    """One foreign support of ``law`` (its other values drawn), the shipped sensors, recording
    IMPACTS impacts of the paper scene."""
    varied = copy.deepcopy(params)
    varied["identification"]["evaluation"]["supports"]["foreign"]["contact_models"] = [law]
    shipped = settings(varied, [1.0], ["shipped"])[0]
    (recorded,) = support_streams(varied, 1, IMPACTS, seed=seed, setting=shipped, scene="paper")
    return recorded


@pytest.fixture(scope="module")
def recordings(params):
    return {
        law: _recording(params, law, seed)
        for law, seed in (("hunt_crossley", 881), ("flores", 882))
    }


def _identify(params, recorded):
    return lambda model_params: replay(
        StreamIdentifier("statistical", params["identification"], model_params),
        recorded.pressure,
        recorded.imu,
        recorded.rebounds,
        vibration=recorded.vibration,
    )


def _profile(params, recorded):
    v = recorded.vibration
    return calibrate(
        params,
        (recorded.pressure.stamp_s, recorded.pressure.pressure_pa),
        (recorded.imu.stamp_s, recorded.imu.linear_acceleration_mps2[:, 2]),
        _identify(params, recorded),
        (v.sample_stamps_s(), v.accel_mps2) if v is not None else None,
        [r.stamp_s for r in recorded.rebounds],
    )


@pytest.fixture(scope="module")
def profiles(params, recordings):
    return {law: _profile(params, recorded) for law, recorded in recordings.items()}


def _latent_mass(weights, edges, below: bool, at: float) -> float:
    """The weight of the bins lying wholly below (or wholly at or above) the latent ``at``."""
    bounds = [-np.inf, *edges, np.inf]
    return sum(
        w for k, w in enumerate(weights) if (bounds[k + 1] <= at if below else bounds[k] >= at)
    )


def test_the_supports_hysteresis_is_read_from_its_recording(params, profiles):
    """Hunt-Crossley's chi at e = 0.35 is 0.975 against the calibrated law's 2.5 (latent about
    -0.95) and Flores' is about the calibrated one's (+0.1): the Hunt-Crossley support's weight
    lies on bins below -0.5, the Flores support's on bins from -0.5 up, each by 0.9 or more."""
    from tail_beam_id.methods import load_model

    edges = load_model("statistical")["hysteresis"]["bin_edges"]
    hc, fl = profiles["hunt_crossley"], profiles["flores"]
    assert hc.hysteresis_weights is not None and fl.hysteresis_weights is not None
    assert hc.hysteresis_impacts >= 8 and fl.hysteresis_impacts >= 8
    assert _latent_mass(hc.hysteresis_weights, edges, True, -0.5) >= 0.9, hc.hysteresis_weights
    assert _latent_mass(fl.hysteresis_weights, edges, False, -0.5) >= 0.9, fl.hysteresis_weights
    # The profile file carries them, for id_node and tail-beam identify --config.
    section = hc.parameters()["/**"]["ros__parameters"]["calibration"]
    assert (
        section["hysteresis_weights"] == hc.hysteresis_weights
        and section["hysteresis_bin_edges"] == edges
    )


def test_labels_decided_knowing_the_hysteresis_are_no_worse_and_say_so(
    params, recordings, profiles
):
    """On each support the labels with the profile's hysteresis are right at least as often as
    the same profile's without it, and every three-signal label says how far it moved
    (``hysteresis_shift``), which turned it or made it less sure, never surer; without the
    weights none does."""
    tolerance = match_tolerance_s(params["identification"])
    for law, recorded in recordings.items():
        with_weights = with_profile(params, profiles[law])
        without = copy.deepcopy(with_weights)
        del without["calibration"]["hysteresis_weights"]
        right = {}
        for name, model_params in (("with", with_weights), ("without", without)):
            labels = _identify(params, recorded)(model_params)
            matching = match(recorded.truths, labels, tolerance)
            pairs = [
                (truth, labels[matching.label_index(k)])
                for k, truth in enumerate(recorded.truths)
                if matching.label_index(k) is not None
            ]
            assert len(pairs) == IMPACTS and not matching.extra
            right[name] = sum(label.material == truth["label"] for truth, label in pairs)
            shifted = sum("hysteresis_shift" in label.features for _, label in pairs)
            assert (shifted >= IMPACTS // 2) if name == "with" else shifted == 0, (
                law,
                name,
                shifted,
            )
            for _, label in pairs:  # the shift turns a label or makes it less sure, never surer
                if "hysteresis_shift" in label.features:
                    logit, shift = label.features["logit"], label.features["hysteresis_shift"]
                    assert shift in (0.0, label.features["hysteresis_shift_read"])
                    assert (logit > 0) != (logit - shift > 0) or abs(logit) <= abs(
                        logit - shift
                    ) + 1e-12, (law, logit, shift)
        assert right["with"] >= right["without"], (law, right)
