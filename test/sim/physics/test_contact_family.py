"""The group path of simulate_many (contact_family, sense_many, contact_batch): many impacts
of one contact solved and sensed at once give what simulate gives for each, impact by impact,
for pulse and RK4 contacts, on the rigid beam and with bending modes; impacts it does not
cover (re-contacts, a particle coming to rest) go the per-impact way."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from same_result import SIGNAL_TOLERANCE, assert_same_result

from tail_beam_sim.physics.contact_family import ContactFamily, Grid
from tail_beam_sim.physics.fidelity import plan, shipped_settings
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.sense_many import _grid_peaks
from tail_beam_sim.physics.simulate import _problem, histories, simulate, simulate_many
from tail_beam_sim.physics.solvers.contact_batch import integrate_contacts
from tail_beam_sim.physics.solvers.dynamics import FloatDynamics
from tail_beam_sim.physics.solvers.hybrid import DEFAULT_STEPS_PER_CONTACT, contact_phase


def _problems(scenes: list[Scene], tier: str) -> list:
    """Each scene's impact problem as simulate_many plans it at ``tier`` (shipped settings)."""
    settings = shipped_settings()
    return [
        _problem(s, plan(s, tier, settings.needs, settings), settings, None)[0] for s in scenes
    ]


def _drawn(params: dict, count: int, seed: int = 4) -> list[Scene]:
    """Coal and gangue, 25-100 mm, dropped 0.5-4 m anywhere on the impact zone, each scene
    with its own noise seed (as the benchmark and the data sets draw them)."""
    base = Scene.from_params(params, {})
    rng = np.random.default_rng(seed)
    names = ["coal", "sandstone", "mudstone", "marble"]
    support = base.support
    scenes = []
    for k in range(count):
        height = float(rng.uniform(0.5, 4.0))
        material = base.materials[names[k % len(names)]]
        scene = base.with_impact(
            material=material,
            restitution=material.restitution,
            radius_m=float(rng.uniform(0.025, 0.1)),
            drop_height_m=height,
            impact_speed_mps=float(np.sqrt(2 * support.gravity_mps2 * height)),
            position_m=float(rng.uniform(support.impact_zone_min_m, support.impact_zone_max_m)),
        )
        scenes.append(replace(scene, sensors=replace(scene.sensors, seed=100 + k)))
    return scenes


def _recontact(params: dict) -> Scene:
    """A small marble lump dropped 1 cm near the hinge: caught again by the plate."""
    return Scene.from_params(
        params, {"material": "marble", "radius_m": 0.02, "drop_height_m": 0.01, "position_m": 0.2}
    )


@pytest.mark.parametrize("tier", ["rigid", "modal"])
def test_simulate_many_equals_simulate_impact_by_impact(params, tier):
    """Drawn impacts (pulse and RK4 contacts both among them) and one that re-contacts:
    simulate_many's results are simulate's to 1e-11 of every signal, with the same noise,
    stamps and accelerometer blocks, and the re-contact's (solved alone) bit for bit."""
    scenes = _drawn(params, 16) + [_recontact(params)]
    flags = [k % 5 != 0 for k in range(len(scenes))]
    many = simulate_many(scenes, tier=tier, vibration=flags)
    kinds = {
        (r.trajectory.stats["pulse_contacts"], r.trajectory.stats["rk4_contacts"]) for r in many
    }
    assert {(1, 0), (0, 1)} <= kinds
    assert len(many[-1].trajectory.contacts) > 1
    for scene, flag, result in zip(scenes, flags, many):
        assert_same_result(result, simulate(scene, tier=tier, vibration=flag))


def test_histories_are_read_when_asked_and_hold_the_summary_peaks(params):
    """A group result's histories are the trajectory's own (simulate.histories), computed when
    first read; the summary's peaks, found without them, are their maxima after contact."""
    for result in simulate_many(_drawn(params, 6, seed=9)):
        assert result.history._values is None  # not computed yet
        alone = histories(result.scene, result.trajectory)
        for key, values in alone.items():
            assert np.array_equal(result.history[key], values), key
        after = alone["time_s"] >= 0.0
        summary = result.summary
        for key, peak in (
            (
                "peak_jack_pressure_change_pa",
                np.max(alone["jack_pressure_pa"][after])
                - result.scene.support.setting_pressure_pa,
            ),
            (
                "peak_beam_angular_velocity_radps",
                np.max(np.abs(alone["beam_angular_velocity_radps"][after])),
            ),
            (
                "peak_imu_dynamic_accel_mps2",
                np.max(np.abs(alone["imu_dynamic_accel_mps2"][after])),
            ),
        ):
            assert abs(summary[key] - peak) <= SIGNAL_TOLERANCE * abs(peak), key


def test_lockstep_rk4_contacts_are_the_hybrid_solvers(params):
    """The RK4 contacts integrated in lockstep over impacts take the hybrid solver's steps, and
    end in its state to rounding (1e-12 of the state's scale), each impact's own step size and
    exit kept."""
    scenes = [s for s in _drawn(params, 24, seed=5) if s.impact.radius_m > 0.06]
    problems = _problems(scenes, "modal")
    batch = integrate_contacts(problems, DEFAULT_STEPS_PER_CONTACT)
    assert batch.ok.all() and len(problems) >= 4
    for k, problem in enumerate(problems):
        dynamics = FloatDynamics(problem)
        n = problem.structure.size
        start = dynamics.state(problem.q0, problem.qd0, 0.0, -problem.impact_speed_mps)
        segment, record = contact_phase(problem, dynamics, 0.0, start, DEFAULT_STEPS_PER_CONTACT)
        assert batch.t_s[k].size == segment.t_s.size
        expected = np.concatenate([segment.q[:, -1], segment.qd[:, -1]])
        got = batch.states[k][-1, : 2 * n]
        assert np.max(np.abs(got - expected)) <= 1e-12 * np.max(np.abs(expected))
        assert abs(batch.t_s[k][-1] - record.end_s) <= 1e-12 * record.end_s
        assert abs(batch.peak_force_n[k] - record.peak_force_n) <= 1e-12 * record.peak_force_n


def test_the_family_leaves_recontacts_to_the_solver(params):
    """An impact whose particle the plate can catch again within the window is not the
    family's (ok false); a drawn impact from 0.5-4 m is."""
    scenes = [_recontact(params)] + _drawn(params, 3)
    problems = _problems(scenes, "rigid")
    family = ContactFamily(problems, 5e-3)
    assert list(family.ok) == [False, True, True, True]


@pytest.mark.parametrize("rate_hz", [2000.0, 20000.0, 97000.0])
def test_peaks_read_next_to_the_extrema_are_the_whole_grids(params, rate_hz):
    """The summary's peaks read only at the grid instants next to each reading's extrema (and
    through the contact) equal the maxima of the same readings over every grid instant, signed
    and in magnitude, on grids coarse and fine against the ring's 39 Hz and the contacts."""
    scenes = _drawn(params, 60, seed=11)
    problems = _problems(scenes, "rigid")
    family = ContactFamily(problems, 5e-3)
    rows = np.flatnonzero(family.ok)
    assert rows.size > 50
    n = family.n
    rng = np.random.default_rng(3)
    outputs = rng.normal(size=(3, 3 * n))
    window = scenes[0].window_s
    uniform = np.arange(0.0, window + 0.5 / rate_hz, 1.0 / rate_hz)
    count = rows.size
    whole = family.read(
        rows,
        Grid(np.broadcast_to(uniform, (count, uniform.size)), uniform, np.zeros(count)),
        outputs,
    )
    whole[1:] = np.abs(whole[1:])
    peaks = _grid_peaks(family, rows, uniform, outputs, ("test", rate_hz))
    assert np.array_equal(peaks, whole.max(axis=2))


def test_readings_at_the_contact_samples_are_reads_there(params):
    """read_at_samples, which takes each contact sample's own state, gives what read gives at
    those instants (the cubic Hermite there, the free response at the contact's end), for
    readings of q, q' and q'', pulse and RK4 contacts; nan past an impact's last sample."""
    scenes = _drawn(params, 40, seed=5)
    problems = _problems(scenes, "modal")
    family = ContactFamily(problems, 5e-3)
    rows = np.flatnonzero(family.ok)
    assert family.pulse[rows].any() and (~family.pulse[rows]).any()
    readings = np.random.default_rng(8).normal(size=(4, 3 * family.n))
    readings[0, 2 * family.n :] = 0.0  # one of q and q' only
    got = family.read_at_samples(rows, readings)
    times = family.contact_times[rows]
    real = np.isfinite(times)
    expected = family.read(rows, Grid(np.where(real, times, 0.0)), readings)
    assert np.array_equal(np.isnan(got), np.broadcast_to(~real, got.shape))
    scale = np.abs(expected[:, real]).max(axis=1, keepdims=True)
    assert np.all(np.abs(got[:, real] - expected[:, real]) <= SIGNAL_TOLERANCE * scale)
