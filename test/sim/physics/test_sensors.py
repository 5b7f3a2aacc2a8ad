"""The sensor models: seeded reproducibility, noise level, the IMU's sample mean or low-pass,
saturation."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from scipy import signal
from scipy.integrate import cumulative_trapezoid

from tail_beam_sim.config import deep_merge, load_parameters
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.sensors import imu_samples
from tail_beam_sim.physics.simulate import simulate


def test_same_seed_same_streams_other_seed_other_noise(params):
    """The same seed gives bit-identical pressure, IMU and rebound readings; another seed other
    pressure noise."""
    a = simulate(Scene.from_params(params, {"seed": 7}))
    b = simulate(Scene.from_params(params, {"seed": 7}))
    c = simulate(Scene.from_params(params, {"seed": 8}))
    assert np.array_equal(a.pressure.pressure_pa, b.pressure.pressure_pa)
    assert np.array_equal(a.imu.linear_acceleration_mps2, b.imu.linear_acceleration_mps2)
    assert np.array_equal(a.rebound.velocity_mps, b.rebound.velocity_mps)
    assert not np.array_equal(a.pressure.pressure_pa, c.pressure.pressure_pa)


def test_noise_rms_matches_configuration(params):
    """Residuals of the sampled streams about the noise-free model have the configured RMS
    (2000 samples: the sample standard deviation is within 2 % at one sigma)."""
    scene = Scene.from_params(params, {"window_s": 1.0})
    result = simulate(scene)
    trajectory = result.trajectory
    stamps = result.pressure.stamp_s
    state = trajectory.sample(stamps - result.contact_stamp_s)
    clean = trajectory.problem.structure.pressure_pa(state.q, state.qd)
    assert np.std(result.pressure.pressure_pa - clean) == pytest.approx(
        scene.sensors.pressure_noise_pa, rel=0.1
    )

    gyro, accel = imu_samples(
        trajectory, result.imu.stamp_s - result.contact_stamp_s, 1.0 / scene.sensors.imu_rate_hz
    )
    assert np.std(result.imu.linear_acceleration_mps2[:, 2] - accel[:, 2]) == pytest.approx(
        scene.sensors.imu_accel_noise_mps2, rel=0.1
    )
    assert np.std(result.imu.angular_velocity_radps[:, 1] - gyro[:, 1]) == pytest.approx(
        scene.sensors.imu_gyro_noise_radps, rel=0.1
    )
    assert np.all(result.imu.angular_velocity_radps[:, [0, 2]] != 0.0)  # every axis carries noise


def test_imu_sample_is_the_mean_over_its_period(params):
    """Each noise-free IMU sample equals the time average of the instantaneous specific force over
    the preceding sample period, integrated numerically from the dense history (contact
    included)."""
    scene = Scene.from_params(params)
    result = simulate(scene)
    h = result.history
    period = 1.0 / scene.sensors.imu_rate_hz
    t = h["time_s"]
    integral = cumulative_trapezoid(h["imu_specific_force_mps2"], t, initial=0.0)
    ends = np.arange(2, 60) * period  # sample instants after first contact, covering it
    mean_numeric = (np.interp(ends, t, integral) - np.interp(ends - period, t, integral)) / period
    _, accel = imu_samples(result.trajectory, ends, period)
    scale = np.max(np.abs(h["imu_dynamic_accel_mps2"]))
    assert np.max(np.abs(accel[:, 2] - mean_numeric)) < 1e-3 * scale
    # At rest the accelerometer reads +g along the plate's upward axis (REP 145 specific force).
    gyro_rest, accel_rest = imu_samples(result.trajectory, np.array([-2 * period]), period)
    assert accel_rest[0, 2] == pytest.approx(scene.support.gravity_mps2, rel=1e-9)
    assert gyro_rest[0, 1] == 0.0


def test_saturated_pressure_transducer_reads_its_limit():
    """A transducer whose range ends below the setting pressure reads its upper limit."""
    params = deep_merge(load_parameters(), {"sensors": {"pressure_range_max_pa": 19.0e6}})
    result = simulate(Scene.from_params(params))
    assert np.all(result.pressure.pressure_pa == 19.0e6)


def test_imu_noise_grows_with_sqrt_of_rate():
    """Noise is specified at the nominal rate; at 4x the rate (4x bandwidth) the RMS doubles.
    Measured on the x axis far from the impact, where the noise-free reading is ~0."""
    params = deep_merge(load_parameters(), {"sensors": {"imu_rate_hz": 8000.0}})
    scene = Scene.from_params(params, {"window_s": 0.25})
    accel_x = simulate(scene).imu.linear_acceleration_mps2[:, 0]
    assert np.std(accel_x) == pytest.approx(2.0 * scene.sensors.imu_accel_noise_mps2, rel=0.1)


def test_a_site_without_the_accelerometer_has_the_same_other_streams(params):
    """simulate(vibration=False) (a site without the tail-beam accelerometer: what the IMU-only
    training and evaluation settings simulate) gives no blocks and, sample for sample, the same
    pressure, IMU and rebound as with it: the accelerometer draws its noise last and alone."""
    scene = Scene.from_params(params, {"material": "marble", "radius_m": 0.04, "window_s": 0.05})
    with_it, without = (
        simulate(scene, tier="modal"),
        simulate(scene, tier="modal", vibration=False),
    )
    assert with_it.vibration.count > 0 and without.vibration.count == 0
    np.testing.assert_array_equal(with_it.pressure.pressure_pa, without.pressure.pressure_pa)
    np.testing.assert_array_equal(
        with_it.imu.linear_acceleration_mps2, without.imu.linear_acceleration_mps2
    )
    np.testing.assert_array_equal(with_it.rebound.velocity_mps, without.rebound.velocity_mps)
    assert with_it.rebound.stamp_s == without.rebound.stamp_s


def _low_pass_params(params, order: int = 4, rate_hz: float = 5000.0) -> dict:
    quiet = {
        "imu_accel_noise_mps2": 0.0,
        "imu_gyro_noise_radps": 0.0,
        "imu_rate_hz": rate_hz,
        "imu_antialias_order": order,
    }
    return deep_merge(copy.deepcopy(params), {"sensors": quiet})


def test_an_imu_behind_a_low_pass_reads_the_analog_filter_of_the_beams_response(params):
    """sensors.imu_antialias_order 4: each noise-free sample is the beam's specific force and
    pitch rate through a 4th-order Butterworth low-pass at 0.25 x the rate, read at the sample
    instant. Reference: the continuous-time Butterworth prototype (scipy.signal.lsim) run on the
    instantaneous response sampled every 2 us, independent of the simulator's digital filter on
    4 dense values per sample; they agree within 3 % of the pulse's peak (the digital filter's
    bilinear warping at 1/16 of its rate and its dense means). At rest it reads +g (unit gain)."""
    scene = Scene.from_params(_low_pass_params(params))
    result = simulate(scene)
    rate = scene.sensors.imu_rate_hz
    stamps = result.imu.stamp_s - result.contact_stamp_s
    fine = np.arange(stamps[0], stamps[-1] + 1e-9, 2e-6)
    state = result.trajectory.sample(fine)
    structure = result.trajectory.problem.structure
    force = (
        structure.gravity_mps2 * np.cos(structure.imu_slope_shape @ state.q)
        - structure.imu_shape @ state.qdd
    )
    pitch_rate = structure.imu_slope_shape @ state.qd
    b, a = signal.butter(4, 2 * np.pi * 0.25 * rate, analog=True)
    picked = np.searchsorted(fine, stamps - 1e-9)
    for reading, signal_in in (
        (result.imu.linear_acceleration_mps2[:, 2], force),
        (result.imu.angular_velocity_radps[:, 1], pitch_rate),
    ):
        start = signal_in[0]
        _, reference, _ = signal.lsim((b, a), signal_in - start, fine - fine[0])
        expected = reference[picked] + start
        swing = np.max(np.abs(expected - start))
        assert swing > 0.0 and np.max(np.abs(reading - expected)) < 0.03 * swing
    assert result.imu.linear_acceleration_mps2[0, 2] == pytest.approx(
        scene.support.gravity_mps2, rel=1e-9
    )


def test_the_low_pass_delays_the_contacts_pulse_by_its_group_delay(params):
    """On the rigid beam (no bending modes ringing after it), the contact pulse's centre (the
    centroid of the specific force's deviation over the first 3 ms) comes later behind the
    low-pass than in the period means, by the filter's low-frequency group delay (1.6 samples
    for a 4th-order Butterworth at 0.25 x the rate) less the half sample a period mean lags its
    instant: to within a fifth of a sample."""
    rate = 5000.0
    centres = []
    for order in (0, 4):
        result = simulate(Scene.from_params(_low_pass_params(params, order, rate)), tier="rigid")
        t = result.imu.stamp_s - result.contact_stamp_s
        window = (t > -1e-3) & (t < 3e-3)
        deviation = np.abs(
            result.imu.linear_acceleration_mps2[window, 2]
            - result.imu.linear_acceleration_mps2[0, 2]
        )
        centres.append(np.sum(t[window] * deviation) / np.sum(deviation))
    b, a = signal.butter(4, 0.25 * rate, fs=4 * rate)
    _, delay = signal.group_delay((b, a), w=[10.0], fs=4 * rate)
    expected_s = delay[0] / (4 * rate) - 0.5 / rate
    assert centres[1] - centres[0] == pytest.approx(expected_s, abs=0.2 / rate)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("imu_antialias_order", 11),
        ("imu_antialias_order", 1.5),
        ("imu_antialias_cutoff_fraction", 0.6),
        ("imu_oversample", 1),
    ],
)
def test_a_bad_imu_filter_setting_is_refused_by_name(params, field, value):
    """Out of range (order 0-10, cut-off in (0, 0.5] of the rate, oversample 2-32): refused
    naming the field."""
    bad = deep_merge(copy.deepcopy(params), {"sensors": {field: value}})
    with pytest.raises(InputError, match=f"sensors.{field}"):
        Scene.from_params(bad)
