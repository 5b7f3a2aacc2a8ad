"""The sensors' fast paths give what the direct computations give: scipy's filter kernel called
directly, the accelerometer's rest before the contact taken as read, the seeds' children kept
per seed, and the ring-down's per-structure gains kept."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy import signal

from tail_beam_sim.physics import ringdown_filtering, sensors
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.simulate import simulate


def test_the_direct_filter_kernel_is_scipys_sosfilt_bit_for_bit():
    """sos_filter gives signal.sosfilt's output and final state exactly, whole or in chunks."""
    sos, zi_unit = sensors._butterworth(25600.0, 4, 0.4, 4)
    rng = np.random.default_rng(1)
    x = 9.8 + rng.standard_normal(700)
    expected, final = signal.sosfilt(sos, x, zi=zi_unit * x[0])
    out, state = sensors.sos_filter(sos, x, zi_unit * x[0])
    assert np.array_equal(out, expected) and np.array_equal(state, final)
    head, middle = sensors.sos_filter(sos, x[:123], zi_unit * x[0])
    tail, _ = sensors.sos_filter(sos, x[123:], middle)
    assert np.array_equal(np.concatenate([head, tail]), expected)
    assert not np.array_equal(out, x)  # the filter does filter


@pytest.mark.parametrize("tier", ["rigid", "modal"])
def test_the_rest_before_the_contact_reads_what_filtering_it_gives(params, tier, monkeypatch):
    """The accelerometer's samples before the contact, taken as g without evaluating or
    filtering the beam at rest, equal the samples of the dense path run from stamp 0, to the
    float32 resolution of the samples; and the shortcut does cover most of the rest."""
    base = Scene.from_params(params, {"material": "sandstone", "radius_m": 0.04})
    scene = replace(base, sensors=replace(base.sensors.scaled_noise(0.0), seed=3))
    result = simulate(scene, tier=tier)
    span = sensors.SensorSuite._dense_span
    first, _, _ = span(
        sensors.SensorSuite(scene.sensors),
        result.trajectory,
        result.contact_stamp_s + scene.window_s,
        result.contact_stamp_s,
    )
    dense_rate = scene.sensors.vibration_oversample * scene.sensors.vibration_rate_hz
    assert first > 0.8 * result.contact_stamp_s * dense_rate
    monkeypatch.setattr(
        sensors.SensorSuite,
        "_dense_span",
        lambda self, t, end, stamp: (0, *span(self, t, end, stamp)[1:]),
    )
    whole = simulate(scene, tier=tier).vibration
    assert np.array_equal(whole.first_index, result.vibration.first_index)
    a, b = result.vibration.accel_mps2.astype(float), whole.accel_mps2.astype(float)
    assert np.ptp(b) > 1.0  # the impact is in the blocks
    assert np.max(np.abs(a - b)) < 1e-5


def test_kept_seed_children_draw_what_fresh_ones_draw(params):
    """A suite's generators, made from the children kept per seed, draw what generators of a
    freshly spawned seed draw; the kept contact phase is the phase generator's first draw."""
    spec = Scene.from_params(params, {}).sensors
    for seed in (0, 7, 123456):
        suite = sensors.SensorSuite(replace(spec, seed=seed))
        fresh = np.random.SeedSequence(seed).spawn(6)
        for index, name in ((0, "_pressure_rng"), (1, "_imu_rng"), (4, "_vibration_rng")):
            drawn = getattr(suite, name).standard_normal(5)
            assert np.array_equal(drawn, np.random.default_rng(fresh[index]).standard_normal(5))
        width = 1.0 / 2000.0
        assert 0.0 + width * suite.contact_phase() == np.random.default_rng(fresh[3]).uniform(
            0.0, width
        )


def test_kept_ringdown_gains_equal_fresh_ones(params):
    """The ring-down's per-structure gains, kept, equal those computed with the cache emptied."""
    scene = Scene.from_params(params, {"material": "coal", "radius_m": 0.05})
    result = simulate(scene, tier="modal")
    kept = simulate(scene, tier="modal").vibration.accel_mps2
    ringdown_filtering._GAINS.clear()
    fresh = simulate(scene, tier="modal").vibration.accel_mps2
    assert ringdown_filtering._GAINS  # refilled
    assert np.array_equal(kept, fresh) and np.array_equal(kept, result.vibration.accel_mps2)


def test_the_streams_accelerometer_is_the_same_however_time_is_chunked():
    """The stream's accelerometer, each dense instant evaluated once (the one before a chunk's
    first instant evaluated with it), gives the same blocks advanced at once or in random
    chunks, through two impacts."""
    from tail_beam_sim.config import default_config_dir, load_parameters
    from tail_beam_sim.physics.stream import StreamSimulator

    def make() -> StreamSimulator:
        params = load_parameters([str(default_config_dir() / "sim_node.yaml")])
        stream = StreamSimulator.from_params(params)
        stream.submit(
            {"material": "coal", "radius_m": 0.04, "drop_height_m": 3.0, "position_m": 1.0}, 0.05
        )
        stream.submit(
            {"material": "marble", "radius_m": 0.06, "drop_height_m": 2.0, "position_m": 0.5}, 0.3
        )
        return stream

    whole, pieces = make(), make()
    one = whole.advance(0.6).vibration
    rng = np.random.default_rng(11)
    ends = np.sort(rng.uniform(0.0, 0.6, 30)).tolist() + [0.6]
    parts = [pieces.advance(end).vibration for end in ends]
    joined = sensors.VibrationBlocks.concatenate(parts)
    assert one.sample_count > 10000 and np.ptp(one.accel_mps2) > 1.0
    assert np.array_equal(joined.first_index, one.first_index)
    assert np.array_equal(joined.accel_mps2, one.accel_mps2)


@pytest.mark.parametrize(("tier", "radius_m"), [("rigid", 0.04), ("modal", 0.09)])
def test_a_contact_sampled_through_step_polynomials_is_its_hermite_interpolant(
    params, tier, radius_m
):
    """States within a contact (the pulse's, and an integrated one) read through each step's
    polynomial are the cubic Hermite of the step's ends (values and slopes) and the straight
    line of q'' and the force, to rounding."""
    scene = Scene.from_params(params, {"material": "coal", "radius_m": radius_m})
    trajectory = simulate(scene, tier=tier).trajectory
    segment = trajectory.segments[1]
    t = segment.t_s
    times = np.random.default_rng(2).uniform(t[0], t[-1], 200)
    got = trajectory.sample(times)
    k = np.clip(np.searchsorted(t, times, side="right") - 1, 0, t.size - 2)
    h = t[k + 1] - t[k]
    s = (times - t[k]) / h
    values, slopes, _, _ = trajectory._stacks(1)
    hermite = (
        (2 * s**3 - 3 * s**2 + 1) * values[:, k]
        + (s**3 - 2 * s**2 + s) * h * slopes[:, k]
        + (-2 * s**3 + 3 * s**2) * values[:, k + 1]
        + (s**3 - s**2) * h * slopes[:, k + 1]
    )
    n = trajectory.problem.structure.size
    expected = {
        "q": hermite[:n],
        "qd": hermite[n : 2 * n],
        "z_m": hermite[2 * n],
        "zd_mps": hermite[2 * n + 1],
        "qdd": segment.qdd[:, k] * (1 - s) + segment.qdd[:, k + 1] * s,
        "force_n": segment.force_n[k] * (1 - s) + segment.force_n[k + 1] * s,
    }
    for name, value in expected.items():
        scale = np.max(np.abs(value))
        assert scale > 0.0, name
        assert np.max(np.abs(getattr(got, name) - value)) <= 1e-12 * scale, name
