"""Identification on supports and sensor rates other than the shipped ones : any IMU
rate, an IMU bolted upside down, a lightly damped low bending mode, features far outside
training (confidence capped, and the label says why)."""

from __future__ import annotations

import copy
import math
from dataclasses import replace

import numpy as np
import pytest
from id_helpers import impact

from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.replay import replay
from tail_beam_id.study.dataset import evaluation_params
from tail_beam_id.study.supports import SupportDraw, draw_support, support_ranges
from tail_beam_sim.physics.scene import Scene

RATES_HZ = (1000.0, 2000.0, 4000.0, 5000.0, 8000.0, 10000.0, 16000.0, 20000.0, 25600.0, 50000.0)
VIBRATION_RATES_HZ = (12800.0, 25600.0, 51200.0)


def identify(params, result, method="statistical", imu=None, vibration=None):
    """The labels of one simulated impact (``imu`` in place of its IMU samples when given;
    ``vibration``: the accelerometer's blocks to feed, none by default)."""
    identifier = StreamIdentifier(method, params["identification"], params)
    return replay(
        identifier,
        result.pressure,
        imu if imu is not None else result.imu,
        [result.rebound],
        vibration=vibration,
    )


@pytest.mark.parametrize("rate_hz", RATES_HZ)
def test_any_imu_rate_labels_the_paper_scene(params, rate_hz):
    """At every IMU rate from 1 to 50 kHz (not only the three trained on before) the study's coal
    and sandstone spheres get their right label: the rate is read from the stamps, never a
    category."""
    for material in ("coal", "sandstone"):
        result = impact(params, material=material, seed=21, sensors={"imu_rate_hz": rate_hz})
        labels = identify(params, result)
        assert len(labels) == 1, labels
        assert labels[0].material == ("coal" if material == "coal" else "gangue"), (
            rate_hz,
            labels[0],
        )
        # A rate the suite supports is inside what the models learnt: the label is not capped
        # as outside training for it (1 and 50 kHz were, at the ends of a 1-50 kHz training draw).
        assert "imu_period_s" not in labels[0].outside_training, (
            rate_hz,
            labels[0].outside_training,
        )


@pytest.mark.parametrize("rate_hz", VIBRATION_RATES_HZ)
def test_any_accelerometer_rate_labels_the_paper_scene(params, rate_hz):
    """The tail-beam accelerometer at the data-acquisition rates of the field (12.8, 25.6 and
    51.2 kHz) beside the 2 kHz IMU: each impact is decided on its samples, its rate not taken
    for something outside training, and rightly: at least 9 of 10 (5 coal, 5 sandstone), none
    wrong at confidence 0.9 or more. (A 25 mm coal sphere can sit near even odds: seed
    21's at 25.6 kHz read P(coal) 0.55 with the models trained on 3,000 drawn-support impacts
    and 0.46 with those trained on 6,000, which label 599 of 600 paper impacts right.)"""
    right = 0
    for seed in range(21, 26):
        for material in ("coal", "sandstone"):
            result = impact(
                params, material=material, seed=seed, sensors={"vibration_rate_hz": rate_hz}
            )
            labels = identify(params, result, vibration=result.vibration)
            assert len(labels) == 1, labels
            assert "vibration" in labels[0].signals
            assert labels[0].features["imu_period_s"] == pytest.approx(1.0 / rate_hz, rel=1e-6)
            correct = labels[0].material == ("coal" if material == "coal" else "gangue")
            assert correct or labels[0].confidence < 0.9, (rate_hz, seed, labels[0])
            right += correct
            assert "imu_period_s" not in labels[0].outside_training, (
                rate_hz,
                labels[0].outside_training,
            )
    assert right >= 9, (rate_hz, right)


def test_odd_rate_is_never_confidently_wrong(params):
    """The reported failure: a 50 mm coal sphere with a 5 kHz IMU was gangue with confidence
    1.0."""
    result = impact(
        params, material="coal", radius_m=0.05, seed=3, sensors={"imu_rate_hz": 5000.0}
    )
    (label,) = identify(params, result)
    assert label.material == "coal" or label.confidence < 0.9, label


@pytest.mark.parametrize("method", ["threshold", "statistical", "physics"])
def test_imu_bolted_upside_down_gives_the_same_label(params, method):
    """An IMU mounted upside down reads -g and mirrored pulses: the identifier reads the mounting
    from gravity and labels as with the IMU the right way up, and says it found it inverted."""
    result = impact(
        params, material="sandstone", radius_m=0.04, seed=5, sensors={"imu_rate_hz": 10000.0}
    )
    flipped = replace(
        result.imu,
        linear_acceleration_mps2=result.imu.linear_acceleration_mps2 * np.array([1.0, -1.0, -1.0]),
        angular_velocity_radps=result.imu.angular_velocity_radps * np.array([1.0, -1.0, -1.0]),
    )
    (upright,) = identify(params, result, method)
    (inverted,) = identify(params, result, method, imu=flipped)
    assert inverted.material == upright.material == "gangue"
    assert inverted.imu_mount == "inverted" and upright.imu_mount is None
    assert abs(inverted.confidence - upright.confidence) < 0.05


def test_accelerometer_bolted_upside_down_gives_the_same_label(params):
    """A tail-beam accelerometer mounted upside down reads -g and mirrored pulses (the models read
    a pulse's polarity). The identifier reads its mounting from gravity, labels as with it the
    right way up, and says so in ``vibration_mount``. A piezoelectric (AC-coupled) one sees no
    gravity: its sign is read from the IMU beside it once the beam moves, right way up or upside
    down."""
    result = impact(params, material="sandstone", radius_m=0.04, seed=5)
    vibration = result.vibration
    assert vibration.count, "the shipped layout has the accelerometer"

    def labels(accel):
        return identify(
            params, result, vibration=replace(vibration, accel_mps2=accel.astype(np.float32))
        )

    accel = np.asarray(vibration.accel_mps2, dtype=float)
    (upright,) = labels(accel)
    (inverted,) = labels(-accel)
    ac = accel - np.median(accel[:1000])
    (ac_coupled,) = labels(ac)
    (ac_inverted,) = labels(-ac)
    assert "vibration" in upright.signals
    assert {inverted.material, upright.material, ac_coupled.material, ac_inverted.material} == {
        "gangue"
    }
    assert inverted.vibration_mount == ac_inverted.vibration_mount == "inverted"
    assert upright.vibration_mount is None and ac_coupled.vibration_mount is None
    assert inverted.impact_stamp_s == upright.impact_stamp_s == ac_inverted.impact_stamp_s
    assert inverted.confidence == pytest.approx(upright.confidence, abs=1e-6)
    assert ac_inverted.confidence == pytest.approx(ac_coupled.confidence, abs=1e-6)


def test_lightly_damped_low_mode_ringing_is_not_taken_for_impacts(params):
    """A support whose first bending mode is at 120 Hz with 0.5 % damping rings for about a
    second after a large impact; the detector follows the ringing on the samples themselves and
    labels one impact, not the ringing."""
    draw = SupportDraw(
        {
            "inertia_scale": 1.0,
            "jack_stiffness_scale": 1.0,
            "jack_damping_scale": 1.0,
            "bending_1_frequency_hz": 120.0,
            "damping_ratio": 0.005,
            "imu_from_hinge_m": 1.2,
            "imu_rate_hz": 10000.0,
            "pressure_rate_hz": 2000.0,
            "camera_frame_rate_hz": 5000.0,
            "noise_factor": 1.0,
        },
        "calibrated",
    )
    varied = draw.apply(params)
    from id_helpers import PRE_CONTACT_S

    from tail_beam_sim.physics.fidelity import FidelitySettings
    from tail_beam_sim.physics.scene import Scene
    from tail_beam_sim.physics.simulate import simulate

    scene = Scene.from_params(
        varied,
        {
            "material": "marble",
            "radius_m": 0.09,
            "drop_height_m": 4.0,
            "position_m": 1.4,
            "pre_contact_s": PRE_CONTACT_S,
            "window_s": 0.3,
            "seed": 2,
        },
    )
    result = simulate(scene, tier="modal", settings=FidelitySettings.from_params(varied))
    labels = identify(varied, result)
    assert len(labels) == 1, [(lab.impact_stamp_s, lab.signals) for lab in labels]
    assert abs(labels[0].impact_stamp_s - result.contact_stamp_s) < 0.001


def test_features_far_outside_training_cap_confidence_and_say_why(params):
    """An impact whose features no training impact came near (a pressure noise 100 x anything
    trained on) gets at most the configured confidence, and the label names the features."""
    result = impact(
        params, material="marble", radius_m=0.05, seed=8, sensors={"pressure_noise_pa": 2.0e6}
    )
    (label,) = identify(params, result)
    cap = params["identification"]["statistical"]["outside_confidence_cap"]
    assert label.confidence <= cap + 1e-9
    assert "pressure_noise_pa" in label.outside_training


def test_drawn_supports_stay_inside_their_ranges(params):
    """Every drawn support lies in the configured ranges, and its parameters describe it."""
    ranges = support_ranges(evaluation_params(params), "foreign")
    rng = np.random.default_rng(0)
    for _ in range(50):
        draw = draw_support(ranges, rng)
        for name, value in draw.values.items():
            low, high = ranges[name]
            assert low <= value <= high or (name == "vibration_rate_hz" and value == 0.0), name
        varied = draw.apply(params)
        assert varied["modes"]["bending_1"]["frequency_hz"] == pytest.approx(
            draw.values["bending_1_frequency_hz"]
        )
        assert varied["sensors"]["imu_rate_hz"] == draw.values["imu_rate_hz"]
        assert varied["sensors"]["vibration_rate_hz"] == (
            draw.vibration_rate_hz or params["sensors"]["vibration_rate_hz"]
        )
        assert varied["support"]["beam_inertia_about_hinge_kgm2"] == pytest.approx(
            params["support"]["beam_inertia_about_hinge_kgm2"] * draw.values["inertia_scale"]
        )
    assert copy.deepcopy(params) == params  # the nominal parameters are not touched


def test_the_drawn_paper_set_strikes_drawn_supports_with_the_paper_scenes_impacts(params):
    """varied_paper (training): each impact is the paper scene's (its radius, drop and position,
    the material's nominal restitution) on a support of its own, drawn from the training ranges
    with its contact law, so the models learn that scene beyond config/'s support."""
    from tail_beam_id.study.dataset import DRAWN_SETTING, simulate_set

    ev = evaluation_params(params)
    paper, ranges = ev["paper"], support_ranges(ev, "training")
    impacts = list(simulate_set(params, "varied_paper", 3, 11, [], tier="modal"))
    assert len(impacts) == 3
    for item in impacts:
        assert (
            item.command["radius_m"] == paper["radius_m"][0]
            and item.command["drop_height_m"] == paper["drop_height_m"][0]
        )
        assert (
            item.command["position_m"] == paper["position_m"][0]
            and "restitution" not in item.command
        )
        low, high = ranges["bending_1_frequency_hz"]
        assert low <= item.support.values["bending_1_frequency_hz"] <= high
        simulated = item.results[DRAWN_SETTING].scene
        assert simulated.impact.radius_m == paper["radius_m"][0]
        assert (
            simulated.impact.restitution
            == params["materials"][item.command["material"]]["restitution"]
        )
        assert simulated.contact_model == item.support.contact_model
    assert (
        len({item.support.values["bending_1_frequency_hz"] for item in impacts}) == 3
    )  # a support each


def rescaled_ranges(params) -> dict:
    """The training's support ranges without its structure draws (the nominal modes rescaled on
    every support) and its cameras that stamp the separation (drawn after them)."""
    ranges = support_ranges(evaluation_params(params), "training")
    return {
        k: v
        for k, v in ranges.items()
        if not k.startswith("structure") and k != "exact_camera_share"
    }


def test_training_supports_draw_a_hysteresis_scale_without_moving_any_other_draw(params):
    """Training's supports carry a contact_damping_scale from its range (log-uniform), which
    reaches the simulated support; it is drawn last, so ranges without it (foreign's) draw every
    support as before, and with it every other value is the same. (The training's structure
    draws, tested in test_structures.py, are left out: they come after it.)"""
    ranges = rescaled_ranges(params)
    low, high = ranges["contact_damping_scale"]
    without = {k: v for k, v in ranges.items() if k != "contact_damping_scale"}
    scales = []
    for k in range(40):
        draw = draw_support(ranges, np.random.default_rng(k), np.random.default_rng(100 + k))
        other = draw_support(without, np.random.default_rng(k), np.random.default_rng(100 + k))
        assert {
            n: v for n, v in draw.values.items() if n != "contact_damping_scale"
        } == other.values
        assert (
            draw.contact_model == other.contact_model
            and "contact_damping_scale" not in other.values
        )
        scales.append(draw.values["contact_damping_scale"])
        assert low <= scales[-1] <= high
        assert Scene.from_params(draw.apply(params)).support.contact_damping_scale == scales[-1]
    assert min(scales) < 0.8 and max(scales) > 1.25  # spread over the range, not stuck at 1
    assert "contact_damping_scale" not in support_ranges(evaluation_params(params), "foreign")


def test_drawn_supports_have_the_accelerometer_at_the_configured_share(params):
    """About vibration_share of drawn supports have the accelerometer (rate in range, noise scaled
    as the others'), the rest none; drawn from its own generator, it leaves every other draw as it
    was. (The training's structure draws are left out, as above.)"""
    ranges = rescaled_ranges(params)
    draws = [
        draw_support(ranges, np.random.default_rng(5 + k), np.random.default_rng(100 + k))
        for k in range(200)
    ]
    with_it = [d for d in draws if d.vibration_rate_hz > 0.0]
    assert abs(len(with_it) / len(draws) - float(ranges["vibration_share"])) < 0.1
    low, high = ranges["vibration_rate_hz"]
    assert all(low <= d.vibration_rate_hz <= high for d in with_it)
    varied = with_it[0].apply(params)
    assert varied["sensors"]["vibration_noise_density_mps2_rthz"] == pytest.approx(
        params["sensors"]["vibration_noise_density_mps2_rthz"] * with_it[0].values["noise_factor"]
    )
    none = {**ranges, "vibration_share": 0.0}
    for k, draw in enumerate(draws):
        other = draw_support(none, np.random.default_rng(5 + k), np.random.default_rng(100 + k))
        assert other.vibration_rate_hz == 0.0
        assert {n: v for n, v in other.values.items() if n != "vibration_rate_hz"} == {
            n: v for n, v in draw.values.items() if n != "vibration_rate_hz"
        } and other.contact_model == draw.contact_model


def test_shipped_models_are_less_sure_of_a_small_impact_than_a_large_one_at_one_logit(
    params,
):
    """The shipped statistical models' temperature grows as the moment impulse shrinks (fitted on
    unseen drawn supports: small particles are where they err): the same network logit gives a
    smaller confidence for a 1 N m s impact than for a 20 N m s one, in the three-signal model of
    both families, and the shipped fit says so with a positive slope."""
    import math

    from tail_beam_id.methods import load_model
    from tail_beam_id.methods.statistical import temperature_of

    model = load_model("statistical")
    for family in ("subsets", "calibrated_subsets"):
        subset = model[family]["jack_pressure+imu+rebound_velocity"]
        assert subset["temperature_size"]["feature"] == "moment_impulse_pressure_nms"
        assert subset["temperature_size"]["slope"] > 0.0
        column = [name for name, _ in subset["features"]].index("moment_impulse_pressure_nms")
        x = np.array(subset["mean"], dtype=float)
        small, large = x.copy(), x.copy()
        small[column], large[column] = math.log(1.0), math.log(20.0)
        assert (
            temperature_of(subset, small) > subset["temperature"] > temperature_of(subset, large)
        )


def test_a_slow_cameras_rebounds_stay_with_their_impacts(params):
    """A 250 Hz camera (4 ms frames; its stamps say 2 ms at least, the slowest frame they are read
    to): each rebound is stamped up to 4 ms after its contact ended, past the rebound window a
    2 kHz camera needs. The window widens by the frame's excess once the stamps have told it
    (from the 4th rebound on), so no rebound becomes an impact of its own from there; with the
    frame self-calibration reads from all the stamps (tail-beam identify's default), none at
    all."""
    import copy
    from dataclasses import replace

    from tail_beam_id.calibration.offline import calibrate, with_profile
    from tail_beam_id.stream.identifier import StreamIdentifier
    from tail_beam_id.stream.label import match, match_tolerance_s
    from tail_beam_id.stream.replay import replay
    from tail_beam_id.study.dataset import settings, support_streams

    recorded = next(
        support_streams(params, 1, 12, seed=41004, setting=settings(params, [1.0], ["shipped"])[0])
    )
    separations = np.array([truth["final_separation_stamp"] for truth in recorded.truths])
    rebounds = [
        replace(
            r,
            stamp_s=float(
                np.ceil(separations[np.argmin(np.abs(separations - r.stamp_s))] * 250.0) / 250.0
            ),
        )
        for r in recorded.rebounds
    ]
    assert (
        max(r.stamp_s - t for r, t in zip(rebounds, separations)) > 0.0025
    )  # lags past the window a 2 kHz camera needs

    def extras(model_params):
        labels = replay(
            StreamIdentifier("statistical", model_params["identification"], model_params),
            recorded.pressure,
            recorded.imu,
            rebounds,
            vibration=recorded.vibration,
        )
        matching = match(recorded.truths, labels, match_tolerance_s(params["identification"]))
        assert not matching.missed
        return [labels[k].impact_stamp_s for k in matching.extra]

    assert all(stamp < rebounds[3].stamp_s for stamp in extras(params))
    v = recorded.vibration
    profile = calibrate(
        params,
        (recorded.pressure.stamp_s, recorded.pressure.pressure_pa),
        (recorded.imu.stamp_s, recorded.imu.linear_acceleration_mps2[:, 2]),
        lambda model_params: [],
        (v.sample_stamps_s(), v.accel_mps2),
        [r.stamp_s for r in rebounds],
    )
    assert profile.camera_frame_rate_hz == pytest.approx(500.0)
    assert extras(with_profile(copy.deepcopy(params), profile)) == []


@pytest.mark.parametrize("camera_hz", [100.0, 50.0])
def test_a_camera_slower_than_its_frame_can_be_read_gives_no_extra_labels(params, camera_hz):
    """A 100 Hz and a 50 Hz camera (10 and 20 ms frames, beyond the 2 ms the stamps are read to
    and the configured 5 kHz): each rebound is stamped up to a frame after its contact ended,
    far past its rebound window. Uncalibrated (the frame never known), every rebound stays with
    its impact (before the late rule a 100 Hz camera's rebounds made 123 extra labels in 200
    foreign impacts), no impact is missed, and a label with such a rebound assumes a frame at
    least as long as its delay, so it is decided without the delay (never from a 10 ms lag read
    as a contact)."""
    from dataclasses import replace

    from tail_beam_id.stream.identifier import StreamIdentifier
    from tail_beam_id.stream.label import match, match_tolerance_s
    from tail_beam_id.stream.replay import replay
    from tail_beam_id.study.dataset import settings, support_streams

    recorded = next(
        support_streams(params, 1, 12, seed=41004, setting=settings(params, [1.0], ["shipped"])[0])
    )
    separations = np.array([truth["final_separation_stamp"] for truth in recorded.truths])
    rebounds = [
        replace(
            r,
            stamp_s=float(
                np.ceil(separations[np.argmin(np.abs(separations - r.stamp_s))] * camera_hz)
                / camera_hz
            ),
        )
        for r in recorded.rebounds
    ]
    lags = [r.stamp_s - t for r, t in zip(rebounds, separations)]
    assert max(lags) > 0.5 / camera_hz  # some lag far past the 3.5 ms window
    labels = replay(
        StreamIdentifier("statistical", params["identification"], params),
        recorded.pressure,
        recorded.imu,
        rebounds,
        vibration=recorded.vibration,
    )
    matching = match(recorded.truths, labels, match_tolerance_s(params["identification"]))
    assert not matching.missed and not matching.extra
    late = [label for label in labels if label.features.get("rebound_late")]
    assert late and all("rebound_velocity" in label.signals for label in labels)
    for label in late:
        assert label.features["camera_frame_period_s"] >= label.features["rebound_delay_s"] > 0.003
        assert "delay_unusual" not in label.features  # decided without the delay


def test_a_camera_known_to_be_fast_gives_no_late_rebounds(params):
    """The late rule is for cameras that may be slower than their frame is known to be. Once the
    stamps (from the 4th rebound) or self-calibration show a fast camera, a rebound after its
    window is another impact's, or a slow IMU's onset came early: a 500 Hz IMU alone (below the
    supported 1 kHz) places onsets 3-5 ms early, and the pulse claiming the rebound late kept
    that onset, so its label would miss its impact. From the 4th rebound on no rebound is taken
    late, and these two supports' impacts are all found (extra labels remain: README, Known
    limitations)."""
    from dataclasses import replace

    from tail_beam_id.stream.identifier import StreamIdentifier
    from tail_beam_id.stream.label import match
    from tail_beam_id.stream.replay import replay
    from tail_beam_id.study.dataset import settings, support_streams

    streams = list(
        support_streams(params, 4, 20, 41004, setting=settings(params, [1.0], ["shipped"])[0])
    )
    for recorded in (streams[0], streams[3]):
        imu = recorded.imu
        slow = replace(
            imu,
            stamp_s=imu.stamp_s[::4],
            angular_velocity_radps=imu.angular_velocity_radps[::4],
            linear_acceleration_mps2=imu.linear_acceleration_mps2[::4],
        )
        labels = replay(
            StreamIdentifier("statistical", params["identification"], params),
            recorded.pressure,
            slow,
            recorded.rebounds,
            vibration=None,
        )
        assert not match(recorded.truths, labels, 0.005).missed
        fourth = sorted(r.stamp_s for r in recorded.rebounds)[3]
        assert all(
            label.impact_stamp_s < fourth for label in labels if label.features.get("rebound_late")
        )


def test_a_share_of_training_supports_have_a_camera_that_stamps_the_separation(params):
    """exact_camera_share of the training's supports (drawn last) have the camera that stamps
    the separation itself (EXACT_CAMERA_RATE_HZ); the draw changes nothing else, and ranges
    without it (foreign's, structures') draw no such camera."""
    from tail_beam_id.study.supports import EXACT_CAMERA_RATE_HZ

    ev = evaluation_params(params)
    ranges = support_ranges(ev, "training")
    share = float(ranges["exact_camera_share"])
    assert 0.0 < share < 1.0
    without = {k: v for k, v in ranges.items() if k != "exact_camera_share"}
    exact = 0
    for k in range(200):
        draw = draw_support(
            ranges, np.random.default_rng(k), np.random.default_rng(100 + k), params["modes"]
        )
        other = draw_support(
            without, np.random.default_rng(k), np.random.default_rng(100 + k), params["modes"]
        )
        changed = {n for n in draw.values if draw.values[n] != other.values[n]}
        assert changed <= {"camera_frame_rate_hz"}
        if draw.values["camera_frame_rate_hz"] == EXACT_CAMERA_RATE_HZ:
            exact += 1
        else:
            assert not changed
    assert abs(exact / 200 - share) < 4 * math.sqrt(share * (1 - share) / 200)
    for which in ("foreign", "structures"):
        assert "exact_camera_share" not in support_ranges(ev, which)
