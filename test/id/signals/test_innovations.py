"""The accelerometer's ringing predicted from the samples before (tail_beam_id.signals.
innovations), and the second detector that scans what the predictor leaves for the contacts the
vibration detector loses in another impact's ringing."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from tail_beam_id.calibration.offline import calibrate, with_profile
from tail_beam_id.signals.innovations import ORDER, fit_predictor, prediction_errors
from tail_beam_id.stream.label import Label
from tail_beam_id.stream.replay import replay
from tail_beam_id.stream.share_reader import SharingIdentifier
from tail_beam_id.study.flow import record_sim_flow
from tail_beam_id.study.flow_evaluation import FLOW_SEED, flow_supports
from tail_beam_sim.config import load_parameters
from tail_beam_sim.errors import InputError

RATE_HZ = 25600.0  # the shipped accelerometer


def ringing(seconds: float, noise: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Two lightly damped modes (178 Hz at 0.8 %, 560 Hz at 1 %) struck every 0.2 s with random
    amplitudes, plus white noise of RMS ``noise``: (free ringing, measured), m/s^2."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * RATE_HZ)) / RATE_HZ
    free = np.zeros_like(t)
    for start in np.arange(0.01, seconds, 0.2):
        after = t >= start
        tau = t[after] - start
        for f, zeta in ((178.0, 0.008), (560.0, 0.01)):
            w = 2 * math.pi * f
            free[after] += rng.uniform(20, 200) * np.exp(-zeta * w * tau) * np.sin(w * tau)
    return free, free + rng.normal(0.0, noise, t.size)


def test_the_predictor_leaves_the_noise_of_a_ringing_beam():
    """Fitted on 2 s of two modes ringing at 20-200 m/s^2 over noise of 0.25 m/s^2, the
    predictor's errors have an RMS within 3 x the noise's (white noise is not predictable;
    the predictor passes it on with its own coefficients' gain), where the samples' RMS is
    over 100 x: the ringing is what it predicts."""
    free, measured = ringing(2.0, 0.25, 1)
    coefficients = fit_predictor(measured)
    assert coefficients is not None and coefficients.size == ORDER
    errors = prediction_errors(measured, coefficients)
    assert np.sqrt(np.mean(measured**2)) > 100 * 0.25
    assert np.sqrt(np.mean(errors[ORDER:] ** 2)) < 3 * 0.25


def test_the_errors_do_not_depend_on_where_the_stream_was_cut():
    """Each sample's error depends on it and the ORDER samples before: the errors of a stream's
    tail equal those of the whole after its first ORDER samples."""
    _, measured = ringing(0.3, 0.25, 2)
    coefficients = fit_predictor(measured)
    whole = prediction_errors(measured, coefficients)
    tail = prediction_errors(measured[1000:], coefficients)
    assert np.allclose(tail[ORDER:], whole[1000 + ORDER :], rtol=0, atol=1e-9)


def test_too_short_a_recording_fits_no_predictor():
    """Fewer samples than MIN_SAMPLES_PER_COEFFICIENT per coefficient give None."""
    assert fit_predictor(np.zeros(100)) is None


@pytest.fixture(scope="module")
def ringing_flow():
    """Two seconds of 50 lumps/s on the flow set's first foreign support, whose first mode
    (178 Hz) is damped 0.8 %: it rings for about a tenth of a second after each lump."""
    params = load_parameters([])
    name, draw = flow_supports(params, 1, FLOW_SEED)[1]
    assert name == "foreign-1" and draw.values["damping_ratio"] < 0.01
    return params, record_sim_flow(params, 50.0, 2.0, 1.0, 0.5, 0.7, seed=9301, support=draw)


def with_innovations(params, innovations: bool) -> dict:
    """``params`` with identification.detection.vibration_innovations as given."""
    section = dict(params["identification"])
    section["detection"] = {**section["detection"], "vibration_innovations": innovations}
    return {**params, "identification": section}


def run(recording, model_params, identifier=None, chunk_s: float = 0.01, progress=None):
    """The recording's labels, replayed in ``chunk_s`` chunks into ``identifier`` (default: a
    fresh one reading ``model_params``)."""
    if identifier is None:
        identifier = SharingIdentifier(
            None, params=model_params["identification"], model_params=model_params
        )
    return replay(
        identifier,
        recording.pressure,
        recording.imu,
        recording.rebounds,
        chunk_s=chunk_s,
        vibration=recording.vibration,
        progress=progress,
    )


def profile_of(params, recording):
    """The recording's self-calibrated profile under ``params``."""
    vibration = recording.vibration
    return calibrate(
        params,
        (recording.pressure.stamp_s, recording.pressure.pressure_pa),
        (recording.imu.stamp_s, recording.imu.linear_acceleration_mps2[:, 2]),
        lambda model_params: run(recording, model_params),
        (vibration.sample_stamps_s(), vibration.accel_mps2),
        [r.stamp_s for r in recording.rebounds],
    )


def identify(
    params, recording, innovations: bool, chunks_s: tuple[float, ...] = (0.01,)
) -> list[list[Label]]:
    """The flow's labels replayed in each of ``chunks_s`` (s), self-calibrated (10 ms chunks)
    with identification.detection.vibration_innovations as given."""
    params = with_innovations(params, innovations)
    profile = profile_of(params, recording)
    assert (profile.vibration_predictor is not None) == innovations
    return [
        run(recording, with_profile(params, profile), chunk_s=chunk_s) for chunk_s in chunks_s
    ]


def resting_on_accelerometer(labels: list[Label]) -> int:
    return sum("vibration" in (label.signals or ()) for label in labels)


def test_the_second_detector_finds_pulses_in_the_ringing(ringing_flow):
    """With the predictor the flow's labels rest on an accelerometer pulse at least 1.2 x as
    often, and their number stays within 3 of the lumps (the second detector adds no impact
    where the first found one)."""
    params, recording = ringing_flow
    (without,) = identify(params, recording, False)
    (with_it,) = identify(params, recording, True)
    lumps = len(recording.truths)
    assert abs(len(with_it) - lumps) <= 3 and abs(len(without) - lumps) <= 3
    assert resting_on_accelerometer(with_it) >= 1.2 * resting_on_accelerometer(without)


def label_record(label: Label) -> dict:
    """A label's JSON without its wall-clock latency."""
    data = json.loads(label.to_json())
    data.pop("latency_ms", None)
    return data


def test_with_the_predictor_labels_do_not_depend_on_the_chunking(ringing_flow):
    """The flow replayed in 10 ms, 3.7 ms and 21.3 ms chunks with the predictor gives the same
    labels."""
    params, recording = ringing_flow
    runs = [
        [label_record(lab) for lab in labels]
        for labels in identify(params, recording, True, (0.01, 0.0037, 0.0213))
    ]
    assert runs[1] == runs[0] and runs[2] == runs[0] and len(runs[0]) > 50


def test_a_bad_predictor_in_a_profile_is_refused_by_name():
    """A profile whose predictor holds a value beyond +-1000 is refused naming the field."""
    from tail_beam_id.stream.config import check_profile

    with pytest.raises(InputError, match="vibration_predictor"):
        check_profile({"calibration": {"vibration_predictor": [1.0, 1e9]}})


def test_calibration_fits_the_predictor_on_the_longest_unbroken_run(params):
    """ringing_predictor: off unless identification.detection.vibration_innovations; on, it
    fits the longest evenly spaced run of a recording with a lost block and reports the rate
    it holds for; the predictor is that run's own fit."""
    from tail_beam_id.calibration.offline import ringing_predictor

    _, measured = ringing(1.0, 0.25, 3)
    stamp = np.arange(measured.size) / RATE_HZ
    stamp[10000:] += 0.05  # a lost block: 50 ms missing after the first 10,000 samples
    section = dict(params["identification"])

    def with_flag(flag: bool) -> dict:
        detection = {**section["detection"], "vibration_innovations": flag}
        return {**params, "identification": {**section, "detection": detection}}

    assert ringing_predictor(with_flag(False), (stamp, measured)) == {}
    found = ringing_predictor(with_flag(True), (stamp, measured))
    assert found["vibration_predictor_rate_hz"] == pytest.approx(RATE_HZ, rel=1e-9)
    assert found["vibration_predictor"] == pytest.approx(
        list(fit_predictor(measured[10000:])), rel=1e-12, abs=1e-12
    )


def test_a_predictor_taken_mid_stream_labels_no_impact_twice(ringing_flow):
    """A profile with the predictor taken half way through the flow (as a profile learnt
    online would be): the second detector starts where the first has got to, so the impacts
    already decided get no second label (a look back over the buffered half second would add
    about twenty): the labels number within 3 of the lumps."""
    params, recording = ringing_flow
    params = with_innovations(params, True)
    profile = profile_of(params, recording)
    assert profile.vibration_predictor is not None
    identifier = SharingIdentifier(None, params=params["identification"], model_params=params)
    switched = []

    def halfway(done_s: float, total_s: float) -> None:
        if not switched and done_s >= 0.5 * total_s:
            identifier.recalibrate(with_profile(params, profile))
            switched.append(done_s)

    labels = run(recording, params, identifier, progress=halfway)
    assert switched
    assert abs(len(labels) - len(recording.truths)) <= 3


def test_the_same_profile_again_mid_stream_changes_no_label(ringing_flow):
    """A profile with the predictor given from the start and then again half way (as a node
    taking the same profile twice would): the second detector carries on, so every label is
    the one the uninterrupted replay gives."""
    params, recording = ringing_flow
    params = with_innovations(params, True)
    calibrated = with_profile(params, profile_of(params, recording))
    identifier = SharingIdentifier(
        None, params=calibrated["identification"], model_params=calibrated
    )
    switched = []

    def halfway(done_s: float, total_s: float) -> None:
        if not switched and done_s >= 0.5 * total_s:
            identifier.recalibrate(calibrated)
            switched.append(done_s)

    again = run(recording, calibrated, identifier, progress=halfway)
    assert switched
    once = run(recording, calibrated)
    assert [label_record(lab) for lab in again] == [label_record(lab) for lab in once]


def test_a_predictor_of_too_many_coefficients_is_refused_by_name():
    """A profile whose predictor holds more than MAX_PREDICTOR_ORDER coefficients (each costs
    a multiply per buffered sample at every delivery) is refused naming the field and the
    bound."""
    from tail_beam_id.stream.config import MAX_PREDICTOR_ORDER, check_profile

    with pytest.raises(InputError, match=f"vibration_predictor.*at most {MAX_PREDICTOR_ORDER}"):
        check_profile(
            {
                "calibration": {
                    "vibration_predictor": [0.01] * (MAX_PREDICTOR_ORDER + 1),
                    "vibration_predictor_rate_hz": RATE_HZ,
                }
            }
        )
