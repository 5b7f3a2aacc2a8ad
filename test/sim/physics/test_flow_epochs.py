"""The flow's epochs as the stream's sensors sample them: the period before an epoch's start
read from the epoch before, positions and velocities without accelerations, the stamps split
by epoch."""

from __future__ import annotations

import numpy as np
import pytest

from tail_beam_sim.config import default_config_dir, load_parameters
from tail_beam_sim.physics.stream import _split_by_epoch
from tail_beam_sim.physics.superpose import FlowEpoch, FlowSimulator

LUMPS = [
    {"material": "sandstone", "radius_m": 0.05, "drop_height_m": 2.5, "position_m": 0.6},
    {"material": "coal", "radius_m": 0.06, "drop_height_m": 2.0, "position_m": 1.1},
]
STAMPS_S = [0.05, 0.0502, 0.0507, 0.09, 0.0901]  # overlapping contacts, then separate ones


@pytest.fixture(scope="module")
def epochs() -> list[FlowEpoch]:
    """The epochs of a flow of overlapping contacts, each linked to the one before."""
    params = load_parameters([default_config_dir() / "sim_node.yaml"])
    sim = FlowSimulator.from_params(params)
    for k, stamp in enumerate(STAMPS_S):
        sim.submit({**LUMPS[k % 2], "restitution": 0.4, "impact_id": f"l{k}"}, stamp)
    sim._fold_until(1.0)  # every contact ended and folded: an epoch at each start and end
    found = [e for e in sim._epochs if isinstance(e, FlowEpoch) and e.previous is not None]
    assert len(found) >= 2 * len(STAMPS_S) - 1
    assert max(len(e.active) for e in found) >= 2  # contacts overlapping in an epoch
    return found


def test_the_beam_moves_on_continuously_across_each_epoch_start(epochs):
    """At an epoch's start the beam's displacement and velocity are the epoch before's (a
    contact starts at zero force, another leaves at zero force): the new epoch's own formula
    and the previous epoch's agree there, and just before the start the epoch reads the
    previous one."""
    for epoch in epochs:
        # the rest epoch, from -inf, reads absolute stamps
        shift = epoch.start_s - (epoch.previous_start_s if epoch.previous_start_s > -np.inf else 0)
        own = epoch.sample_parts(np.array([0.0]))[0]
        previous = epoch.previous.sample(np.array([shift]))
        scale_q = np.max(np.abs(previous.q)) + 1e-12
        scale_qd = np.max(np.abs(previous.qd)) + 1e-12
        assert np.max(np.abs(own.q - previous.q)) < 1e-6 * scale_q
        assert np.max(np.abs(own.qd - previous.qd)) < 1e-6 * scale_qd
        times = np.array([-2e-4, -1e-5, 0.0, 1e-4])
        mixed = epoch.sample(times)
        early = epoch.previous.sample(times[:2] + shift)
        np.testing.assert_array_equal(mixed.q[:, :2], early.q)
        np.testing.assert_array_equal(mixed.qd[:, :2], early.qd)
        np.testing.assert_array_equal(mixed.force_n[:2], early.force_n)
        late = epoch.sample(times[2:])
        np.testing.assert_array_equal(mixed.q[:, 2:], late.q)
        np.testing.assert_array_equal(mixed.qdd[:, 2:], late.qdd)


def test_positions_only_are_the_full_samples_without_accelerations(epochs):
    """``sample_states`` (what the sensors read) gives the same q and qd as a full sample, the
    times before the start included, and leaves q'' and the force out (NaN, read-only)."""
    parts = [np.linspace(-3e-4, 2e-3, 41), np.array([5e-4, -1e-5])]
    for epoch in epochs:
        full = epoch.sample_many(parts)
        states = epoch.sample_states(parts)
        for a, b in zip(full, states):
            np.testing.assert_array_equal(a.t_s, b.t_s)
            np.testing.assert_array_equal(a.q, b.q)
            np.testing.assert_array_equal(a.qd, b.qd)
            assert np.isnan(b.qdd).all() and np.isnan(b.force_n).all()
            assert not b.qdd.flags.writeable
        assert np.isfinite(full[0].qdd).all()


def test_stamps_are_split_by_the_epoch_they_fall_in():
    """Each stamp goes to the last epoch starting at or before it, ordered stamps as slices,
    others as masks, and every stamp exactly once."""
    starts = [-np.inf, 0.1, 0.2, 0.2, 0.35]
    rng = np.random.default_rng(1)
    for stamps in (np.sort(rng.uniform(0.0, 0.5, 200)), rng.uniform(0.0, 0.5, 200)):
        seen = np.zeros(stamps.size, dtype=int)
        for k, where in _split_by_epoch(starts, stamps):
            picked = np.zeros(stamps.size, dtype=bool)
            picked[where] = True
            seen += picked
            assert np.all(stamps[picked] >= starts[k])
            if k + 1 < len(starts):
                assert np.all(stamps[picked] < starts[k + 1])
        assert np.all(seen == 1)
    assert _split_by_epoch(starts, np.empty(0)) == []
    assert [k for k, _ in _split_by_epoch(starts, np.array([0.21, 0.3]))] == [3]
