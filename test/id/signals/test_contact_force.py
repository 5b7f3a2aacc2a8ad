"""The contact force's shape read through the support's ringing
(tail_beam_id.signals.contact_force): against a hysteretic Hertz force of known span through a
second mode at twice the first, and against the simulator's own force on such a support, where
the contact lasts longer than half a period of a mode."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from id_helpers import impact
from scipy.integrate import solve_ivp

from tail_beam_id.signals.contact_fit import ContactFitConfig, fit_contact
from tail_beam_id.signals.contact_force import END_FRACTION, pulse_shapes
from tail_beam_id.study.supports import tabulated_modes

RATE_HZ = 25600.0


def _hertz_force(chi: float, t_s: np.ndarray, span_s: float) -> np.ndarray:
    """A sphere's force on a rigid plate, F = K d^1.5 (1 + chi d'/v0), integrated here by scipy
    (independently of the module's own table), peak 1, its time scaled so that it stays above
    END_FRACTION of its peak for ``span_s``; at ``t_s`` (s, 0 = first touch)."""

    def rhs(_, s):
        d, v = s
        return [v, -max(max(d, 0.0) ** 1.5 * (1.0 + chi * v), 0.0)]

    def leaves(_, s):
        return s[0] + 1e-12

    leaves.terminal, leaves.direction = True, -1
    sol = solve_ivp(
        rhs, (0.0, 20.0), [1e-12, 1.0], max_step=2e-3, rtol=1e-9, atol=1e-12, events=leaves
    )
    d, v = sol.y
    f = np.clip(np.clip(d, 0.0, None) ** 1.5 * (1.0 + chi * v), 0.0, None)
    f /= f.max()
    above = np.flatnonzero(f >= END_FRACTION)
    scale = span_s / (sol.t[above[-1]] - sol.t[above[0]])
    return np.interp(t_s, sol.t * scale, f, left=0.0, right=0.0)


def test_the_shapes_span_one_unit_above_the_end_fraction_and_peak_sooner_with_hysteresis():
    """Every tabulated shape lasts one unit above END_FRACTION of its peak; chi 0 is an elastic
    pulse, symmetric (peak half-way); more hysteresis peaks sooner within that span up to chi 2
    (beyond, the span above END_FRACTION keeps its shape and the tail below it grows) and its
    whole contact lasts longer. The linear elastic shape is a half-sine: its own best half-sine
    is its whole contact."""
    shapes = pulse_shapes()
    for s in shapes:
        above = s.times[s.force >= END_FRACTION]
        assert above[-1] - above[0] == pytest.approx(1.0, abs=2e-3)
    for exponent in (1.0, 1.5):
        mine = [s for s in shapes if s.exponent == exponent]
        assert mine[0].chi == 0.0
        assert mine[0].peak_time - mine[0].lead == pytest.approx(0.5, abs=0.01)
        rises = [s.peak_time - s.lead for s in mine if s.chi <= 2.0]
        assert rises == sorted(rises, reverse=True)
        assert rises[-1] < 0.3
        ends = [s.times[-1] for s in mine]
        assert ends == sorted(ends)
    linear = next(s for s in shapes if s.exponent == 1.0 and s.chi == 0.0)
    assert linear.half_sine == pytest.approx(1.0 + 2 * linear.lead, abs=0.03)


@pytest.mark.parametrize("chi", [0.5, 2.5])
def test_a_long_hysteretic_force_through_a_mode_pair_two_to_one_is_recovered(chi):
    """A Hertz force with hysteresis (chi between the module's tabulated ones) lasting 800 us
    above 5 % of its peak, longer than half a period of the 700 Hz mode (714 us), passed
    directly (the rigid beam) and through modes at 350 and 700 Hz (the second 2x the first),
    convolved numerically on a 1 MHz grid and sampled at 25.6 kHz with 0.2 m/s^2 noise. The
    force read-out gives the span within 10 %: the duration grid's refined step (4.5 %), one
    sample (39 us, 5 %) at either end interpolated, and a chi between two tabulated shapes.
    The best half-sine reads it at most 0.8 of that (it matches the main lobe)."""
    dense_step = 1e-6
    span_s = 8.0e-4
    t_dense = np.arange(-0.01, 0.01, dense_step)
    force = _hertz_force(chi, t_dense, span_s)
    response = 60.0 * force
    for frequency_hz, zeta, gain in ((350.0, 0.02, 1.5e5), (700.0, 0.02, -2.5e5)):
        omega = 2 * math.pi * frequency_hz
        tau = np.arange(0.0, 0.01, dense_step)
        kernel = gain * np.exp(-zeta * omega * tau) * np.sin(omega * math.sqrt(1 - zeta**2) * tau)
        response += np.convolve(force, kernel)[: t_dense.size] * dense_step
    stamps = np.arange(-0.005, 0.009, 1.0 / RATE_HZ)
    samples = (
        np.interp(stamps, t_dense, response)
        + np.random.default_rng(2).normal(0.0, 0.2, stamps.size)
        + 9.81
    )
    fit = fit_contact(stamps, samples, 0.0, 1.0 / RATE_HZ, 0.2, ContactFitConfig())
    assert fit is not None and fit.force is not None
    assert fit.force.duration_s == pytest.approx(span_s, rel=0.10)
    assert fit.duration_s < 0.8 * span_s
    assert fit.force.residual_noise_ratio < 3.0


def _force_span_s(result) -> float:
    """How long the simulated contact force stays above END_FRACTION of its peak, s."""
    t, f = result.history["time_s"], result.history["contact_force_n"]
    above = np.flatnonzero(f >= END_FRACTION * f.max())
    return float(t[above[-1]] - t[above[0]])


@pytest.mark.parametrize(
    "material, radius_m", [("mudstone", 0.08), ("coal", 0.095), ("sandstone", 0.09)]
)
def test_a_contact_longer_than_half_a_mode_period_reads_as_the_simulated_force(
    params, material, radius_m
):
    """A support whose bending modes are 420 and 840 Hz (the second 2x the first, 300 kg each):
    a large particle's contact (0.5-1 ms to separation) lasts longer than half a period of the
    840 Hz mode (595 us). The force read-out gives the simulator's own force span above 5 % of
    its peak within 15 % (the synthetic case's 10 %, plus the plate's motion, which bends the
    force away from a rigid plate's shapes, and the accelerometer's anti-alias filter)."""
    support = copy.deepcopy(params)
    support["modes"] = tabulated_modes(params["modes"], ((420.0, 300.0), (840.0, 300.0)))
    result = impact(
        support, material=material, radius_m=radius_m, drop_height_m=3.5, position_m=1.0
    )
    truth = result.truth()
    assert truth["final_separation_stamp"] - truth["contact_start_stamp"] > 0.5 / 840.0
    blocks = result.vibration
    samples = np.concatenate([blocks.block(b)[2] for b in range(blocks.count)]).astype(float)
    t = blocks.sample_stamps_s() - result.contact_stamp_s
    fit = fit_contact(
        t, samples, 0.0, blocks.period_s, math.sqrt(blocks.noise_variance), ContactFitConfig()
    )
    assert fit is not None and fit.force is not None
    assert fit.force.duration_s == pytest.approx(_force_span_s(result), rel=0.15)
