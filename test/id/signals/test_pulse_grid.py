"""The half-sine grid search's shared pulse geometry: the samples inside each candidate pulse,
listed from runs where the samples are in order, are exactly those np.nonzero lists."""

from __future__ import annotations

import numpy as np
import pytest

from tail_beam_id.signals import contact_fit


def _nonzero_within(t, durations, starts):
    since = t[None, :] - starts[:, None]
    return np.nonzero((since > 0.0)[None] & (since[None] < durations[:, None, None]))


@pytest.mark.parametrize("period_s", [1 / 25600, 1 / 8000, 1 / 51200])
def test_runs_list_the_samples_np_nonzero_lists(period_s):
    rng = np.random.default_rng(3)
    for _ in range(20):
        onset = float(rng.uniform(0.0, period_s))
        t = np.arange(-12, 120) * period_s - onset
        durations = np.exp(np.linspace(np.log(3e-5), np.log(2e-3), 20)) * rng.uniform(0.7, 1.3)
        starts = np.arange(-3, 6) * period_s / 2.0 + rng.uniform(-1, 1) * period_s
        grid = contact_fit._pulse_grid(t, durations, starts)
        for got, want in zip(grid.within, _nonzero_within(t, durations, starts)):
            np.testing.assert_array_equal(got, want)


def test_samples_out_of_order_fall_back_to_np_nonzero():
    t = np.array([0.0, 2e-4, 1e-4, 3e-4, 4e-4, 5e-4, 6e-4, 7e-4])
    durations, starts = np.array([1.5e-4, 3e-4]), np.array([-5e-5, 5e-5])
    grid = contact_fit._pulse_grid(t, durations, starts)
    for got, want in zip(grid.within, _nonzero_within(t, durations, starts)):
        np.testing.assert_array_equal(got, want)


def test_the_same_arrays_get_the_same_grid_and_others_a_new_one():
    t = np.arange(40) * 4e-5
    durations, starts = np.array([1e-4, 2e-4]), np.array([0.0, 2e-5])
    grid = contact_fit._pulse_grid(t, durations, starts)
    assert contact_fit._pulse_grid(t, durations, starts) is grid
    assert contact_fit._pulse_grid(t.copy(), durations, starts) is not grid
