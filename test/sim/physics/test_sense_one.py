"""simulate()'s lean path (tail_beam_sim.physics.sense_one) against the general one, which reads
every sensor from the trajectory's own sampling: the same noise, stamps, blocks and summary,
the signals to rounding, over drawn impacts on every tier and solver it covers, single and
repeated contacts, with and without the accelerometer, at equal and unequal sample rates."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from same_result import assert_same_result

from tail_beam_sim.physics import sense_one
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.sensors import SensorSuite
from tail_beam_sim.physics.simulate import sense, sense_general, simulate
from tail_beam_sim.physics.solvers import solve
from tail_beam_sim.physics.solvers.problem import OdeSegment


def _drawn(params: dict, count: int, seed: int) -> list[Scene]:
    """Coal and gangue impacts, 10-120 mm, over the impact zone, each with its own noise seed."""
    rng = np.random.default_rng(seed)
    base = Scene.from_params(params, {})
    scenes = []
    for k in range(count):
        material = base.materials[["coal", "sandstone", "marble", "mudstone"][k % 4]]
        scene = base.with_impact(
            material=material,
            restitution=material.restitution,
            radius_m=float(rng.uniform(0.01, 0.12)),
            position_m=float(rng.uniform(0.2, 1.5)),
        )
        scenes.append(replace(scene, sensors=replace(scene.sensors, seed=k)))
    return scenes


@pytest.mark.parametrize("tier", ["rigid", "modal", "impulse", "brittle"])
def test_lean_sensing_equals_the_general_sensing(params, tier):
    """Drawn impacts: the lean path (the one simulate takes) gives the general path's results,
    with and without the accelerometer."""
    for scene in _drawn(params, 6, seed=len(tier)):
        trajectory = simulate(scene, tier=tier).trajectory
        assert sense_one.covers(scene, trajectory)
        for vibration in (True, False):
            lean = sense(scene, trajectory, vibration)
            assert_same_result(lean, sense_general(scene, trajectory, vibration))
            assert lean.vibration.count > 0 if vibration else lean.vibration.count == 0


@pytest.mark.parametrize("tier", ["rigid", "modal", "impulse"])
def test_lean_sensing_of_repeated_contacts(params, tier):
    """A large particle dropped from low on the beam's tip strikes it several times: every
    contact and free flight in between is read where it lies."""
    scene = Scene.from_params(
        params,
        {"material": "sandstone", "radius_m": 0.2, "position_m": 1.5, "drop_height_m": 0.05},
    )
    trajectory = simulate(scene, tier=tier).trajectory
    assert len(trajectory.contacts) >= 3
    assert_same_result(sense(scene, trajectory), sense_general(scene, trajectory))


def test_lean_sensing_at_unequal_rates_with_the_impact_point(params):
    """Pressure and IMU at their own rates (their instants then apart), a slower accelerometer
    and the camera reporting the impact point: the same results."""
    for scene in _drawn(params, 3, seed=11):
        spec = replace(
            scene.sensors,
            pressure_rate_hz=1000.0,
            imu_rate_hz=4000.0,
            vibration_rate_hz=12800.0,
            camera_reports_impact_point=True,
        )
        scene = replace(scene, sensors=spec)
        trajectory = simulate(scene).trajectory
        lean, general = sense(scene, trajectory), sense_general(scene, trajectory)
        assert_same_result(lean, general)
        assert lean.point is not None and np.array_equal(lean.point.point_m, general.point.point_m)


@pytest.mark.parametrize(("solver", "options"), [("rk4", {"dt_s": 2e-5}), ("hybrid", {})])
def test_lean_sensing_of_other_solvers(params, solver, options):
    """A fixed-step solver's trajectory (its contact integrated over the whole window) and the
    hybrid's: the same results."""
    scene = _drawn(params, 1, seed=5)[0]
    chosen = simulate(scene)
    trajectory = solve(chosen.trajectory.problem, solver, **options)
    assert sense_one.covers(scene, trajectory)
    assert_same_result(sense(scene, trajectory), sense_general(scene, trajectory))


def test_what_the_lean_path_leaves_to_the_general_one(params):
    """An IMU behind its own low-pass and a trajectory with a dense-output span (scipy's
    solvers) are not covered; sense then gives the general path's result."""
    scene = _drawn(params, 1, seed=3)[0]
    trajectory = simulate(scene).trajectory
    filtered = replace(scene, sensors=replace(scene.sensors, imu_antialias_order=2))
    assert not sense_one.covers(filtered, trajectory)
    assert_same_result(sense(filtered, trajectory), sense_general(filtered, trajectory))
    radau = solve(trajectory.problem, "Radau", rtol=1e-6)
    assert any(isinstance(segment, OdeSegment) for segment in radau.segments)
    assert not sense_one.covers(scene, radau)


def test_kept_readouts_and_history_instants_equal_fresh_ones(params):
    """The readout rows and the histories' uniform instants, kept, give what they give when
    the caches are emptied."""
    scene = _drawn(params, 1, seed=8)[0]
    trajectory = simulate(scene, tier="modal").trajectory
    kept = sense(scene, trajectory)
    sense_one._READOUTS.clear()
    sense_one._uniform_times.cache_clear()
    fresh = sense(scene, trajectory)
    assert sense_one._READOUTS
    assert np.array_equal(kept.vibration.accel_mps2, fresh.vibration.accel_mps2)
    for name, values in kept.history.items():
        assert np.array_equal(values, fresh.history[name]), name


def test_lean_sensing_without_the_ring_down(params, monkeypatch):
    """The accelerometer read densely over the whole window (the ring-down's start pushed past
    it): the same results."""
    monkeypatch.setattr(SensorSuite, "_ringdown_start", lambda self, t, c, count: count)
    for scene in _drawn(params, 2, seed=13):
        trajectory = simulate(scene).trajectory
        lean = sense(scene, trajectory)
        assert lean.vibration.sample_count > 1000
        assert_same_result(lean, sense_general(scene, trajectory))


@pytest.mark.parametrize(
    ("material", "radius_m", "tier"),
    [("coal", 0.03, "rigid"), ("coal", 0.09, "modal"), ("marble", 0.05, "brittle")],
)
def test_contact_readings_are_the_general_sampling_read_through_the_rows(
    params, material, radius_m, tier
):
    """Within a contact (the pulse's, an integrated one, a crushing one) the lean path's
    readings are bit for bit the states Trajectory.sample gives, read through the same rows, at
    the contact's steps and between them."""
    scene = Scene.from_params(params, {"material": material, "radius_m": radius_m})
    trajectory = simulate(scene, tier=tier).trajectory
    structure, segment = trajectory.problem.structure, trajectory.segments[1]
    rng = np.random.default_rng(4)
    times = np.concatenate([segment.t_s[:-1], rng.uniform(segment.t_s[0], segment.t_s[-1], 50)])
    lean = np.empty((sense_one.LINEAR, times.size))
    sense_one._contact_readings(structure, segment, times, lean)
    n = structure.size
    general = sense_one._readouts(structure)[3] @ trajectory.sample(times).q.base[: 3 * n]
    assert np.array_equal(lean, general)


@pytest.mark.parametrize("tier", ["rigid", "modal"])
def test_free_readings_direct_and_on_grids_are_the_general_sampling_to_rounding(params, tier):
    """After the contact the readings in closed form, instant by instant and on an even grid
    (each exponential the first instant's times the grid's), equal the states Trajectory.sample
    gives read through the same rows, to 1e-12 of each reading's largest magnitude."""
    scene = _drawn(params, 1, seed=6)[0]
    trajectory = simulate(scene, tier=tier).trajectory
    structure, last = trajectory.problem.structure, trajectory.segments[-1]
    grid = last.start_s + 1e-5 + np.arange(2000) * 2.5e-5
    direct = np.random.default_rng(5).uniform(-0.004, 0.05, 500)
    near, (far,) = sense_one._evaluate(
        trajectory, direct, [(grid, 2.5e-5, slice(0, sense_one.LINEAR))], None
    )
    n = structure.size
    rows = sense_one._readouts(structure)[3]
    for times, got in ((direct, near), (grid, far)):
        expected = rows @ trajectory.sample(times).q.base[: 3 * n]
        scale = np.max(np.abs(expected), axis=1, keepdims=True)
        assert np.all(np.abs(got[: sense_one.LINEAR] - expected) <= 1e-12 * scale)
