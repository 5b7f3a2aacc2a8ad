"""The half-sine grid search's shared pulse geometry: built once for the very same arrays, and
never read for others."""

from __future__ import annotations

import math

import numpy as np

from tail_beam_id.signals import contact_fit


def test_the_same_arrays_get_the_same_grid_and_others_a_new_one():
    """The grid is shared only with a call on the very same arrays."""
    t = np.arange(40) * 4e-5
    durations, starts = np.array([1e-4, 2e-4]), np.array([0.0, 2e-5])
    grid = contact_fit._pulse_grid(t, durations, starts)
    assert contact_fit._pulse_grid(t, durations, starts) is grid
    assert contact_fit._pulse_grid(t.copy(), durations, starts) is not grid
    assert contact_fit._pulse_grid(t, durations, starts.copy()) is not grid


def test_a_search_reads_the_same_with_the_shared_grid_as_with_its_own():
    """Two searches over the same samples and grid with other poles, then one over another
    grid: each reads what it reads with the grids built afresh."""
    rng = np.random.default_rng(5)
    period_s = 1.0 / 25600.0
    t = np.arange(-8, 77) * period_s - 0.3 * period_s
    sway = np.linalg.qr(np.stack([np.ones_like(t), t, t * t], axis=1))[0]
    since = np.clip(t - 1e-5, 0.0, None)
    y = np.where(since < 2e-4, np.sin(math.pi * since / 2e-4), 0.0) + 0.01 * rng.standard_normal(
        t.size
    )
    y -= sway @ (sway.T @ y)
    grid = (np.exp(np.linspace(math.log(3e-5), math.log(2e-3), 20)), np.arange(-3, 6) * period_s)
    other = (grid[0][5:14] * 1.1, np.arange(-2, 3) * period_s / 6.0)
    calls = [
        (np.array([-300.0 + 2j * math.pi * 900.0]), *grid),
        (np.array([-500.0 + 2j * math.pi * 1300.0, -80.0 + 2j * math.pi * 400.0]), *grid),
        (np.array([-300.0 + 2j * math.pi * 900.0]), *other),
    ]
    shared = [contact_fit._best(t, y, sway, *call) for call in calls]
    fresh = []
    for call in calls:
        contact_fit._last_grids.clear()
        fresh.append(contact_fit._best(t, y, sway, *call))
    assert shared == fresh
