"""The stepping solvers' right-hand side, written out per structure size, gives the floats of
the plain loops it stands for (tail_beam_sim.physics.solvers.dynamics)."""

from __future__ import annotations

import numpy as np
import pytest

from tail_beam_sim.physics.fidelity import shipped_settings
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.simulate import _prepare
from tail_beam_sim.physics.solvers.dynamics import FloatDynamics


def _loops(dyn: FloatDynamics, y: list[float], approach: float, peak: float):
    """The equations as plain loops: delta = -(b . q) - z, q'' = load F - K' q - C' qd, z'' =
    F / m - g."""
    n = dyn.n
    q, qd = y[:n], y[n : 2 * n]
    delta = -sum(b * x for b, x in zip(dyn.shape, q)) - y[2 * n]
    rate = -sum(b * v for b, v in zip(dyn.shape, qd)) - y[2 * n + 1]
    force = dyn.force(delta, rate, approach, peak) if delta > 0.0 else 0.0
    acc = [
        li * force - sum(k * a for k, a in zip(krow, q)) - sum(c * v for c, v in zip(crow, qd))
        for li, krow, crow in zip(dyn.load, dyn.stiffness_rows, dyn.damping_rows)
    ]
    return (delta, rate), (
        [*qd, *acc, y[2 * n + 1], force / dyn.mass_kg - dyn.gravity_mps2],
        force,
    )


@pytest.mark.parametrize("tier", ["rigid", "modal", "brittle"])
def test_written_out_dynamics_equal_the_loops_bit_for_bit(params, tier):
    """Over random states in and out of contact, penetration and derivative are exactly the
    loops' (Hertz with hysteresis, and the crushing law of the brittle tier)."""
    settings = shipped_settings()
    scene = Scene.from_params(params, {"material": "coal", "radius_m": 0.06})
    _, problem, _, _ = _prepare(scene, tier, settings.needs, settings, None)
    dyn = FloatDynamics(problem)
    assert (dyn.crushing is not None) == (tier == "brittle")
    rng = np.random.default_rng(5)
    contacts = 0
    for _ in range(300):
        y = [float(v) for v in rng.normal(0.0, 1e-4, 2 * dyn.n + 2)]
        y[2 * dyn.n + 1] = float(rng.normal(0.0, 3.0))
        approach, peak = float(rng.uniform(1.0, 9.0)), float(rng.uniform(0.0, 3e-4))
        (delta, rate), (derivative, force) = _loops(dyn, y, approach, peak)
        contacts += force > 0.0
        assert dyn.penetration(y) == (delta, rate)
        got, got_force = dyn.derivative(y, approach, peak)
        assert got == derivative and got_force == force
    assert 50 < contacts < 250  # both in and out of contact
