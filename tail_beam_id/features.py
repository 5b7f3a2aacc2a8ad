"""Features of one detected impact, from the three signals, in physical units.

What the sensors can carry about a particle (physics.md): the rigid beam answers to the
moment of the contact impulse about the hinge, M = J x (N m s), which both the IMU pulse and
the jack pressure measure; the camera gives the rebound speed; the time from the IMU pulse
to the camera's end-of-contact stamp, and the IMU pulse's own width at high IMU rates, carry
the contact duration, i.e. the particle's stiffness. Every feature is named with its unit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from tail_beam_id.detection import Pulse
from tail_beam_sim.materials import material_table
from tail_beam_sim.structure import LinearStructure, rigid_beam
from tail_beam_sim.support import Support

SIGNALS = ("jack_pressure", "imu", "rebound_velocity")
# RMS width of a half-sine pulse over its duration: sqrt(1/4 - 2/pi^2).
HALF_SINE_WIDTH_RATIO = math.sqrt(0.25 - 2.0 / math.pi**2)


@dataclass(frozen=True)
class BeamModel:
    """The identifier's belief about the support: the nominal rigid beam from config/."""

    support: Support
    structure: LinearStructure

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> BeamModel:
        """The nominal beam from the merged ``support`` and ``materials`` parameters."""
        support = Support.from_params(params.get("support"), material_table(params))
        return cls(support, rigid_beam(support))

    @property
    def imu_moment_per_velocity(self) -> float:
        """Moment impulse about the hinge per m/s of plate velocity at the IMU, N m s / (m/s)."""
        return self.support.beam_inertia_about_hinge_kgm2 / self.support.imu_from_hinge_m

    def pressure_response(self, t_s: np.ndarray) -> np.ndarray:
        """Jack pressure change per unit moment impulse at t = 0, Pa / (N m s); 0 before it."""
        s = self.structure
        unit_moment = np.zeros(s.size)
        unit_moment[0] = 1.0
        qd0 = s.inv_mass @ unit_moment
        after = np.clip(t_s, 0.0, None)
        q, qd = s.propagate(np.zeros(s.size), qd0, after)
        response = s.pressure_pa(q, qd) - s.setting_pressure_pa
        return np.where(t_s >= 0.0, response, 0.0)


@dataclass(frozen=True)
class PressureFit:
    """Moment impulse fitted to the jack pressure around an onset, with its standard error."""

    moment_impulse_nms: float
    sigma_nms: float
    noise_pa: float
    swing_pa: float
    saturated: bool


def fit_pressure(
    model: BeamModel, stamp_s: np.ndarray, pressure_pa: np.ndarray, onset_s: float, pre_s: float, window_s: float
) -> PressureFit | None:
    """Least-squares fit of the pressure in [onset - pre, onset + window]: a constant plus the
    beam's free sway at its nominal frequency (earlier impacts still ringing) plus M times the
    response to a unit moment impulse at the onset. None when too few samples."""
    inside = (stamp_s >= onset_s - pre_s) & (stamp_s <= onset_s + window_s)
    t = stamp_s[inside] - onset_s
    y = pressure_pa[inside]
    if t.size < 8 or not np.any(t > 0):
        return None
    saturated = _flat_lined(y)
    omega = 2.0 * math.pi * model.support.rigid_mode_frequency_hz
    template = model.pressure_response(t)
    basis = np.vstack([np.ones_like(t), np.cos(omega * t), np.sin(omega * t), template]).T
    coeffs, *_ = np.linalg.lstsq(basis, y - y.mean(), rcond=None)
    residual = y - y.mean() - basis @ coeffs
    dof = max(t.size - basis.shape[1], 1)
    noise = float(math.sqrt(np.sum(residual**2) / dof))
    covariance = np.linalg.pinv(basis.T @ basis) * noise**2
    peak = float(np.max(np.abs(model.pressure_response(np.linspace(0.0, window_s, 200)))))
    return PressureFit(float(coeffs[3]), float(math.sqrt(covariance[3, 3])), noise, float(coeffs[3]) * peak, saturated)


def _flat_lined(values: np.ndarray) -> bool:
    """True when a clipped transducer shows: two or more samples exactly at the window's extreme."""
    return bool(np.sum(values == values.max()) >= 2 or np.sum(values == values.min()) >= 2)


def pulse_duration_s(pulse: Pulse) -> float:
    """Contact duration from the IMU pulse's RMS width (half-sine force), s; 0 if unresolved."""
    excess = pulse.width_s**2 - pulse.period_s**2 / 12.0
    return math.sqrt(excess) / HALF_SINE_WIDTH_RATIO if excess > 0.0 else 0.0


def impact_features(
    model: BeamModel,
    pulse: Pulse | None,
    pressure: PressureFit | None,
    rebound: tuple[float, np.ndarray] | None,
) -> dict[str, float]:
    """The feature dict of one impact from whatever signals there are (missing ones absent)."""
    features: dict[str, float] = {}
    estimates = []
    if pulse is not None:
        moment = pulse.impulse_mps * model.imu_moment_per_velocity
        sigma = pulse.noise_mps2 * pulse.period_s * math.sqrt(max(pulse.last_index - pulse.first_index + 1, 1))
        features["moment_impulse_imu_nms"] = moment
        features["imu_impulse_mps"] = pulse.impulse_mps
        features["imu_pulse_sigma"] = pulse.peak_sigma
        features["imu_pulse_width_s"] = pulse.width_s
        features["imu_pulse_duration_s"] = pulse_duration_s(pulse)
        features["imu_period_s"] = pulse.period_s
        estimates.append((moment, sigma * model.imu_moment_per_velocity))
    if pressure is not None and not pressure.saturated:
        features["moment_impulse_pressure_nms"] = pressure.moment_impulse_nms
        features["pressure_swing_pa"] = pressure.swing_pa
        features["pressure_noise_pa"] = pressure.noise_pa
        estimates.append((pressure.moment_impulse_nms, pressure.sigma_nms))
    if estimates:
        weights = np.array([1.0 / max(s, 1e-12) ** 2 for _, s in estimates])
        values = np.array([m for m, _ in estimates])
        features["moment_impulse_nms"] = float(np.sum(weights * values) / weights.sum())
    if rebound is not None:
        stamp, velocity = rebound
        features["rebound_speed_mps"] = float(velocity[2])
        if pulse is not None:
            features["rebound_delay_s"] = float(stamp - pulse.centroid_s)
    return features
