"""The beam's bending modes read from its ringing after impacts (self-calibration:
"the beam's modes and their damping from the ringing, so that ringing is never taken for an
impact"): against ring-downs of known modes, and against the eigenvalues of the simulated
structure that rang."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tail_beam_id.calibration.modes import RingingMode, ring_decay_s, ringing_modes
from tail_beam_id.calibration.offline import SupportProfile, calibrate, with_profile
from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.replay import replay
from tail_beam_id.study.dataset import settings, support_streams
from tail_beam_sim.physics.fidelity import TIERS, FidelitySettings, structure_for
from tail_beam_sim.physics.materials import material_table
from tail_beam_sim.physics.support import Support

RATE_HZ = 25600.0


def _synthetic(
    modes: list[tuple[float, float]], onsets_s: np.ndarray, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """An accelerometer's samples (+g at rest, a 40 Hz sway, 0.05 m/s^2 noise) in which each
    impact at ``onsets_s`` sets the modes (Hz, damping ratio) ringing with random amplitudes
    and phases: the free ring-down a modal beam gives, in closed form."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, onsets_s[-1] + 0.4, 1.0 / RATE_HZ)
    accel = 9.81 + 0.05 * rng.standard_normal(t.size) + 0.3 * np.sin(2 * np.pi * 40.0 * t)
    for onset in onsets_s:
        after = t >= onset
        tau = t[after] - onset
        for frequency, zeta in modes:
            omega = 2 * np.pi * frequency
            amplitude = rng.uniform(2.0, 20.0)
            accel[after] += (
                amplitude
                * np.exp(-zeta * omega * tau)
                * np.sin(omega * math.sqrt(1 - zeta**2) * tau + rng.uniform(0, 2 * np.pi))
            )
    return t, accel


def test_ring_downs_of_known_modes_give_their_frequencies_and_damping():
    """Two modes of known frequency and damping, rung by 12 impacts 0.3-0.45 s apart over a
    swaying beam: found within 1 % in frequency and 10 % in damping, and the detector's decay
    time is the slower mode's 1 / (zeta 2 pi f)."""
    truth = [(450.0, 0.01), (1700.0, 0.03)]
    onsets = 0.2 + np.cumsum(np.random.default_rng(1).uniform(0.3, 0.45, 12))
    found = ringing_modes(*_synthetic(truth, onsets), onsets)
    assert len(found) == 2, found
    for mode, (frequency, zeta) in zip(found, truth):
        assert mode.frequency_hz == pytest.approx(frequency, rel=0.01)
        assert mode.damping_ratio == pytest.approx(zeta, rel=0.10)
    assert ring_decay_s(found) == pytest.approx(1.0 / (0.01 * 2 * np.pi * 450.0), rel=0.10)


def test_a_lightly_damped_low_mode_gives_a_long_ring_decay():
    """A 120 Hz mode at 0.5 % damping rings for 0.27 s (1 / (zeta 2 pi f)): the detector is told
    so (the shipped 12 ms would let its envelope die 20 times too fast)."""
    onsets = 0.2 + np.cumsum(np.full(8, 0.35))
    found = ringing_modes(*_synthetic([(120.0, 0.005)], onsets, seed=3), onsets)
    assert [round(m.frequency_hz) for m in found] == pytest.approx([120], abs=2)
    assert ring_decay_s(found) == pytest.approx(1.0 / (0.005 * 2 * np.pi * 120.0), rel=0.15)


def test_too_few_impacts_or_no_ringing_measure_no_mode():
    """Two impacts are too few; a beam that does not ring (noise and sway only) has no mode."""
    onsets = np.array([0.3, 0.7])
    assert ringing_modes(*_synthetic([(450.0, 0.01)], onsets), onsets) == []
    onsets = 0.2 + np.cumsum(np.full(10, 0.3))
    assert ringing_modes(*_synthetic([], onsets), onsets) == []
    assert ring_decay_s([]) is None


@pytest.fixture(scope="module")
def streams(params):
    """Three foreign supports with the shipped sensors (the 25.6 kHz accelerometer), 12 impacts
    each."""
    shipped = settings(params, [1.0], ["shipped"])[0]
    return list(support_streams(params, 3, 12, seed=41004, setting=shipped))


def _coupled_modes(recorded) -> list[tuple[float, float]]:
    """The recorded support's bending modes (Hz, damping ratio) from the eigenvalues of its
    structure: the coupled modes the accelerometer sees, jack damping included."""
    support = Support.from_params(recorded.params["support"], material_table(recorded.params))
    structure = structure_for(
        TIERS["modal"], support, FidelitySettings.from_params(recorded.params).modes
    )
    eigen = structure._eigen[0]
    eigen = eigen[eigen.imag > 0]
    modes = sorted((float(abs(e.imag)) / (2 * np.pi), float(-e.real / abs(e))) for e in eigen)
    return modes[1:]  # the first is the sway on the oil column


def test_the_modes_read_from_a_simulated_support_are_its_structures(params, streams):
    """Every mode read from a simulated support's ringing is one of its structure's coupled
    bending modes (within 1 % in frequency, 15 % in damping): none is made up; and a mode that
    rings for 5 ms or more within the accelerometer's band is found."""
    for recorded in streams:
        v = recorded.vibration
        onsets = [truth["contact_start_stamp"] for truth in recorded.truths]
        found = ringing_modes(v.sample_stamps_s(), v.accel_mps2, onsets)
        coupled = _coupled_modes(recorded)
        for mode in found:
            frequency, zeta = min(coupled, key=lambda m: abs(m[0] - mode.frequency_hz))
            assert mode.frequency_hz == pytest.approx(frequency, rel=0.01), (
                recorded.support.describe(),
                found,
                coupled,
            )
            assert mode.damping_ratio == pytest.approx(zeta, rel=0.15), (
                recorded.support.describe(),
                found,
                coupled,
            )
        lasting = [
            f for f, z in coupled if f < 0.4 / v.period_s and 1.0 / (z * 2 * np.pi * f) >= 0.005
        ]
        for frequency in lasting:
            assert any(abs(m.frequency_hz - frequency) < 0.01 * frequency for m in found), (
                recorded.support.describe(),
                found,
                coupled,
            )


def test_self_calibration_hands_the_ringing_to_the_detector(params, streams):
    """calibrate() measures the modes from the accelerometer it is given, the profile sets
    identification.detection.ring_decay_s to the slowest one's decay time, and an identifier
    built on the profile (offline) or recalibrated with it (id_node online) follows the
    ringing for that long."""
    recorded = next(r for r in streams if r.vibration is not None)
    v = recorded.vibration

    def identify(model_params):
        return replay(
            StreamIdentifier("statistical", model_params["identification"], model_params),
            recorded.pressure,
            recorded.imu,
            recorded.rebounds,
            vibration=v,
        )

    profile = calibrate(
        params,
        (recorded.pressure.stamp_s, recorded.pressure.pressure_pa),
        (recorded.imu.stamp_s, recorded.imu.linear_acceleration_mps2[:, 2]),
        identify,
        (v.sample_stamps_s(), v.accel_mps2),
    )
    assert profile.ringing_modes_hz and profile.ring_decay_s is not None
    expected = ring_decay_s(
        [
            RingingMode(f, z, 0)
            for f, z in zip(profile.ringing_modes_hz, profile.ringing_damping_ratios)
        ]
    )
    assert profile.ring_decay_s == expected
    assert profile.ring_decay_s != params["identification"]["detection"]["ring_decay_s"]
    merged = with_profile(params, profile)
    assert merged["identification"]["detection"]["ring_decay_s"] == profile.ring_decay_s
    offline = StreamIdentifier("statistical", merged["identification"], merged)
    assert (
        offline.detector.config.ring_decay_s
        == offline.vibration_detector.config.ring_decay_s
        == profile.ring_decay_s
    )
    online = StreamIdentifier("statistical", params["identification"], params)
    online.recalibrate(merged)
    assert online.vibration_detector.config.ring_decay_s == profile.ring_decay_s
    assert "Hz (" in profile.describe_modes()


def test_a_profile_without_modes_leaves_the_detector_as_configured(params):
    """No mode measured: the profile says nothing of the detector (config/'s ring_decay_s
    holds)."""
    profile = SupportProfile(
        duration_s=5.0,
        impacts_used=0,
        imu_mount_sign=1.0,
        rigid_mode_frequency_hz=39.0,
        oil_bulk_modulus_pa=1.9e9,
        beam_inertia_about_hinge_kgm2=None,
        imu_gain_spread=None,
        pressure_noise_pa=1e4,
        imu_accel_noise_mps2=0.05,
    )
    assert "identification" not in profile.parameters()["/**"]["ros__parameters"]
    assert profile.describe_modes() == "no bending mode measured in the ringing"
