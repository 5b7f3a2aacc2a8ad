"""Self-calibration: a support profile from the support's own recording, no labels;
`tail-beam calibrate` writes it and `tail-beam identify` uses it."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from tail_beam_id.calibration.offline import (
    calibrate,
    imu_gain,
    mount_sign,
    sway_frequency,
    with_profile,
)
from tail_beam_id.signals.camera import GRIDLESS_PERIOD_S
from tail_beam_id.signals.timing import UNUSUAL
from tail_beam_id.stream.decision import profile_says_timing_suspect
from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.label import Label
from tail_beam_id.stream.replay import replay
from tail_beam_id.study.dataset import support_streams
from tail_beam_sim.bags.records import imu_msgs, pressure_msgs, rebound_msg, write_bag
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.fidelity import TIERS, FidelitySettings, structure_for
from tail_beam_sim.physics.materials import material_table
from tail_beam_sim.physics.support import Support

TAIL_BEAM = str(Path(sys.executable).parent / "tail-beam")  # the installed console script


@pytest.fixture(scope="module")
def recordings(params):
    """Three drawn foreign supports, each a continuous stream of 12 impacts."""
    return list(support_streams(params, 3, 12, seed=777))


def first_impacts(recorded, count: int) -> tuple[list, list[dict]]:
    """A recording's bag records (pressure, IMU, rebounds) up to 50 ms before its impact
    ``count`` + 1, and the truths of the first ``count`` impacts: a shorter bag to write and
    read, still many sway periods long."""
    end_s = recorded.truths[count]["contact_start_stamp"] - 0.05
    imu, pressure = recorded.imu, recorded.pressure
    kept_imu, kept_pressure = imu.stamp_s < end_s, pressure.stamp_s < end_s
    records = [
        *pressure_msgs(pressure.stamp_s[kept_pressure], pressure.pressure_pa[kept_pressure], 1e8),
        *imu_msgs(
            imu.stamp_s[kept_imu],
            imu.angular_velocity_radps[kept_imu],
            imu.linear_acceleration_mps2[kept_imu],
            0.0,
            0.0,
        ),
        *(rebound_msg(r.stamp_s, r.velocity_mps) for r in recorded.rebounds if r.stamp_s < end_s),
    ]
    return records, recorded.truths[:count]


def _identify(params, recorded):
    return lambda model_params: replay(
        StreamIdentifier("statistical", params["identification"], model_params),
        recorded.pressure,
        recorded.imu,
        recorded.rebounds,
    )


def test_sway_frequency_is_the_supports_rigid_mode(params, recordings):
    """The peak of the jack pressure's spectrum is the lowest natural frequency of the support that
    recorded it (the beam swaying on the oil column, lowered a little by a soft bending mode; not
    the nominal 39 Hz), within 2 % (a 5 s recording resolves 0.2 Hz of 40 Hz, and the impacts
    force the sway off its free frequency a little)."""
    for recorded in recordings:
        support = Support.from_params(recorded.params["support"], material_table(recorded.params))
        structure = structure_for(
            TIERS["modal"], support, FidelitySettings.from_params(recorded.params).modes
        )
        truth = structure.natural_frequencies_hz()[0]
        found = sway_frequency(recorded.pressure.stamp_s, recorded.pressure.pressure_pa)
        assert found == pytest.approx(truth, rel=0.02), recorded.support.describe()


def test_profile_restores_the_supports_sway_and_jack_gain(params, recordings):
    """The profile's (rigid) support sways at the recorded support's lowest natural frequency, so
    its pressure per unit moment impulse, omega / (d S) on the rigid beam, is the recorded one's,
    within 2 % (as the frequency); and the nominal support's is not (the test would pass on no
    profile otherwise)."""
    for recorded in recordings:
        profile = calibrate(
            params,
            (recorded.pressure.stamp_s, recorded.pressure.pressure_pa),
            (recorded.imu.stamp_s, recorded.imu.linear_acceleration_mps2[:, 2]),
            _identify(params, recorded),
        )
        assert profile.calibrated
        calibrated = {
            **params,
            "support": {
                **params["support"],
                **profile.parameters()["/**"]["ros__parameters"]["support"],
            },
        }
        materials = material_table(params)
        support = Support.from_params(recorded.params["support"], materials)
        structure = structure_for(
            TIERS["modal"], support, FidelitySettings.from_params(recorded.params).modes
        )
        truth = (
            2
            * np.pi
            * structure.natural_frequencies_hz()[0]
            / (support.jack_lever_arm_m * support.piston_area_m2)
        )
        found = Support.from_params(calibrated["support"], materials)
        nominal = Support.from_params(params["support"], materials)

        def gain(s):
            return 2 * np.pi * s.rigid_mode_frequency_hz / (s.jack_lever_arm_m * s.piston_area_m2)

        assert gain(found) == pytest.approx(truth, rel=0.02)
        assert gain(nominal) != pytest.approx(truth, rel=0.02)
        assert profile.impacts_used >= 3


def test_mount_sign_from_gravity():
    """+g at rest on z: mounted as configured; -g: upside down; no gravity: unknown."""
    rng = np.random.default_rng(0)
    noise = rng.normal(0.0, 0.05, 200)
    assert mount_sign(9.81 + noise) == 1.0
    assert mount_sign(-9.81 + noise) == -1.0
    assert mount_sign(noise) is None


def test_no_impacts_no_profile(params):
    """A recording of noise only has no sway to measure: the profile says it is not calibrated."""
    rng = np.random.default_rng(1)
    stamps = np.arange(0.0, 5.0, 1 / 2000.0)
    profile = calibrate(
        params,
        (stamps, 20e6 + rng.normal(0, 1e4, stamps.size)),
        (stamps, 9.81 + rng.normal(0, 0.05, stamps.size)),
        lambda p: [],
    )
    assert not profile.calibrated
    assert profile.imu_mount_sign == 1.0
    assert profile.pressure_noise_pa == pytest.approx(1e4, rel=0.1)


def test_calibrate_then_identify_from_the_command_line(params, recordings, tmp_path):
    """`tail-beam calibrate BAG --out profiles/profile.yaml` writes a ROS 2 parameter file (its
    folder made); `tail-beam identify BAG --config profile.yaml` then labels every impact as
    calibrated, as plain `tail-beam identify BAG` does by default (saying what it measured), and
    `--no-calibrate` does not. An --out that is a symbolic link is refused in one line, exit 2."""
    # Six of the twelve impacts: 2.7 s, over a hundred periods of the 44 Hz sway (a bag half as
    # long for each of the four commands to read).
    records, truths = first_impacts(recordings[0], 6)
    bag = tmp_path / "support"
    write_bag(bag, records)
    link = tmp_path / "link.yaml"
    link.symlink_to(tmp_path / "elsewhere.yaml")
    done = subprocess.run(
        [TAIL_BEAM, "calibrate", str(bag), "--out", str(link)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert (
        done.returncode == 2
        and "symbolic link" in done.stderr
        and len(done.stderr.strip().splitlines()) == 1
    )
    assert not (tmp_path / "elsewhere.yaml").exists()
    profile = tmp_path / "profiles" / "profile.yaml"
    done = subprocess.run(
        [TAIL_BEAM, "calibrate", str(bag), "--out", str(profile)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    content = yaml.safe_load(profile.read_text())["/**"]["ros__parameters"]
    assert (
        content["calibration"]["rigid_mode_frequency_hz"] > 0
        and "oil_bulk_modulus_pa" in content["support"]
    )
    done = subprocess.run(
        [TAIL_BEAM, "identify", str(bag), "--config", str(profile), "--no-calibrate"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    labels = [Label.from_json(line) for line in done.stdout.splitlines()]
    assert len(labels) >= len(truths) - 1
    assert all(label.calibrated for label in labels)
    # Plain identify calibrates by itself (identification.self_calibrate) to the same profile,
    # says so on stderr, and gives the same labels; --no-calibrate gives the uncalibrated ones.
    plain = subprocess.run(
        [TAIL_BEAM, "identify", str(bag)], capture_output=True, text=True, check=False
    )
    assert plain.returncode == 0, plain.stderr
    assert (
        f"self-calibration: sway {content['calibration']['rigid_mode_frequency_hz']:.2f} Hz"
        in plain.stderr
    )

    def decided(found):  # all but latency_ms, a wall-clock figure
        return [replace(label, latency_ms=0.0) for label in found]

    assert decided(Label.from_json(line) for line in plain.stdout.splitlines()) == decided(labels)
    raw = subprocess.run(
        [TAIL_BEAM, "identify", str(bag), "--no-calibrate"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert raw.returncode == 0 and "self-calibration" not in raw.stderr
    assert not any(json.loads(line)["calibrated"] for line in raw.stdout.splitlines())


def test_foreign_supports_at_a_named_setting_keep_their_mechanics_and_impacts(params):
    """The foreign set compares like with like: recorded at a named sensor setting, each drawn
    support keeps its mechanics, contact law and impacts (the truths are identical) while its
    sensors become the setting's (the IMU at its rate, the accelerometer present or not, noise
    x1)."""
    from tail_beam_id.study.dataset import settings

    shipped, nominal = settings(params, [1.0], ["shipped", "nominal"])
    drawn = list(support_streams(params, 2, 2, seed=778))
    at_shipped = list(support_streams(params, 2, 2, seed=778, setting=shipped))
    at_nominal = list(support_streams(params, 2, 2, seed=778, setting=nominal))
    for own, s, n in zip(drawn, at_shipped, at_nominal):
        assert s.support.contact_model == n.support.contact_model == own.support.contact_model
        mechanics = {
            k: v
            for k, v in own.support.values.items()
            if not k.endswith("_rate_hz") and k != "noise_factor"
        }
        for other in (s, n):
            assert {k: other.support.values[k] for k in mechanics} == mechanics
            assert [t["radius_m"] for t in other.truths] == [t["radius_m"] for t in own.truths]
            assert [t["material"] for t in other.truths] == [t["material"] for t in own.truths]
            assert other.support.values["noise_factor"] == 1.0
        assert np.median(np.diff(s.imu.stamp_s)) == pytest.approx(
            1.0 / shipped.rates_hz["imu_rate_hz"]
        )
        assert s.vibration is not None and s.vibration.period_s == pytest.approx(
            1.0 / shipped.vibration_rate_hz
        )
        assert n.vibration is None


def test_a_recording_too_short_to_resolve_the_sway_measures_no_sway(params):
    """A 0.33 s recording of one impact (80 ms after the contact) rings the sway, but its
    spectrum's bins are 3 Hz wide, 8 % of the 39 Hz sway: no sway frequency is claimed (one was;
    a 55 ms bag of `tail-beam simulate` gave 37.2 Hz for the nominal 39.3), so identify
    --calibrate keeps the configured support rather than a guessed one."""
    from id_helpers import impact

    result = impact(params, material="marble", radius_m=0.08)
    assert sway_frequency(result.pressure.stamp_s, result.pressure.pressure_pa) is None


def test_foreign_stream_impacts_come_in_order_a_gap_apart(params):
    """A foreign support's impacts strike one after another, stream_gap_s to 1.5 stream_gap_s
    apart, as documented (they were put at k gaps times a random 1..1.5: out of order, some
    within milliseconds of another, their features mixed)."""
    from tail_beam_id.study.dataset import evaluation_params

    gap_s = float(evaluation_params(params)["stream_gap_s"])
    (recorded,) = support_streams(params, 1, 12, seed=779)
    starts = np.array([t["contact_start_stamp"] for t in recorded.truths])
    steps = np.diff(starts)
    assert len(starts) == 12
    assert np.all(steps >= gap_s - 1e-9) and np.all(steps <= 1.5 * gap_s + 1e-9)


def test_identify_still_labels_when_self_calibration_fails(
    params, recordings, tmp_path, monkeypatch, capsys
):
    """Self-calibration is a refinement: if it cannot read a recording (here made to raise), the
    bag is still identified on the configured support, and stderr says why."""
    import tail_beam_id.cli.identify_cmd as identify_cmd

    # The first four impacts suffice (what is pinned is that labels come, uncalibrated).
    records, truths = first_impacts(recordings[1], 4)
    bag = tmp_path / "support"
    write_bag(bag, records)

    def broken(*args, **kwargs):
        raise FloatingPointError("overflow in the sway fit")

    monkeypatch.setattr(identify_cmd, "calibrate_support", broken)
    labels = identify_cmd.identify_bag(str(bag))
    assert len(labels) >= len(truths) - 1 and not any(label.calibrated for label in labels)
    assert (
        "self-calibration failed (FloatingPointError: overflow in the sway fit)"
        in capsys.readouterr().err
    )


def test_a_long_identification_shows_its_progress_on_a_terminal_only(params, recordings):
    """replay reports how far it got, in order, ending at the whole recording; identify's
    progress line writes on a terminal (in place, then a newline) and stays silent on a pipe or
    for a short recording."""
    import io

    from tail_beam_id.cli.identify_cmd import ProgressLine

    recorded = recordings[0]
    seen = []
    replay(
        StreamIdentifier("statistical", params["identification"], params),
        recorded.pressure,
        recorded.imu,
        recorded.rebounds,
        progress=lambda done, total: seen.append((done, total)),
    )
    stamps = np.concatenate([recorded.pressure.stamp_s, recorded.imu.stamp_s])
    total = stamps.max() - stamps.min()
    assert len(seen) >= 10 and all(t == pytest.approx(total) for _, t in seen)
    assert [d for d, _ in seen] == sorted(d for d, _ in seen) and seen[-1][0] == pytest.approx(
        total
    )

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    terminal, pipe = Terminal(), io.StringIO()
    for stream in (terminal, pipe):
        line = ProgressLine(stream, "identify: / identifying")
        line.update(30.0, 120.0)
        line.update(120.0, 120.0)
        line.close()
    assert terminal.getvalue() == (
        "\ridentify: / identifying: 30 of 120 s of data (25 %)"
        "\ridentify: / identifying: 120 of 120 s of data (100 %)\n"
    )
    assert pipe.getvalue() == ""
    short = Terminal()
    ProgressLine(short, "x").update(1.0, 5.0)
    assert short.getvalue() == ""


def test_identify_says_once_what_it_left_out_even_when_it_calibrates(params, recordings, tmp_path):
    """A NaN pressure sample in a bag is reported on stderr once, though self-calibration passes
    through the recording as well (it was reported twice); self-calibration leaves it out as the
    identifier does and still measures the sway (the NaN made it fail); labels stay strict JSON."""
    recorded = recordings[2]
    imu = recorded.imu
    pressure = recorded.pressure.pressure_pa.copy()
    pressure[len(pressure) // 2] = np.nan
    bag = tmp_path / "support"
    write_bag(
        bag,
        [
            *pressure_msgs(recorded.pressure.stamp_s, pressure, 1e8),
            *imu_msgs(
                imu.stamp_s, imu.angular_velocity_radps, imu.linear_acceleration_mps2, 0.0, 0.0
            ),
            *(rebound_msg(r.stamp_s, r.velocity_mps) for r in recorded.rebounds),
        ],
    )
    done = subprocess.run(
        [TAIL_BEAM, "identify", str(bag)], capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, done.stderr
    assert (
        done.stderr.count("jack_pressure: 1 sample(s) with a non-finite stamp or value left out")
        == 1
    )
    assert "self-calibration: sway" in done.stderr
    for line in done.stdout.splitlines():
        json.loads(line, parse_constant=lambda name: pytest.fail(f"label carries {name}"))


def test_self_calibration_reads_the_cameras_frame_from_every_rebound(params, recordings):
    """A 1 kHz camera (each rebound stamped at the first 1 ms frame after separation): the
    profile reads its frame from the grid of all the recording's rebound stamps, so even the
    first impacts, before four rebounds have come, are decided with its lag, not config/'s
    5 kHz camera's (labels say the frame they assumed); a recording whose stamps lie on no grid
    is read as stamped at the separation itself (tail_beam_id.signals.camera.GRIDLESS_PERIOD_S)."""
    recorded = recordings[0]
    separations = np.array([truth["final_separation_stamp"] for truth in recorded.truths])
    rebounds = [
        replace(
            r,
            stamp_s=float(
                np.ceil(separations[np.argmin(np.abs(separations - r.stamp_s))] * 1000.0) / 1000.0
            ),
        )
        for r in recorded.rebounds
    ]
    slow = replace(recorded, rebounds=rebounds)
    profile = calibrate(
        params,
        (slow.pressure.stamp_s, slow.pressure.pressure_pa),
        (slow.imu.stamp_s, slow.imu.linear_acceleration_mps2[:, 2]),
        _identify(params, slow),
        rebound_stamps_s=[r.stamp_s for r in rebounds],
    )
    assert profile.camera_frame_rate_hz == pytest.approx(1000.0, rel=1e-6)
    assert (
        profile.parameters()["/**"]["ros__parameters"]["sensors"]["camera_frame_rate_hz"]
        == profile.camera_frame_rate_hz
    )
    merged = with_profile(params, profile)
    labels = replay(
        StreamIdentifier("statistical", merged["identification"], merged),
        slow.pressure,
        slow.imu,
        slow.rebounds,
    )
    first = min(labels, key=lambda label: label.impact_stamp_s)
    assert first.features["camera_frame_period_s"] == pytest.approx(0.001, rel=1e-6)
    uncalibrated = replay(
        StreamIdentifier("statistical", params["identification"], params),
        slow.pressure,
        slow.imu,
        slow.rebounds,
    )
    assert min(uncalibrated, key=lambda label: label.impact_stamp_s).features[
        "camera_frame_period_s"
    ] == pytest.approx(1 / 5000.0)
    jittered = [r.stamp_s + 1e-5 * k for k, r in enumerate(rebounds)]
    assert (
        calibrate(
            params,
            (slow.pressure.stamp_s, slow.pressure.pressure_pa),
            (slow.imu.stamp_s, slow.imu.linear_acceleration_mps2[:, 2]),
            _identify(params, slow),
            rebound_stamps_s=jittered,
        ).camera_frame_rate_hz
        == 1.0 / GRIDLESS_PERIOD_S
    )


def test_the_paper_scene_strikes_the_foreign_supports_the_stream_scene_does(params):
    """support_streams(scene="paper") (the foreign_paper set) records the very supports the
    stream scene's foreign set does (same seed: same drawn values, same contact law), each
    struck by the paper scene's impacts: 25 mm spheres dropped 3.5 m at 1.0 m from the hinge."""
    from tail_beam_id.study.dataset import evaluation_params

    paper = evaluation_params(params)["paper"]
    streams = list(support_streams(params, 2, 4, seed=779))
    papers = list(support_streams(params, 2, 4, seed=779, scene="paper"))
    for stream, struck in zip(streams, papers):
        assert struck.support == stream.support
        radii = {t["radius_m"] for t in struck.truths}
        assert len(struck.truths) == 4 and all(
            min(paper["radius_m"]) <= r <= max(paper["radius_m"]) for r in radii
        )
        assert {t["radius_m"] for t in stream.truths} != radii


def _gain_features(
    rng: np.random.Generator, gain: float, impulses_mps: np.ndarray, sigma_nms: float
) -> list[dict[str, float]]:
    """Impacts' features whose pressure moment is ``gain`` x the IMU impulse plus noise of
    sigma_nms."""
    moments = gain * impulses_mps + rng.normal(0.0, sigma_nms, impulses_mps.size)
    return [
        {
            "moment_impulse_pressure_nms": float(m),
            "moment_impulse_sigma_nms": sigma_nms,
            "imu_impulse_mps": float(i),
        }
        for m, i in zip(moments, impulses_mps)
    ]


def test_imu_gain_is_unbiased_when_few_impacts_stand_clear_of_the_noise():
    """Twenty small impacts, each only 1-6 standard errors clear (the paper scene's 25 mm spheres):
    the weighted least-squares gain is unbiased (the mean over 200 recordings within 2 % of the
    true gain, whose standard error over them is about 1 %), where the median of only the impacts 5
    sigma clear is pushed up by the noise that put them there."""
    rng = np.random.default_rng(3)
    gain, sigma = 800.0, 0.2
    fitted, selected = [], []
    for _ in range(200):
        impulses = rng.uniform(0.25e-3, 1.5e-3, 20)  # 1-6 sigma of moment
        features = _gain_features(rng, gain, impulses, sigma)
        found = imu_gain(features)
        assert found is not None and found[1] == 20
        fitted.append(found[0])
        clear = [
            f["moment_impulse_pressure_nms"] / f["imu_impulse_mps"]
            for f in features
            if f["moment_impulse_pressure_nms"] > 5 * sigma
        ]
        if len(clear) >= 3:
            selected.append(np.median(clear))
    assert np.mean(fitted) == pytest.approx(gain, rel=0.02)
    assert np.median(selected) > 1.1 * gain  # the selection's bias the fit avoids


def test_imu_gain_needs_impacts_and_a_fit_clear_of_zero():
    """None with fewer than 3 usable impacts (non-finite or missing features skipped) or when
    the IMU impulses explain nothing the noise does not (the fit within 5 standard errors of 0)."""
    rng = np.random.default_rng(4)
    assert imu_gain(_gain_features(rng, 800.0, np.array([1e-3, 2e-3]), 0.05)) is None
    features = _gain_features(rng, 800.0, np.array([1e-3, 2e-3, 3e-3]), 0.05)
    assert imu_gain(features) is not None
    broken = features[:2] + [
        {
            "moment_impulse_pressure_nms": math.nan,
            "moment_impulse_sigma_nms": 0.05,
            "imu_impulse_mps": 3e-3,
        },
        {"moment_impulse_pressure_nms": 1.0},
    ]
    assert imu_gain(broken) is None
    assert imu_gain(_gain_features(rng, 0.0, np.full(20, 1e-4), 0.5)) is None


def test_imu_gain_from_noise_free_readings():
    """A recording whose pressure moments carry no noise (sigma 0, e.g. a noise-free simulation)
    gives the exact gain, alone or among noisy impacts, instead of none."""
    exact = [
        {
            "moment_impulse_pressure_nms": 800.0 * i,
            "moment_impulse_sigma_nms": 0.0,
            "imu_impulse_mps": i,
        }
        for i in (1e-3, 2e-3, 3e-3)
    ]
    assert imu_gain(exact)[0] == pytest.approx(800.0, rel=1e-12)
    noisy = _gain_features(np.random.default_rng(5), 800.0, np.full(5, 2e-3), 0.05)
    assert imu_gain(exact + noisy)[0] == pytest.approx(800.0, rel=0.02)


def test_an_implausible_imu_gain_keeps_the_configured_beam_and_its_oil(params, recordings):
    """An IMU whose impulses read 7 times low (a wrong scale factor) gives an inertia about 7 times
    the configured one: refused as implausible, and the oil's bulk modulus is then the one that
    gives the sway frequency with the configured beam (not one solved for the refused
    inertia), as a profile without any IMU gain would have."""
    from tail_beam_id.calibration.offline import bulk_modulus_for

    recorded = recordings[0]
    plain = _identify(params, recorded)

    def scaled(model_params):
        return [
            replace(
                label,
                features={
                    **label.features,
                    "imu_impulse_mps": label.features["imu_impulse_mps"] / 7.0,
                },
            )
            if "imu_impulse_mps" in label.features
            else label
            for label in plain(model_params)
        ]

    profile = calibrate(
        params,
        (recorded.pressure.stamp_s, recorded.pressure.pressure_pa),
        (recorded.imu.stamp_s, recorded.imu.linear_acceleration_mps2[:, 2]),
        scaled,
    )
    assert (
        profile.calibrated
        and profile.beam_inertia_about_hinge_kgm2 is None
        and profile.imu_gain_spread is None
    )
    assert profile.oil_bulk_modulus_pa == pytest.approx(
        bulk_modulus_for(params, profile.rigid_mode_frequency_hz), rel=1e-12
    )


def _marked_unusual(identify, unusual_in):
    """``identify`` whose labels' delay checks say unusual where ``unusual_in(model_params)``."""

    def marked(model_params):
        value = 1.0 if unusual_in(model_params) else 0.0
        return [
            replace(label, features={**label.features, UNUSUAL: value})
            for label in identify(model_params)
        ]

    return marked


def test_a_clock_verdict_from_configs_beam_is_taken_again_with_the_profile(params, recordings):
    """The calibration pass runs with config/'s beam and camera; where its delay checks say the
    clocks are offset, they are counted again on a pass with the profile itself, and that count
    is the profile's. Delays unusual only under config/'s beam: the profile does not start the
    identifier suspecting the clocks. Unusual under both: it does (offset clocks)."""
    from tail_beam_id.signals.timing import TimingConfig

    recorded = recordings[0]
    plain = _identify(params, recorded)
    timing = TimingConfig.from_params(params["identification"]["sensor_timing"])
    signals = (
        (recorded.pressure.stamp_s, recorded.pressure.pressure_pa),
        (recorded.imu.stamp_s, recorded.imu.linear_acceleration_mps2[:, 2]),
    )
    passes = []

    def first_pass_only(model_params):
        passes.append("calibration" in model_params)
        return "calibration" not in model_params

    profile = calibrate(params, *signals, _marked_unusual(plain, first_pass_only))
    assert passes == [False, True]  # the calibration pass, then the one with the profile
    assert profile.delay_checked_impacts >= timing.min_impacts
    assert profile.delay_unusual_impacts == 0
    assert not profile_says_timing_suspect(with_profile(params, profile), timing)

    offset = calibrate(params, *signals, _marked_unusual(plain, lambda _: True))
    assert offset.delay_unusual_impacts == offset.delay_checked_impacts >= timing.min_impacts
    assert profile_says_timing_suspect(with_profile(params, offset), timing)

    agreeing = []
    calibrate(params, *signals, lambda p: agreeing.append(p) or plain(p))
    assert len(agreeing) == 1  # clocks that agree at the first pass cost no second one


def test_a_dense_flows_imu_gain_is_read_from_the_impacts_no_other_crowds(params):
    """On a lightly damped support (the flow set's foreign-1: first mode 178 Hz, 0.8 %) a flow of
    20 lumps/s rings under every impact. Read from the impacts with no other onset in their own
    reads' windows (gain_impacts) the IMU gain puts the beam's inertia within 10 % of the
    support's; the hysteresis is read from those impacts too. Read from every impact it is
    within 15 % with the velocity steps fitted jointly with the other impacts'
    (impulse_neighbour_fit), and below 0.75 of it with one step per fit, whose background
    holds the earlier impacts' kicks."""
    from tail_beam_id.calibration.offline import _hysteresis_weights, gain_impacts
    from tail_beam_id.study.flow import FlowRecording, record_sim_flow
    from tail_beam_id.study.flow_evaluation import FLOW_SEED, flow_supports, identify_flow

    name, draw = flow_supports(params, 1, FLOW_SEED)[1]
    assert name == "foreign-1" and draw.values["damping_ratio"] < 0.01
    flow = record_sim_flow(params, 20.0, 5.0, 0.0, 0.0, 0.0, seed=4711, support=draw)
    support = flow.params["support"]
    # the inertia a gain gives at config/'s IMU distance (calibrate's convention)
    target = (
        support["beam_inertia_about_hinge_kgm2"]
        / support["imu_from_hinge_m"]
        * params["support"]["imu_from_hinge_m"]
    )
    passes, models = [], []

    def identify(model_params):
        labels = identify_flow(flow, "shipped", "statistical", model_params)[0]
        passes.append(labels)
        models.append(model_params)
        return labels

    profile = calibrate(
        params,
        (flow.pressure.stamp_s, flow.pressure.pressure_pa),
        (flow.imu.stamp_s, flow.imu.linear_acceleration_mps2[:, 2]),
        identify,
        (flow.vibration.sample_stamps_s(), flow.vibration.accel_mps2),
        [r.stamp_s for r in flow.rebounds],
    )
    assert profile.beam_inertia_about_hinge_kgm2 == pytest.approx(target, rel=0.1)
    chosen = gain_impacts(params, passes[0])
    assert profile.impacts_used <= len(chosen) < len(passes[0])
    # the support's hysteresis is read from the same impacts (every one would give 18 here)
    _, weighed, _ = _hysteresis_weights(
        params, chosen, profile.beam_inertia_about_hinge_kgm2, None
    )
    assert profile.hysteresis_impacts == weighed
    imu_from_hinge = params["support"]["imu_from_hinge_m"]
    crowded = imu_gain([label.features for label in passes[0]])
    assert crowded is not None
    assert crowded[0] * imu_from_hinge == pytest.approx(target, rel=0.15)
    alone = dict(flow.params)
    alone["identification"] = {**alone["identification"], "impulse_neighbour_fit": False}
    single = identify_flow(
        FlowRecording(**{**flow.__dict__, "params": alone}), "shipped", "statistical", models[0]
    )[0]
    crowded = imu_gain([label.features for label in single])
    assert crowded is not None
    assert crowded[0] * imu_from_hinge < 0.75 * target


@pytest.mark.parametrize(
    ("field", "value", "allowed"),
    [
        ("rigid_mode_frequency_hz", float("nan"), r"must be in \(0, 1000\] Hz"),
        ("rigid_mode_frequency_hz", "abc", r"must be in \(0, 1000\] Hz"),
        ("rigid_mode_frequency_hz", [39.0, 40.0], r"must be in \(0, 1000\] Hz"),
        ("camera_frame_rate_hz", 1e-300, r"must be in \[1, 1e\+06\] Hz"),
        ("beam_inertia_about_hinge_kgm2", 1e-300, r"must be in \[1, 1e\+06\] kg m\^2"),
        ("ringing_modes_hz", [float("nan")], "must be a list of finite numbers"),
        ("delay_unusual_impacts", 12, r"must be an integer in \[0, 10\]"),
    ],
)
def test_a_hand_edited_profile_with_an_implausible_field_is_refused_by_name(
    params, field, value, allowed
):
    """A profile field that no measurement gives (NaN, text, a list, a rate of 1e-300, more
    unusual delays than checked ones) is refused naming the field and its range, instead of
    marking the labels calibrated or dividing by it."""
    profile = {"rigid_mode_frequency_hz": 39.3, "delay_checked_impacts": 10, field: value}
    with pytest.raises(InputError, match=rf"calibration\.{field} = .*: {allowed}"):
        StreamIdentifier(
            "statistical",
            params=params["identification"],
            model_params={**params, "calibration": profile},
        )


@pytest.mark.parametrize(
    ("section", "field"),
    [
        ("support", "beam_inertia_about_hinge_kgm2"),
        ("sensors", "camera_frame_rate_hz"),
    ],
)
def test_a_vanishing_support_or_camera_setting_is_refused_by_name(params, section, field):
    """A beam inertia or camera frame rate of 1e-300 in the parameters (a profile merged into
    them, or a hand-edited file) is refused naming the field, not taken as a real support."""
    broken = {**params, section: {**params[section], field: 1e-300}}
    with pytest.raises(InputError, match=rf"{section}\.{field} = 1e-300: must be (>=|in \[)"):
        StreamIdentifier("statistical", params=params["identification"], model_params=broken)


def test_a_measured_profile_still_marks_the_labels_calibrated(params):
    """The check refuses only the implausible: a profile as tail-beam calibrate writes it (a
    sway frequency, a camera rate) is taken, and the identifier says it is calibrated."""
    profile = {"rigid_mode_frequency_hz": 39.3, "camera_frame_rate_hz": 5000.0}
    identifier = StreamIdentifier(
        "statistical",
        params=params["identification"],
        model_params={**params, "calibration": profile},
    )
    assert identifier.calibrated
    assert not StreamIdentifier(
        "statistical", params=params["identification"], model_params=params
    ).calibrated


def test_a_sensors_section_given_as_one_value_is_refused_by_name(params):
    """``sensors: 5`` in a parameter file is refused naming the section, not an AttributeError
    where the identifier reads the camera's configured frame rate."""
    with pytest.raises(InputError, match="sensors = 5: must be a parameter section"):
        StreamIdentifier(
            "statistical", params=params["identification"], model_params={**params, "sensors": 5}
        )
