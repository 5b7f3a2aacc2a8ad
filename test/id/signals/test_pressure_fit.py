"""The jack-pressure fit of a moment impulse when other impacts' responses overlap it: one
impulse column per known onset (the support is linear, responses add)."""

from __future__ import annotations

import numpy as np
import pytest

from tail_beam_id.signals.features import BeamModel, fit_pressure, separable_onsets

RATE_HZ = 2000.0  # the shipped jack-pressure rate
NOISE_PA = 10.0e3  # the shipped transducer noise RMS (config/sensors.yaml)


@pytest.fixture(scope="module")
def model(params):
    return BeamModel.from_params(params)


def pressure(model, t_s, impulses):
    """Setting pressure, a free sway of an earlier impact, and the sum of the responses to the
    given (onset s, moment impulse N m s) impulses: the linear support's pressure, Pa."""
    omega = 2.0 * np.pi * model.support.rigid_mode_frequency_hz
    y = 30.0e6 + 2.0e4 * np.cos(omega * t_s + 0.7)
    for onset_s, moment_nms in impulses:
        y = y + moment_nms * model.pressure_response(t_s - onset_s)
    return y


@pytest.mark.parametrize("gap_s", [0.005, 0.01, 0.02, 0.03])
def test_the_joint_fit_recovers_two_overlapping_impulses_exactly(model, gap_s):
    """Two impulses of 3 and 11 N m s at onsets 5-30 ms apart, both inside the window: each
    fit, given the other's onset, reads its own impulse to 1e-6 (noise-free: the least-squares
    solution of an exactly representable signal); alone it reads a mixture of the two."""
    t = np.arange(0.0, 0.2, 1.0 / RATE_HZ)
    first, second = 0.1, 0.1 + gap_s
    y = pressure(model, t, [(first, 3.0), (second, 11.0)])
    window = dict(pre_s=0.04, window_s=0.04)
    a = fit_pressure(model, t, y, first, other_onsets_s=[second], **window)
    b = fit_pressure(model, t, y, second, other_onsets_s=[first], **window)
    assert a.moment_impulse_nms == pytest.approx(3.0, rel=1e-6)
    assert b.moment_impulse_nms == pytest.approx(11.0, rel=1e-6)
    assert a.neighbours == b.neighbours == 1
    assert a.unresolved == b.unresolved == 0
    alone = fit_pressure(model, t, y, first, **window)
    assert abs(alone.moment_impulse_nms - 3.0) > 0.1


@pytest.mark.parametrize("gap_s", [0.005, 0.01, 0.02, 0.03])
def test_with_the_transducers_noise_the_read_impulse_is_within_its_stated_error(model, gap_s):
    """With the shipped 10 kPa noise, over the shipped window (20 ms before, 12 ms after), next
    to an impulse 4 ms before and one 5-30 ms after (outside the window from 12 ms on): over
    100 noise draws the read impulse is unbiased (its mean within 3 standard errors of the
    mean of the truth), within 5 stated standard errors every time, and the stated error is
    the scatter's (within 30 %)."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 0.2, 1.0 / RATE_HZ)
    first, second = 0.1, 0.1 + gap_s
    clean = pressure(model, t, [(first - 0.004, 20.0), (first, 5.0), (second, 30.0)])
    reads, sigmas = [], []
    for _ in range(100):
        y = clean + rng.normal(0.0, NOISE_PA, t.size)
        fit = fit_pressure(model, t, y, first, 0.02, 0.012, other_onsets_s=[first - 0.004, second])
        reads.append(fit.moment_impulse_nms)
        sigmas.append(fit.sigma_nms)
    reads, sigmas = np.array(reads), np.array(sigmas)
    assert abs(np.mean(reads) - 5.0) < 3.0 * np.std(reads) / np.sqrt(reads.size)
    assert np.all(np.abs(reads - 5.0) < 5.0 * sigmas)
    assert np.std(reads) == pytest.approx(np.mean(sigmas), rel=0.3)


def test_onsets_closer_than_the_separation_are_read_together(model):
    """Two impulses 0.3 ms apart (less than a 2 kHz sample) cannot be told apart: the fit
    drops the neighbour's column, says so, and reads their sum (within 5 %)."""
    t = np.arange(0.0, 0.2, 1.0 / RATE_HZ)
    y = pressure(model, t, [(0.1, 4.0), (0.1003, 6.0)])
    fit = fit_pressure(
        model, t, y, 0.1, 0.02, 0.012, other_onsets_s=[0.1003], min_separation_s=0.001
    )
    assert fit.neighbours == 0 and fit.unresolved == 1
    assert fit.moment_impulse_nms == pytest.approx(10.0, rel=0.05)


def test_separable_onsets_keep_the_window_and_the_spacing():
    """Only onsets inside [lo, hi] count; one closer than the separation to the impact's onset
    or to a kept neighbour is unresolved."""
    kept, unresolved = separable_onsets(
        0.0, [-0.05, -0.01, -0.0095, 0.0004, 0.004, 0.03], -0.02, 0.012, 0.001
    )
    assert kept == [-0.01, 0.004]
    assert unresolved == 2


def test_without_neighbours_the_fit_is_the_single_impulse_fit(model):
    """No other onset in the window: the same numbers as without the argument (a sparse
    flow's features, and the training sets', do not change)."""
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 0.2, 1.0 / RATE_HZ)
    y = pressure(model, t, [(0.1, 7.0)]) + rng.normal(0.0, NOISE_PA, t.size)
    plain = fit_pressure(model, t, y, 0.1, 0.02, 0.012)
    far = fit_pressure(model, t, y, 0.1, 0.02, 0.012, other_onsets_s=[0.05, 0.15])
    assert far == plain
