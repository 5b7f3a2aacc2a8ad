"""Features of one detected impact, from the three signals, in physical units.

What the sensors can carry about a particle (docs/physics.md): the rigid beam answers to the
moment of the contact impulse about the hinge, M = J x (N m s), which both the IMU pulse and
the jack pressure measure; the camera gives the rebound speed; the time from the IMU pulse
to the camera's end-of-contact stamp, and the IMU pulse's own width at high IMU rates, carry
the contact duration, i.e. the particle's stiffness. Every feature is named with its unit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from tail_beam_id.signals.contact_fit import ContactFit
from tail_beam_id.signals.imu_detection import Pulse
from tail_beam_sim.config import fingerprint
from tail_beam_sim.physics.materials import material_table
from tail_beam_sim.physics.structure import LinearStructure, rigid_beam
from tail_beam_sim.physics.support import Support

SIGNALS = ("jack_pressure", "imu", "rebound_velocity")
# Feature flag (1.0 when present) of an impact whose acceleration features (the imu_* names, the
# rebound delay) came from the tail-beam accelerometer's ``vibration`` stream, not the IMU.
VIBRATION_CHANNEL = "vibration_channel"
FORCE_DURATION = "contact_force_duration_s"  # the contact force's duration above 5 % of its peak
# The acceleration channel's own moment impulse (N m s) where it said the beam turned against
# the jack's clear moment and the jack's stands for it (:func:`impact_features`).
IMU_MOMENT_READ = "moment_impulse_imu_read_nms"
# The jack's moment impulse is clear when it is this many of its standard errors above zero.
CLEAR_MOMENT_SIGMA = 3.0


MODEL_CACHE_SIZE = 64
_BEAM_MODELS: dict[str, BeamModel] = {}


@dataclass(frozen=True)
class BeamModel:
    """The identifier's belief about the support: the nominal rigid beam from config/."""

    support: Support
    structure: LinearStructure
    # The largest |pressure response| over [0, window] by window (s): the same for every impact.
    _pressure_peaks: dict[float, float] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> BeamModel:
        """The nominal beam from the merged ``support`` and ``materials`` parameters (built
        once per content of those sections: an identifier per impact builds it again)."""
        key = fingerprint(params.get("support"), params.get("materials"))
        known = _BEAM_MODELS.get(key) if key is not None else None
        if known is None:
            support = Support.from_params(params.get("support"), material_table(params))
            known = cls(support, rigid_beam(support))
            if key is not None:
                if len(_BEAM_MODELS) >= MODEL_CACHE_SIZE:
                    _BEAM_MODELS.clear()
                _BEAM_MODELS[key] = known
        return known

    @cached_property
    def sway_omega_radps(self) -> float:
        """The rigid beam's sway (its undamped mode on the jack), rad/s: the same for every
        impact (the support is not changed once the model is built)."""
        return 2.0 * math.pi * self.support.rigid_mode_frequency_hz

    @property
    def imu_moment_per_velocity(self) -> float:
        """Moment impulse about the hinge per m/s of plate velocity at the IMU, N m s / (m/s)."""
        return self.support.beam_inertia_about_hinge_kgm2 / self.support.imu_from_hinge_m

    def imu_velocity_response(self, t_s: np.ndarray) -> np.ndarray:
        """Plate velocity at the IMU (away from the particle) per m/s given to it at t = 0 by an
        impulse, on the rigid beam: 1 just after, then the 40 Hz sway; 0 before."""
        s = self.structure
        unit_moment = np.zeros(s.size)
        unit_moment[0] = 1.0
        qd0 = s.inv_mass @ unit_moment
        _, qd = s.propagate(np.zeros(s.size), qd0, np.clip(t_s, 0.0, None))
        response = (s.imu_shape @ qd) / (s.imu_shape @ qd0)
        return np.where(t_s >= 0.0, response, 0.0)

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

    def pressure_peak(self, window_s: float) -> float:
        """The largest |jack pressure change| per unit moment impulse within ``window_s`` of it
        (200 points over the window), Pa / (N m s); worked out once per window."""
        peak = self._pressure_peaks.get(window_s)
        if peak is None:
            response = self.pressure_response(np.linspace(0.0, window_s, 200))
            peak = self._pressure_peaks[window_s] = float(np.max(np.abs(response)))
        return peak


@dataclass(frozen=True)
class PressureFit:
    """Moment impulse fitted to the jack pressure around an onset, with its standard error;
    ``neighbours``: other impacts' impulses fitted with it (their onsets in the window),
    ``unresolved``: neighbours whose onsets lay too close to be told apart, read with it."""

    moment_impulse_nms: float
    sigma_nms: float
    noise_pa: float
    swing_pa: float
    saturated: bool
    neighbours: int = 0
    unresolved: int = 0


def separable_onsets(
    onset_s: float, other_onsets_s: Sequence[float], lo_s: float, hi_s: float, min_sep_s: float
) -> tuple[list[float], int]:
    """The onsets among ``other_onsets_s`` in [lo, hi] (s) that a joint fit can tell apart
    from ``onset_s`` and from each other (at least ``min_sep_s`` apart, the earlier kept), and
    how many in the window were not (they are read with the impulse they lie next to)."""
    kept: list[float] = []
    unresolved = 0
    for t in sorted(float(t) for t in other_onsets_s if lo_s <= t <= hi_s):
        if abs(t - onset_s) < min_sep_s or (kept and t - kept[-1] < min_sep_s):
            unresolved += 1
        else:
            kept.append(t)
    return kept, unresolved


def background_s(
    onset_s: float,
    other_onsets_s: Sequence[float],
    least_s: float,
    most_s: float,
    after_onset_s: float,
) -> float:
    """How long before ``onset_s`` (s) a read-out fits the background (the beam's free sway):
    up to ``most_s``, ending ``after_onset_s`` after the latest of ``other_onsets_s`` before the
    onset (an impact's kink is no free sway), and never shorter than ``least_s`` (an onset that
    close is in the stretch as it always was). The sway's phase is what a short stretch leaves
    uncertain: a tenth of a second pins it where 20 ms, half a period of a 40 Hz sway, does
    not."""
    earlier = [t for t in other_onsets_s if t < onset_s]
    if earlier:
        most_s = min(most_s, onset_s - max(earlier) - after_onset_s)
    return max(least_s, most_s)


def fit_pressure(
    model: BeamModel,
    stamp_s: np.ndarray,
    pressure_pa: np.ndarray,
    onset_s: float,
    pre_s: float,
    window_s: float,
    sway_drift: bool = False,
    other_onsets_s: Sequence[float] = (),
    min_separation_s: float = 0.0,
) -> PressureFit | None:
    """Least-squares fit of the pressure in [onset - pre, onset + window]: a constant plus the
    beam's free sway at its nominal frequency (earlier impacts still ringing) plus M times the
    response to a unit moment impulse at the onset. With ``sway_drift`` the free sway may also
    drift in frequency and decay across the window (t cos, t sin: their first order), which a
    real sway does against the nominal one. Other impacts whose onsets (``other_onsets_s``, s)
    lie in the window get an impulse column of their own (the support is linear: their
    responses add), so the onset's moment impulse is read even where they overlap; one closer
    than ``min_separation_s`` to the onset or to another kept onset is not separable and is
    read with it (:func:`separable_onsets`). None when too few samples."""
    inside = (stamp_s >= onset_s - pre_s) & (stamp_s <= onset_s + window_s)
    t = stamp_s[inside] - onset_s
    y = pressure_pa[inside]
    if t.size < 8 or not np.any(t > 0):
        return None
    saturated = _flat_lined(y)
    omega = model.sway_omega_radps
    template = model.pressure_response(t)
    columns = [np.ones_like(t), np.cos(omega * t), np.sin(omega * t)]
    if sway_drift:
        columns += [t * np.cos(omega * t), t * np.sin(omega * t)]
    others, unresolved = separable_onsets(
        0.0,
        [o - onset_s for o in other_onsets_s],
        -pre_s,
        window_s,
        min_separation_s,
    )
    # An onset with fewer than two samples after it says nothing of its impulse yet.
    others = [o for o in others if np.count_nonzero(t > o) >= 2]
    neighbour_columns = [model.pressure_response(t - o) for o in others]
    basis = np.vstack([*columns, template, *neighbour_columns]).T
    coeffs, *_ = np.linalg.lstsq(basis, y - y.mean(), rcond=None)
    residual = y - y.mean() - basis @ coeffs
    dof = max(t.size - basis.shape[1], 1)
    noise = float(math.sqrt(np.sum(residual**2) / dof))
    covariance = np.linalg.pinv(basis.T @ basis) * noise**2
    peak = model.pressure_peak(window_s)
    k = len(columns)  # the moment impulse's column
    return PressureFit(
        float(coeffs[k]),
        float(math.sqrt(covariance[k, k])),
        noise,
        float(coeffs[k]) * peak,
        saturated,
        len(others),
        unresolved,
    )


def _flat_lined(values: np.ndarray) -> bool:
    """True when a clipped transducer shows: two or more samples exactly at the window's
    extreme."""
    return bool(np.sum(values == values.max()) >= 2 or np.sum(values == values.min()) >= 2)


@dataclass(frozen=True)
class ImuImpulse:
    """Velocity given to the plate at the IMU by the contact (m/s), its standard error, and the
    RMS of what the rigid beam does not explain after it (bending modes ringing), m/s."""

    velocity_mps: float
    sigma_mps: float
    ring_mps: float


def imu_impulse(
    model: BeamModel,
    stamp_s: np.ndarray,
    accel_z: np.ndarray,
    pulse: Pulse,
    pre_s: float,
    skip_s: float,
    post_s: float,
    sway_drift: bool = False,
    other_onsets_s: Sequence[float] = (),
) -> ImuImpulse | None:
    """The pulse's velocity change, fitted in the velocity domain so the bending modes' ringing
    averages out: the specific force before the pulse gives the background (constant plus the
    beam's free sway; with ``sway_drift`` also its first-order drift in frequency and decay,
    t cos and t sin, which a stretch of several periods shows against the nominal sway); the
    plate velocity after it, integrated from the samples, is fitted with the rigid beam's
    response to an impulse at the onset, from ``skip_s`` (the contact is over) to ``post_s``
    after the onset. With other impacts' onsets (``other_onsets_s``, s) in or near the window,
    the steps are read jointly (:func:`_joint_step`)."""
    if other_onsets_s:
        return _joint_step(
            model, stamp_s, accel_z, pulse, (pre_s, skip_s, post_s), other_onsets_s, sway_drift
        )
    period = pulse.period_s
    before = (stamp_s >= pulse.onset_s - pre_s) & (stamp_s < pulse.onset_s)
    after = (stamp_s >= pulse.onset_s) & (stamp_s <= pulse.onset_s + post_s)
    if before.sum() < 4 or after.sum() < 2:
        return None
    omega = model.sway_omega_radps

    def sway(t: np.ndarray) -> np.ndarray:
        columns = [np.ones_like(t), np.cos(omega * t), np.sin(omega * t)]
        if sway_drift:
            columns += [t * columns[1], t * columns[2]]
        return np.vstack(columns).T

    t_before = stamp_s[before] - pulse.onset_s
    coeffs, *_ = np.linalg.lstsq(sway(t_before), accel_z[before], rcond=None)
    background = sway(stamp_s[after] - pulse.onset_s) @ coeffs
    # Plate velocity change at the end of each sample: specific force = g - plate acceleration.
    velocity = -np.cumsum(accel_z[after] - background) * period
    response = model.imu_velocity_response(stamp_s[after] - pulse.onset_s)
    use = stamp_s[after] >= pulse.onset_s + skip_s
    if not use.any():
        return None
    r, v = response[use], velocity[use]
    fitted = float(np.dot(r, v) / np.dot(r, r))
    residual = v - fitted * r
    ring = float(math.sqrt(np.mean(residual**2)))
    sigma = pulse.noise_mps2 * period * math.sqrt(max(after.sum(), 1) / 2.0)
    return ImuImpulse(fitted, sigma, ring)


def _joint_step(
    model: BeamModel,
    stamp_s: np.ndarray,
    accel_z: np.ndarray,
    pulse: Pulse,
    span_s: tuple[float, float, float],
    other_onsets_s: Sequence[float],
    sway_drift: bool,
) -> ImuImpulse | None:
    """:func:`imu_impulse` among other impacts' onsets (s), over ``span_s`` = (pre_s, skip_s,
    post_s): the plate velocity over the whole window, from pre_s before the onset to post_s
    after, integrated from the samples, is fitted at once with the background (a constant, a
    steady acceleration, the beam's free sway, with ``sway_drift`` its drift) and the rigid
    beam's response to an impulse at every onset in the window, each contact's first skip_s
    left out. The support is linear, so the other impacts' velocity steps and the sway they set
    going are columns of their own, not part of a background fitted across an earlier impact's
    kick (docs/identification.md, Features)."""
    pre_s, skip_s, post_s = span_s
    period = pulse.period_s
    onset = pulse.onset_s
    window = (stamp_s >= onset - pre_s) & (stamp_s <= onset + post_s)
    t = stamp_s[window] - onset
    if np.count_nonzero(t < 0.0) < 4 or np.count_nonzero(t >= skip_s) < 2:
        return None
    velocity = -np.cumsum(accel_z[window]) * period
    omega = model.sway_omega_radps
    onsets = sorted({0.0, *(o - onset for o in other_onsets_s if -pre_s < o - onset < post_s)})
    responses = [model.imu_velocity_response(t - o) for o in onsets]
    # The background's velocity: a constant, a steady acceleration (gravity, the sensor's
    # offset) and the free sway, with its drift over a long stretch.
    background = [np.ones_like(t), t, np.cos(omega * t), np.sin(omega * t)]
    if sway_drift:
        background += [t * background[2], t * background[3]]
    basis = np.vstack([*background, *responses]).T
    use = np.ones(t.size, dtype=bool)
    for o in onsets:
        use &= ~((t >= o) & (t < o + skip_s))
    if use.sum() <= basis.shape[1] or not np.all(np.isfinite(velocity[use])):
        return None  # too few samples, or a sample that is no number: nothing known of the step
    # Least squares by the normal equations of the unit-norm columns (an SVD of the whole
    # window costs ten times more; the small system's own least squares copes with columns
    # that nearly coincide).
    fitted = basis[use]
    scale = 1.0 / np.maximum(np.linalg.norm(fitted, axis=0), 1e-300)
    fitted = fitted * scale
    coeffs = np.linalg.lstsq(fitted.T @ fitted, fitted.T @ velocity[use], rcond=None)[0] * scale
    own = len(background) + onsets.index(0.0)
    after = use & (t >= skip_s)
    residual = velocity[after] - basis[after] @ coeffs
    ring = float(math.sqrt(np.mean(residual**2)))
    sigma = pulse.noise_mps2 * period * math.sqrt(max(np.count_nonzero(t >= 0.0), 1) / 2.0)
    return ImuImpulse(float(coeffs[own]), sigma, ring)


def jack_denies_step(imu_moment_nms: float, pressure: PressureFit) -> bool:
    """Whether the jack's fit says an acceleration channel's moment impulse (N m s) is not the
    rigid beam's: a strike pushes the beam down about the hinge, and a velocity step that says
    it turned the other way while the jack's moment stands CLEAR_MOMENT_SIGMA standard errors
    above zero saw a bending mode's motion (a sensor where a slow mode's shape is large). Only
    for an impact alone in the jack's fit: in a dense flow the others' responses are in both
    reads (and the gangue-share model learnt such impacts' scores as read)."""
    return (
        imu_moment_nms <= 0.0
        and not pressure.saturated
        and not pressure.neighbours
        and not pressure.unresolved
        and pressure.moment_impulse_nms > CLEAR_MOMENT_SIGMA * pressure.sigma_nms
    )


def impact_features(
    model: BeamModel,
    pulse: Pulse | None,
    impulse: ImuImpulse | None,
    pressure: PressureFit | None,
    rebound: tuple[float, np.ndarray] | None,
    contact: ContactFit | None = None,
    contact_half_periods: float | None = None,
    calibrated: bool = False,
) -> dict[str, float]:
    """The feature dict of one impact from whatever signals there are (missing ones absent);
    ``contact_half_periods``: how many half periods of the slowest mode the contact force lasts
    (:func:`tail_beam_id.signals.contact_fit.half_periods`); ``calibrated``: the support's jack
    gain was read from its own recording (a profile), so that its moment may stand for an
    acceleration channel's that turned against it."""
    features: dict[str, float] = {}
    imu_estimate = pressure_estimate = None  # (moment impulse, its standard error), N m s
    if pulse is not None and impulse is not None:
        moment = impulse.velocity_mps * model.imu_moment_per_velocity
        features["moment_impulse_imu_nms"] = moment
        features["imu_impulse_mps"] = impulse.velocity_mps
        features["imu_ring_ratio"] = impulse.ring_mps / max(abs(impulse.velocity_mps), 1e-12)
        features["imu_pulse_sigma"] = pulse.peak_sigma
        features["imu_noise_mps2"] = pulse.noise_mps2
        features["imu_pulse_polarity"] = float(pulse.polarity)
        features["imu_pulse_width_s"] = pulse.width_s
        features["imu_period_s"] = pulse.period_s
        if contact is not None:
            # The contact's duration (the best-fitting pulse's) from the pulse and the ringing
            # (tail_beam_id.signals.contact_fit; a channel too slow to show it gives its sample
            # period). Without it (a fast channel's samples cut short) the acceleration features
            # are not all there, and the models decide without them
            # (methods.statistical.signals_of).
            features["contact_duration_s"] = contact.duration_s
            if contact.force is not None:
                # The force history read through the ringing (signals.contact_force): where it
                # ends, how soon it peaks, how well the model held (x the noise RMS).
                features[FORCE_DURATION] = contact.force.duration_s
                features["contact_force_rise_s"] = contact.force.rise_s
                features["contact_force_chi"] = contact.force.chi
                features["contact_force_residual"] = contact.force.residual_noise_ratio
                features["contact_force_unexplained"] = contact.force.unexplained
                if contact_half_periods is not None:
                    features["contact_force_half_periods"] = contact_half_periods
        imu_estimate = (
            moment,
            max(impulse.sigma_mps, impulse.ring_mps) * model.imu_moment_per_velocity,
        )
    if pressure is not None and not pressure.saturated:
        features["moment_impulse_pressure_nms"] = pressure.moment_impulse_nms
        features["pressure_swing_pa"] = pressure.swing_pa
        features["pressure_noise_pa"] = pressure.noise_pa
        # Other impacts in the fit's window, only when there were some (a lone impact's features
        # are those the models were trained on): those read jointly with it, and those too close
        # to tell apart, whose impulses its moment impulse includes.
        if pressure.neighbours:
            features["pressure_neighbours"] = float(pressure.neighbours)
        if pressure.unresolved:
            features["pressure_unresolved"] = float(pressure.unresolved)
        pressure_estimate = (pressure.moment_impulse_nms, pressure.sigma_nms)
        if (
            calibrated
            and imu_estimate is not None
            and jack_denies_step(imu_estimate[0], pressure)
        ):
            # The jack's moment stands for the channel's, and the combined estimate rests on the
            # jack alone: read at the models' log floor, the step would tell them of a tiny
            # impact the jack denies. Only on a calibrated support (a single-impact bag too
            # short to read the sway gave both reads far off).
            features[IMU_MOMENT_READ] = imu_estimate[0]
            features["moment_impulse_imu_nms"] = pressure.moment_impulse_nms
            imu_estimate = None
    estimates = [e for e in (imu_estimate, pressure_estimate) if e is not None]
    if estimates:
        weights = np.array([1.0 / max(s, 1e-12) ** 2 for _, s in estimates])
        values = np.array([m for m, _ in estimates])
        features["moment_impulse_nms"] = float(np.sum(weights * values) / weights.sum())
        features["moment_impulse_sigma_nms"] = float(1.0 / math.sqrt(weights.sum()))
    if rebound is not None:
        stamp, velocity = rebound
        features["rebound_speed_mps"] = float(velocity[2])
        # Across the plate the true rebound is zero (a normal impact): what the camera reads
        # there is its noise, m/s.
        features["rebound_cross_mps"] = float(math.hypot(velocity[0], velocity[1]))
        if pulse is not None:
            # From the start of the first deviating IMU sample to the camera's end-of-contact
            # stamp: the contact duration plus up to one IMU period and one camera frame.
            features["rebound_delay_s"] = float(stamp - (pulse.first_stamp_s - pulse.period_s))
    return features
