"""The fast simulate path: every sensor read from one sampling of the trajectory, the plan's
settings-only part cached, the free response in real arithmetic over half the spectrum, and
simulate_many solving each distinct impact once, all giving what the direct computations
give."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from same_result import assert_same_result

from tail_beam_sim.physics import fidelity
from tail_beam_sim.physics.fidelity import (
    PHASES,
    TIERS,
    model_errors,
    plan,
    shipped_settings,
    structure_for,
    unit_responses,
)
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.sensors import SensorSuite
from tail_beam_sim.physics.simulate import histories, sense_general, simulate, simulate_many
from tail_beam_sim.physics.structure import LinearStructure
from tail_beam_sim.physics.support import support_indices

FIELDS = ("t_s", "q", "qd", "qdd", "force_n", "z_m", "zd_mps")


def _scene(params: dict, **impact: float | str) -> Scene:
    return Scene.from_params(params, {"material": "coal", "radius_m": 0.05, **impact})


@pytest.mark.parametrize("tier", ["rigid", "modal"])
def test_sample_many_equals_sampling_each_set_on_its_own(params, tier):
    """Trajectory.sample_many gives, bit for bit, what sampling each set of times alone gives,
    for sets in any order spanning rest, contact and free flight."""
    trajectory = simulate(_scene(params), tier=tier).trajectory
    rng = np.random.default_rng(3)
    contact = trajectory.contacts[0]
    parts = [
        rng.uniform(-0.005, 0.05, 300),  # unordered, every segment
        np.linspace(contact.start_s, contact.end_s, 17),  # within the contact
        np.arange(-0.002, 0.05, 1e-5),
        np.array([0.01]),
        np.empty(0),
    ]
    together = trajectory.sample_many(parts)
    for times, joint in zip(parts, together):
        alone = trajectory.sample(times)
        for name in FIELDS:
            assert np.array_equal(getattr(joint, name), getattr(alone, name)), name


@pytest.mark.parametrize("tier", ["rigid", "auto"])
def test_general_sensing_equals_each_sensor_sampling_on_its_own(params, tier):
    """The general path's streams and histories, read from one sampling of the trajectory, are
    bit for bit those each sensor makes sampling the trajectory on its own (same seeds)."""
    scene = _scene(params, material="sandstone", radius_m=0.03, position_m=0.7, seed=5)
    result = sense_general(scene, simulate(scene, tier=tier).trajectory)
    trajectory, stamp = result.trajectory, result.contact_stamp_s
    suite = SensorSuite(scene.sensors)
    pressure = suite.pressure(trajectory, result.pressure.stamp_s, stamp)
    imu = suite.imu(trajectory, result.imu.stamp_s, stamp)
    vibration = suite.vibration(trajectory, stamp + scene.window_s, stamp)
    assert np.array_equal(pressure.pressure_pa, result.pressure.pressure_pa)
    assert np.array_equal(imu.angular_velocity_radps, result.imu.angular_velocity_radps)
    assert np.array_equal(imu.linear_acceleration_mps2, result.imu.linear_acceleration_mps2)
    assert vibration.sample_count > 1000
    assert np.array_equal(vibration.accel_mps2, result.vibration.accel_mps2)
    assert np.array_equal(vibration.first_index, result.vibration.first_index)
    alone = histories(scene, trajectory)
    assert alone.keys() == result.history.keys()
    for name, values in alone.items():
        assert np.array_equal(values, result.history[name]), name


def _sampled_difference_directly(
    scene: Scene, rigid: LinearStructure, modal: LinearStructure, output: str
) -> float:
    """The rigid-vs-modal sampled difference computed from scratch: each structure's response
    to the impact's own unit impulse, propagated and sampled as the sensor samples it."""
    spec, x = scene.sensors, scene.impact.position_m
    rate = spec.pressure_rate_hz if output == "pressure" else spec.imu_rate_hz
    count = int(scene.window_s * rate)
    times = ((np.arange(1, count + 1)[None, :] - np.array(PHASES)[:, None]) / rate).ravel()
    signals = []
    for structure in (rigid, modal):
        qd0 = structure.inv_mass @ structure.contact_shape(x)
        zero = np.zeros(structure.size)
        q, qd = structure.propagate(zero, qd0, times)
        if output == "pressure":
            signals.append((structure.pressure_pa(q, qd) - structure.setting_pressure_pa)[None])
            continue
        before_q, before_qd = structure.propagate(zero, qd0, np.maximum(times - 1 / rate, 0))
        before_q[:, times < 1 / rate], before_qd[:, times < 1 / rate] = 0.0, 0.0
        signals.append(
            np.stack(
                [
                    structure.imu_shape @ (qd - before_qd),
                    structure.imu_slope_shape @ (q - before_q),
                ]
            )
            * rate
        )
    lower, upper = (s.reshape(s.shape[0], len(PHASES), count) for s in signals)
    reference = np.sqrt((upper**2).sum(axis=(0, 2)))
    return float(np.max(np.sqrt(((upper - lower) ** 2).sum(axis=(0, 2))) / reference))


@pytest.mark.parametrize("position_m", [0.45, 1.0, 1.35])
def test_cached_plan_equals_a_fresh_one_and_the_direct_estimate(params, position_m):
    """A plan made with the unit responses cached equals one made with the cache emptied, and
    its sampled rigid-vs-modal difference equals the direct computation (each structure's own
    impulse response) to rounding."""
    settings = shipped_settings()
    scene = _scene(params, position_m=position_m)
    fidelity._UNIT_RESPONSES.clear()
    fidelity._GRAMS.clear()
    fidelity._OUTPUT_GRAMS.clear()
    fresh = plan(scene, "auto", settings.needs, settings)
    assert fidelity._UNIT_RESPONSES and fidelity._GRAMS  # the fresh plan filled the caches
    cached = plan(scene, "auto", settings.needs, settings)
    assert cached.estimates == fresh.estimates
    assert cached.tier == fresh.tier and cached.structure is fresh.structure
    rigid = structure_for(TIERS["rigid"], scene.support, settings.modes)
    modal = structure_for(TIERS["modal"], scene.support, settings.modes)
    direct = max(
        _sampled_difference_directly(scene, rigid, modal, output) for output in ("pressure", "imu")
    )
    via_cache = fidelity._sampled_difference(
        scene,
        (rigid, rigid.contact_shape(position_m)),
        (modal, modal.contact_shape(position_m)),
        {"pressure", "imu"},
    )
    assert via_cache == pytest.approx(direct, rel=1e-9)
    assert fresh.estimates["rigid"] >= fidelity.SAMPLED_MARGIN * direct * (1 - 1e-9)


def test_unit_responses_are_kept_per_structure_and_sensor_setting(params):
    """The unit responses are computed once per (structure, output, rate, window): asked again
    they are the same array; another rate or another structure gets its own."""
    settings = shipped_settings()
    scene = _scene(params)
    modal = structure_for(TIERS["modal"], scene.support, settings.modes)
    first = unit_responses(modal, "imu", 2000.0, 0.05)
    assert unit_responses(modal, "imu", 2000.0, 0.05) is first
    assert first.shape == (2, len(PHASES), 100, modal.size)
    other_rate = unit_responses(modal, "imu", 1000.0, 0.05)
    assert other_rate.shape[2] == 50
    heavier = replace(
        scene.support,
        beam_inertia_about_hinge_kgm2=2.0 * scene.support.beam_inertia_about_hinge_kgm2,
    )
    other = structure_for(TIERS["modal"], heavier, settings.modes)
    assert other is not modal
    assert not np.array_equal(unit_responses(other, "imu", 2000.0, 0.05), first)


@pytest.mark.parametrize("tier", ["rigid", "modal"])
def test_propagate_equals_the_complex_exponential_form_for_every_time_alone(params, tier):
    """propagate's real half-spectrum form equals x(t) = Re V exp(Lambda t) V^-1 x0 to
    rounding, and each time's state is the same asked alone or with others (bit for bit)."""
    settings = shipped_settings()
    structure = structure_for(TIERS[tier], _scene(params).support, settings.modes)
    n = structure.size
    rng = np.random.default_rng(1)
    q0, qd0 = rng.normal(size=n) * 1e-4, rng.normal(size=n) * 1e-2
    times = np.linspace(0.0, 0.3, 257)
    q, qd = structure.propagate(q0, qd0, times)
    eigenvalues, vectors, inverse = structure._eigen
    modal = inverse @ np.concatenate([q0, qd0])
    exact = (vectors @ (np.exp(np.outer(eigenvalues, times)) * modal[:, None])).real
    scale = np.abs(exact).max(axis=1, keepdims=True)
    assert np.max(np.abs(np.vstack([q, qd]) - exact) / scale) < 1e-12
    for k in (0, 100, 256):
        q_alone, qd_alone = structure.propagate(q0, qd0, times[k : k + 1])
        assert np.array_equal(q_alone[:, 0], q[:, k]) and np.array_equal(qd_alone[:, 0], qd[:, k])


def test_simulate_many_gives_simulate_results_solving_each_impact_once(params):
    """simulate_many returns what simulate returns for each scene (to 1e-11 of each signal,
    the same noise and accelerometer blocks); scenes that differ only in their sensors (noise,
    seed, rates) share one trajectory, another impact gets its own."""
    base = _scene(params, seed=2)
    louder = replace(base, sensors=replace(base.sensors.scaled_noise(3.0), seed=9))
    faster = replace(base, sensors=replace(base.sensors, pressure_rate_hz=4000.0, seed=4))
    other = _scene(params, material="marble", radius_m=0.04, seed=2)
    scenes = [base, louder, faster, other]
    flags = [True, False, True, True]
    many = simulate_many(scenes, vibration=flags)
    assert many[0].trajectory is many[1].trajectory is many[2].trajectory
    assert many[3].trajectory is not many[0].trajectory
    for scene, flag, result in zip(scenes, flags, many):
        assert_same_result(result, simulate(scene, vibration=flag))
    assert many[1].vibration.count == 0 and many[0].vibration.count > 0
    with pytest.raises(ValueError, match="2 vibration flags for 4 scenes"):
        simulate_many(scenes, vibration=[True, False])


def test_equal_supports_count_as_one_however_many_objects(params):
    """Scenes on equal but distinct support objects share one trajectory in simulate_many; a
    support with a more damped jack is another impact. support_indices gives equal supports one
    index, others the next."""
    base = _scene(params, seed=2)
    twin = replace(base, support=replace(base.support), sensors=replace(base.sensors, seed=3))
    support = base.support
    damped = replace(
        base, support=replace(support, jack_damping_nspm=2.0 * support.jack_damping_nspm)
    )
    many = simulate_many([base, twin, damped])
    assert twin.support is not base.support and twin.support == base.support
    assert many[0].trajectory is many[1].trajectory
    assert many[2].trajectory is not many[0].trajectory
    index = support_indices()
    assert [index(s.support) for s in (base, twin, damped, base)] == [0, 0, 1, 0]


def test_model_errors_depend_on_the_impact_position_through_the_cache(params):
    """The cached settings-only part still lets the estimate follow the impact: two positions
    give different rigid-tier errors (the contact shape enters after the cache)."""
    settings = shipped_settings()
    near = model_errors(_scene(params, position_m=0.45), settings.needs, settings.modes)
    far = model_errors(_scene(params, position_m=1.35), settings.needs, settings.modes)
    assert near["rigid"] != far["rigid"] and near["rigid"] > 0 and far["rigid"] > 0


def test_contact_gradient_is_numpys_bit_for_bit():
    """The contact segments' particle acceleration (problem._gradient) equals np.gradient bit
    for bit, on uniform steps, on uneven ones and on a single step."""
    from tail_beam_sim.physics.solvers.problem import _gradient

    rng = np.random.default_rng(0)
    for t in (
        np.arange(40) * 3e-6 + 1e-3,
        np.cumsum(rng.uniform(1e-6, 5e-6, 40)),
        np.array([0.0, 2e-6]),
    ):
        values = rng.normal(size=t.size)
        assert np.array_equal(_gradient(values, np.diff(t)), np.gradient(values, t))
