"""The accelerometer's filtered ring-down in closed form (tail_beam_sim.physics.ringdown_filtering)
against the filter run over the dense response, which it replaces after the contact."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy import signal

from tail_beam_sim.physics import sensors
from tail_beam_sim.physics.ringdown_filtering import response, settle_steps
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.simulate import simulate


def _sos() -> np.ndarray:
    return sensors._butterworth(25600.0, 4, 0.4, 4)[0]


def test_the_filter_response_is_the_steady_output_of_a_damped_sinusoid():
    """Run the filter over a long damped sinusoid: once the start-up transient has gone (the
    settle steps), its output is Re(H(z) z^n) for z the sinusoid's ratio per step."""
    sos = _sos()
    z = np.exp(complex(-40.0, 2 * np.pi * 3000.0) / 102400.0)
    n = np.arange(2000)
    out = signal.sosfilt(sos, (z**n).real)
    steady = (response(sos, np.array([z]))[0] * z**n).real
    after = settle_steps(sos.tobytes())
    assert 10 < after < 1000
    assert np.max(np.abs(out[after:] - steady[after:])) < 1e-10
    # while the transient lasts, the two differ: the settle step count is not idle
    assert np.max(np.abs(out[:20] - steady[:20])) > 1e-3
    assert abs(response(sos, np.array([1.0 + 0j]))[0] - 1.0) < 1e-12  # unit gain at DC


@pytest.mark.parametrize("tier", ["rigid", "modal"])
def test_simulated_vibration_equals_the_dense_filtering_to_float32_resolution(
    params, tier, monkeypatch
):
    """Noise-free blocks of coal and gangue impacts (25-100 mm, over the impact zone) with the
    closed form and with the dense path throughout (the ring-down start pushed past the window)
    agree to the float32 resolution of the samples (about 4e-6 m/s^2 at 30 m/s^2)."""
    rng = np.random.default_rng(7)
    base = Scene.from_params(params, {"radius_m": 0.05})
    dense_only = sensors.SensorSuite._ringdown_start
    worst = 0.0
    for k, material in enumerate(["coal", "sandstone", "coal", "marble", "mudstone", "coal"]):
        chosen = base.materials[material]
        scene = base.with_impact(
            material=chosen,
            restitution=chosen.restitution,
            radius_m=float(rng.uniform(0.025, 0.1)),
            position_m=float(rng.uniform(0.6, 1.4)),
        )
        scene = replace(scene, sensors=replace(scene.sensors.scaled_noise(0.0), seed=k))
        fast = simulate(scene, tier=tier).vibration
        monkeypatch.setattr(
            sensors.SensorSuite, "_ringdown_start", lambda self, t, c, count: count
        )
        dense = simulate(scene, tier=tier).vibration
        monkeypatch.setattr(sensors.SensorSuite, "_ringdown_start", dense_only)
        assert np.array_equal(fast.first_index, dense.first_index)
        a, b = fast.accel_mps2.astype(float), dense.accel_mps2.astype(float)
        assert np.ptp(b) > 1.0  # the impact is in the blocks
        worst = max(worst, float(np.max(np.abs(a - b))))
    assert worst < 1e-5
