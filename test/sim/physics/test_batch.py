"""The vectorised batch path against the single-impact solvers (an independent implementation
of the same physics), its streams against the sensors' own sampling, and its input checks."""

from __future__ import annotations

import numpy as np
import pytest

from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.batch import ImpactBatch, streams, summaries
from tail_beam_sim.physics.fidelity import TIERS, shipped_settings, structure_for
from tail_beam_sim.physics.scene import Impact, Scene
from tail_beam_sim.physics.sensors import imu_samples
from tail_beam_sim.physics.simulate import build_problem
from tail_beam_sim.physics.solvers import solve

KEYS = (
    "rebound_speed_mps",
    "contact_duration_s",
    "peak_contact_force_n",
    "peak_jack_pressure_change_pa",
)


def _random_impacts(scene: Scene, count: int, seed: int) -> list[Impact]:
    rng = np.random.default_rng(seed)
    impacts = []
    for _ in range(count):
        material = scene.materials[str(rng.choice(["coal", "mudstone", "sandstone", "marble"]))]
        impacts.append(
            Impact(
                material,
                float(rng.uniform(0.015, 0.04)),
                float(rng.uniform(5.0, 9.0)),
                float(rng.uniform(0.1, 1.5)),
                float(rng.uniform(*material.restitution_range)),
            )
        )
    return impacts


@pytest.mark.parametrize("tier", ["rigid", "modal"])
def test_batch_summaries_agree_with_the_hybrid_solver_impact_by_impact(default_scene, tier):
    """Random sizes, speeds, positions, materials and restitutions: within 2e-3 of the hybrid
    solver (with RK4 through the contact, so not sharing the batch's pulse table)."""
    scene = default_scene
    structure = structure_for(TIERS[tier], scene.support, shipped_settings().modes)
    impacts = _random_impacts(scene, 8, seed=3)
    batch = ImpactBatch.from_impacts(scene.support, scene.materials, impacts)
    result = summaries(scene.support, structure, batch, scene.contact_model, scene.window_s)
    for k, impact in enumerate(impacts):
        problem = build_problem(
            scene.support, impact, scene.contact_model, scene.window_s, structure=structure
        )
        trajectory = solve(problem, "hybrid", contact="rk4", steps_per_contact=96)
        times = np.linspace(0.0, scene.window_s, 20001)
        state = trajectory.sample(times)
        reference = {
            "rebound_speed_mps": trajectory.rebound_velocity_mps,
            "contact_duration_s": trajectory.contacts[0].duration_s,
            "peak_contact_force_n": trajectory.contacts[0].peak_force_n,
            "peak_jack_pressure_change_pa": float(np.max(structure.pressure_pa(state.q, state.qd)))
            - structure.setting_pressure_pa,
        }
        for key in KEYS:
            assert result[key][k] == pytest.approx(reference[key], rel=2e-3), (k, key)
        assert not result["recontact_possible"][k]


def test_batch_streams_match_the_sensors_sampling_of_a_solved_impact(default_scene):
    """Noise-free batch streams of one impact against sampling its hybrid trajectory at the same
    stamps the way SensorSuite does (pressure point samples, IMU means over the period)."""
    scene = default_scene
    structure = structure_for(TIERS["modal"], scene.support, shipped_settings().modes)
    impact = scene.impact
    batch = ImpactBatch.from_impacts(scene.support, scene.materials, [impact])
    quiet = scene.sensors.scaled_noise(0.0)
    out = streams(scene.support, structure, batch, quiet, scene.contact_model, scene.window_s)
    trajectory = solve(
        build_problem(
            scene.support, impact, scene.contact_model, scene.window_s, structure=structure
        )
    )
    offset = out["contact_offset_s"][0]
    state = trajectory.sample(out["pressure_time_s"] - offset)
    pressure = structure.pressure_pa(state.q, state.qd) - structure.setting_pressure_pa
    batch_pressure = out["pressure_pa"][0] - structure.setting_pressure_pa
    assert np.linalg.norm(batch_pressure - pressure) < 2e-3 * np.linalg.norm(pressure)
    stamps = out["imu_time_s"]
    gyro, accel = imu_samples(trajectory, stamps - offset, 1.0 / quiet.imu_rate_hz)
    # Exact once an averaging period no longer holds any of the contact (the batch does not
    # resolve the 0.2 ms inside it): compare those samples tightly, the rest loosely.
    after = stamps - 1.0 / quiet.imu_rate_hz >= offset + trajectory.contacts[0].duration_s
    dynamic = accel[:, 2] - structure.gravity_mps2
    mine = out["imu_accel_mps2"][0, :, 2] - structure.gravity_mps2
    assert np.linalg.norm((mine - dynamic)[after]) < 2e-3 * np.linalg.norm(dynamic[after])
    assert np.linalg.norm(mine - dynamic) < 0.1 * np.linalg.norm(dynamic)
    assert np.linalg.norm(
        (out["imu_gyro_radps"][0, :, 1] - gyro[:, 1])[after]
    ) < 2e-3 * np.linalg.norm(gyro[after, 1])


def test_batch_stream_noise_has_the_configured_rms(default_scene):
    """The batch streams' pressure noise (noisy minus noise-free, same seed) has the configured
    RMS within 2 %."""
    scene = default_scene
    structure = structure_for(TIERS["rigid"], scene.support, ())
    impacts = _random_impacts(scene, 200, seed=5)
    batch = ImpactBatch.from_impacts(scene.support, scene.materials, impacts)
    noisy = streams(scene.support, structure, batch, scene.sensors, seed=1)
    clean = streams(scene.support, structure, batch, scene.sensors.scaled_noise(0.0), seed=1)
    residual = noisy["pressure_pa"] - clean["pressure_pa"]
    assert np.std(residual) == pytest.approx(scene.sensors.pressure_noise_pa, rel=0.02)


def test_low_speed_impacts_are_flagged_for_a_possible_re_contact(default_scene):
    """A 0.25 m/s impact is flagged for a possible re-contact (and the hybrid solver indeed
    finds more than one contact); an 8 m/s one is not."""
    scene = default_scene
    structure = structure_for(TIERS["rigid"], scene.support, ())
    batch = ImpactBatch.from_arrays(
        scene.support,
        scene.materials,
        ["coal", "coal"],
        np.array([0.025, 0.025]),
        np.array([0.25, 8.0]),
        np.array([1.0, 1.0]),
    )
    flags = summaries(scene.support, structure, batch)["recontact_possible"]
    assert flags.tolist() == [True, False]
    assert (
        len(
            solve(
                build_problem(
                    scene.support,
                    scene.impact.__class__(scene.materials["coal"], 0.025, 0.25, 1.0, 0.68),
                    scene.contact_model,
                    scene.window_s,
                )
            ).contacts
        )
        > 1
    )


def test_batch_input_errors_name_the_field_and_the_impact(default_scene):
    """A bad radius, material or position in a batch is an InputError naming the field and the
    index of the first bad impact."""
    scene = default_scene
    with pytest.raises(InputError, match=r"radius_m\[1\]"):
        ImpactBatch.from_arrays(
            scene.support,
            scene.materials,
            ["coal", "coal"],
            np.array([0.02, -1.0]),
            np.array([5.0, 5.0]),
            np.array([1.0, 1.0]),
        )
    with pytest.raises(InputError, match="material"):
        ImpactBatch.from_arrays(
            scene.support,
            scene.materials,
            ["cheese"],
            np.array([0.02]),
            np.array([5.0]),
            np.array([1.0]),
        )
    with pytest.raises(InputError, match=r"position_m\[0\]"):
        ImpactBatch.from_arrays(
            scene.support,
            scene.materials,
            ["coal"],
            np.array([0.02]),
            np.array([5.0]),
            np.array([9.0]),
        )


def test_batch_summaries_follow_the_supports_contact_damping_scale(default_scene):
    """A support whose contacts dissipate twice what the law says (contact_damping_scale 2): the
    batch path and the solver still agree impact by impact, and every rebound is slower than on
    the support with the law as published (more hysteresis)."""
    from dataclasses import replace

    scene = default_scene
    damped = replace(scene.support, contact_damping_scale=2.0)
    structure = structure_for(TIERS["rigid"], damped, shipped_settings().modes)
    impacts = _random_impacts(scene, 4, seed=5)
    result = summaries(
        damped,
        structure,
        ImpactBatch.from_impacts(damped, scene.materials, impacts),
        "hunt_crossley",
        scene.window_s,
    )
    published = summaries(
        scene.support,
        structure_for(TIERS["rigid"], scene.support, shipped_settings().modes),
        ImpactBatch.from_impacts(scene.support, scene.materials, impacts),
        "hunt_crossley",
        scene.window_s,
    )
    for k, impact in enumerate(impacts):
        trajectory = solve(
            build_problem(damped, impact, "hunt_crossley", scene.window_s, structure=structure),
            "hybrid",
            contact="rk4",
            steps_per_contact=96,
        )
        assert result["rebound_speed_mps"][k] == pytest.approx(
            trajectory.rebound_velocity_mps, rel=2e-3
        )
        assert result["rebound_speed_mps"][k] < published["rebound_speed_mps"][k]
