"""Self-calibration: a support profile learned from the support's own recording, no labels.

Every real support differs from ``config/``. What the identifier needs to know about it can be
read off its own signals:

- the IMU's mounting (upside down or not): gravity's sign on the accelerometer's z axis;
- the jack's pressure-to-moment gain: on the rigid beam, a moment impulse M about the hinge
  swings the jack pressure by ``omega M / (d S)`` (omega the beam's sway on the oil column, d
  the jack's lever arm, S its piston area; docs/physics.md), whatever the beam's inertia. The
  sway frequency shows as the peak of the pressure's spectrum, so the jack stiffness that
  gives it is solved for (the geometry d, S as configured);
- the IMU's moment-per-velocity gain (beam inertia over the IMU's distance from the hinge): the
  weighted least-squares ratio, over the recording's impacts that no other crowds
  (:func:`gain_impacts`), of the moment the calibrated jack pressure saw to the velocity step
  the IMU saw (:func:`imu_gain`);
- the beam's bending modes as the acceleration channel sees them ring after each impact (their
  frequencies and damping, tail_beam_id.calibration.modes): the slowest one's decay time becomes
  the detector's ``ring_decay_s``, so that a lightly damped beam's ringing is followed for as long
  as it lasts and a stiff, well damped beam's no longer than it does;
- the camera's frame period, from the grid of all the recording's rebound stamps
  (tail_beam_id.signals.camera): the identifier otherwise reads it from the stamps up to each
  impact, and assumes config/'s camera until four rebounds have come, so a slow camera's first
  impacts were decided as if its lag were a 5 kHz camera's;
- the support's contact hysteresis (tail_beam_id.methods.hysteresis): which of the trained
  hysteresis bins the recording's impacts, taken together, fit best (no labels: each bin's coal
  share is fitted too), so that the statistical method decides each impact knowing it;
- the noise of each sensor.

The result is a ROS 2 parameter file (``tail-beam calibrate BAG --out profile.yaml``) that
``tail-beam identify --config`` and ``id_node --params-file`` load.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from tail_beam_id.calibration.modes import MIN_FREQUENCY_HZ as MIN_MODE_FREQUENCY_HZ
from tail_beam_id.calibration.modes import RingingMode, ring_decay_s, ringing_modes, sample_noise
from tail_beam_id.methods import hysteresis, load_model
from tail_beam_id.methods.statistical import HYSTERESIS
from tail_beam_id.signals.camera import GRIDLESS_PERIOD_S, MIN_REBOUNDS, measured_period_s
from tail_beam_id.signals.contact_fit import unbroken
from tail_beam_id.signals.features import IMU_MOMENT_READ
from tail_beam_id.signals.innovations import fit_predictor
from tail_beam_id.signals.timing import UNUSUAL, TimingConfig, judge
from tail_beam_id.stream.label import Label
from tail_beam_sim.config import deep_merge
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.materials import material_table
from tail_beam_sim.physics.support import Support

SWAY_BAND_HZ = (5.0, 300.0)  # where the beam's sway on the jack can be (nominal 39 Hz)
MIN_PEAK_RATIO = 8.0  # the sway peak must stand this far above the spectrum's median in the band
# The spectrum's bins must be at most this fraction of the sway frequency found: a recording too
# short to resolve it (one 55 ms impact put a 39.3 Hz sway at 37.2 Hz: 18 Hz bins) measures
# nothing.
MAX_BIN_FRACTION = 0.05
MIN_IMPACTS = 3  # impacts needed for the IMU gain
GAIN_SIGMA = (
    5.0  # the IMU gain is measured when its fit is this many standard errors clear of zero
)


@dataclass(frozen=True)
class SupportProfile:
    """What a recording says about its support (units in the names; None: not measurable)."""

    duration_s: float
    impacts_used: int
    imu_mount_sign: float | None
    rigid_mode_frequency_hz: float | None
    oil_bulk_modulus_pa: float | None
    beam_inertia_about_hinge_kgm2: float | None
    imu_gain_spread: float | None  # robust relative spread of the per-impact IMU gains
    pressure_noise_pa: float | None
    imu_accel_noise_mps2: float | None
    # Impacts of the pass whose delay from onset to camera stamp the statistical method checked,
    # and those it found unusual (tail_beam_id.signals.timing: too many, and the sensors' clocks
    # may be offset; the identifier then caps the labels that use the delay from the first one on).
    delay_checked_impacts: int | None = None
    delay_unusual_impacts: int | None = None
    # The bending modes the impacts set ringing (tail_beam_id.calibration.modes), ascending: Hz and
    # damping ratio; None when none could be measured (too few impacts, or the channel too slow).
    ringing_modes_hz: list[float] | None = None
    ringing_damping_ratios: list[float] | None = None
    # The camera's frame rate read from the grid of every rebound stamp, Hz (1 / GRIDLESS_PERIOD_S:
    # stamps on no grid); None from fewer than MIN_REBOUNDS.
    camera_frame_rate_hz: float | None = None
    # The weight of each hysteresis bin of the statistical model (tail_beam_id.methods.hysteresis)
    # and the impacts they rest on; None when too few impacts had every signal.
    hysteresis_weights: list[float] | None = None
    hysteresis_impacts: int | None = None
    hysteresis_bin_edges: list[float] | None = None  # the bins the weights are of (the model's)
    # The accelerometer's one-step ringing predictor (tail_beam_id.signals.innovations) and the
    # rate it was fitted at, Hz; None unless identification.detection.vibration_innovations.
    vibration_predictor: list[float] | None = None
    vibration_predictor_rate_hz: float | None = None

    @property
    def ring_decay_s(self) -> float | None:
        """The detector's ring_decay_s for the measured modes (s), or None."""
        if not self.ringing_modes_hz or not self.ringing_damping_ratios:
            return None
        return ring_decay_s(
            [
                RingingMode(f, z, 0)
                for f, z in zip(self.ringing_modes_hz, self.ringing_damping_ratios)
            ]
        )

    def describe_modes(self) -> str:
        """The measured bending modes in a few words ('ringing 400 Hz (3.7 %), 1269 Hz (1.5
        %)')."""
        if not self.ringing_modes_hz or not self.ringing_damping_ratios:
            return "no bending mode measured in the ringing"
        modes = ", ".join(
            f"{f:.0f} Hz ({100.0 * z:.1f} %)"
            for f, z in zip(self.ringing_modes_hz, self.ringing_damping_ratios)
        )
        return f"ringing {modes}, ring_decay_s {self.ring_decay_s:.3g}"

    def describe_hysteresis(self) -> str:
        """The support's hysteresis as read, in a few words."""
        if self.hysteresis_impacts is None:
            return "hysteresis not read (the statistical model has no hysteresis network)"
        return hysteresis.describe(
            self.hysteresis_weights, self.hysteresis_impacts, self.hysteresis_bin_edges or []
        )

    def describe_predictor(self) -> str:
        """The accelerometer's ringing predictor, in a few words."""
        if self.vibration_predictor is None:
            return "no ringing predictor (no accelerometer, or vibration_innovations off)"
        return (
            f"ringing predictor of order {len(self.vibration_predictor)} at "
            f"{self.vibration_predictor_rate_hz:.0f} Hz"
        )

    def describe_camera(self) -> str:
        """The camera's frame as read from the rebound stamps, in a few words."""
        if self.camera_frame_rate_hz is None:
            return f"camera frame not read (fewer than {MIN_REBOUNDS} rebounds)"
        if self.camera_frame_rate_hz >= 1.0 / GRIDLESS_PERIOD_S:
            return "camera stamps on no frame grid: taken as the contact's end itself"
        return f"camera {self.camera_frame_rate_hz:.0f} frames/s"

    @property
    def calibrated(self) -> bool:
        return self.rigid_mode_frequency_hz is not None

    def parameters(self) -> dict[str, Any]:
        """The profile as a ROS 2 parameter file's content (``/**: ros__parameters:``)."""
        support: dict[str, Any] = {}
        if self.oil_bulk_modulus_pa is not None:
            support["oil_bulk_modulus_pa"] = self.oil_bulk_modulus_pa
        if self.beam_inertia_about_hinge_kgm2 is not None:
            support["beam_inertia_about_hinge_kgm2"] = self.beam_inertia_about_hinge_kgm2
        section: dict[str, Any] = {"support": support} if support else {}
        if self.camera_frame_rate_hz is not None:
            section["sensors"] = {"camera_frame_rate_hz": self.camera_frame_rate_hz}
        if self.ring_decay_s is not None:
            section["identification"] = {"detection": {"ring_decay_s": self.ring_decay_s}}
        section["calibration"] = {k: v for k, v in asdict(self).items() if v is not None}
        return {"/**": {"ros__parameters": section}}


def robust_noise(values: np.ndarray) -> float | None:
    """Noise RMS of a sampled signal from the median absolute first difference (slow motion and
    the odd impact barely move it: tail_beam_id.calibration.modes.sample_noise), in the signal's
    unit; None with fewer than 16 samples."""
    return None if values.size < 16 else sample_noise(values)


def mount_sign(accel_z_mps2: np.ndarray) -> float | None:
    """+1 when the accelerometer's z reads +g at rest (mounted as configured), -1 upside down."""
    if accel_z_mps2.size < 16:
        return None
    median = float(np.median(accel_z_mps2))
    return None if abs(median) < 2.0 else math.copysign(1.0, median)


def sway_frequency(stamp_s: np.ndarray, pressure_pa: np.ndarray) -> float | None:
    """The beam's sway on the oil column, Hz: the peak of the jack pressure's spectrum in
    SWAY_BAND_HZ (refined by a parabola through the peak's log power), or None without a clear
    peak (no impacts to excite it) or when the recording is too short to resolve it."""
    if stamp_s.size < 64:
        return None
    period = float(np.median(np.diff(stamp_s)))
    rate = 1.0 / period
    segment = min(stamp_s.size, int(2.0 * rate))  # 0.5 Hz resolution where the recording allows
    # scipy.signal and scipy.optimize are imported where used: importing them takes a second
    # or two, which id_node's start (and every process that imports it) need not pay.
    from scipy.signal import welch

    freq, power = welch(
        pressure_pa - np.mean(pressure_pa), fs=rate, nperseg=segment, detrend="linear"
    )
    band = (freq >= SWAY_BAND_HZ[0]) & (freq <= min(SWAY_BAND_HZ[1], 0.4 * rate))
    if band.sum() < 5:
        return None
    index = np.flatnonzero(band)
    peak = index[int(np.argmax(power[band]))]
    if power[peak] < MIN_PEAK_RATIO * float(np.median(power[band])) or peak in (
        index[0],
        index[-1],
    ):
        return None
    y0, y1, y2 = np.log(power[peak - 1 : peak + 2])
    shift = 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2) if (y0 - 2 * y1 + y2) != 0 else 0.0
    found = float(freq[peak] + shift * (freq[1] - freq[0]))
    return found if freq[1] - freq[0] <= MAX_BIN_FRACTION * found else None


def bulk_modulus_for(params: Mapping[str, Any], frequency_hz: float) -> float | None:
    """The oil bulk modulus (Pa) that gives the configured support this sway frequency (the
    jack's other compliances, geometry and the beam's inertia as configured)."""
    materials = material_table(params)

    def mismatch(log_scale: float) -> float:
        varied = copy.deepcopy(dict(params["support"]))
        varied["oil_bulk_modulus_pa"] = float(params["support"]["oil_bulk_modulus_pa"]) * math.exp(
            log_scale
        )
        return math.log(
            Support.from_params(varied, materials).rigid_mode_frequency_hz / frequency_hz
        )

    from scipy.optimize import brentq

    try:
        return float(params["support"]["oil_bulk_modulus_pa"]) * math.exp(
            brentq(mismatch, math.log(0.02), math.log(50.0), xtol=1e-6)
        )
    except ValueError:
        return (
            None  # no oil column in that range gives it: the wall or the rod limits the stiffness
        )


def calibrate(
    params: Mapping[str, Any],
    pressure: tuple[np.ndarray, np.ndarray],
    imu: tuple[np.ndarray, np.ndarray],
    identify: Callable[[dict[str, Any]], Sequence[Label]],
    ringing: tuple[np.ndarray, np.ndarray] | None = None,
    rebound_stamps_s: Sequence[float] = (),
    hysteresis_model: Mapping[str, Any] | None = None,
) -> SupportProfile:
    """The profile of the support that recorded ``pressure`` (stamps s, Pa) and ``imu`` (stamps
    s, z specific force m/s^2). ``identify(params)`` must return the labels of the recording
    identified with those parameters (the IMU gain needs each impact's moment estimates, the
    modes each impact's onset). ``ringing`` (stamps s, m/s^2) is the channel the bending modes
    are read from: the tail-beam accelerometer where there is one (it sees modes up to ten
    times higher), else the IMU's z. ``rebound_stamps_s`` (s) give the camera's frame.
    ``hysteresis_model``: the statistical model's hysteresis network (default: the shipped
    one's)."""
    # A sample with a non-finite stamp or value is a lost sample here too, as for the identifier
    # (one NaN pressure sample made the spectrum, and so the whole calibration, fail).
    p_stamp, p_value = _finite(*pressure)
    i_stamp, i_accel = _finite(*imu)
    if p_stamp.size == 0 and i_stamp.size == 0:
        raise InputError(
            "bag",
            "no jack_pressure and no imu",
            "calibration needs the recording's jack pressure or IMU",
        )
    duration = float(
        max(np.ptp(p_stamp) if p_stamp.size else 0.0, np.ptp(i_stamp) if i_stamp.size else 0.0)
    )
    sign = mount_sign(i_accel)
    frequency = sway_frequency(p_stamp, p_value)
    bulk = bulk_modulus_for(params, frequency) if frequency is not None else None
    inertia = None
    spread = None
    used = 0
    checked = unusual = None
    modes: list[RingingMode] = []
    weights: list[float] | None = None
    weighed = edges = None
    if bulk is not None:
        calibrated = copy.deepcopy(dict(params))
        calibrated["support"]["oil_bulk_modulus_pa"] = bulk
        labels = identify(calibrated)
        checked, unusual = delay_checks(params, labels)
        fitted = imu_gain([label.features for label in gain_impacts(params, labels)])
        r_stamp, r_accel = _finite(*ringing) if ringing is not None else (i_stamp, i_accel)
        modes = ringing_modes(
            r_stamp,
            r_accel,
            [label.impact_stamp_s for label in labels],
            min_frequency_hz=max(MIN_MODE_FREQUENCY_HZ, 2.0 * frequency),
        )
        if fitted is not None:
            gain, used, spread = fitted  # N m s per m/s at the IMU = inertia / IMU distance
            inertia_now = float(params["support"]["beam_inertia_about_hinge_kgm2"])
            imu_from_hinge = float(params["support"]["imu_from_hinge_m"])
            inertia = gain * imu_from_hinge
            if not 0.2 < inertia / inertia_now < 5.0:
                inertia, spread = None, None  # implausible: keep the configured beam (and its oil)
            else:
                # The sway frequency must still come out: the oil column follows the new inertia.
                calibrated["support"]["beam_inertia_about_hinge_kgm2"] = inertia
                bulk = bulk_modulus_for(calibrated, frequency) or bulk
        weights, weighed, edges = _hysteresis_weights(
            params, gain_impacts(params, labels), inertia, hysteresis_model
        )
    profile = SupportProfile(
        duration_s=duration,
        impacts_used=used,
        imu_mount_sign=sign,
        rigid_mode_frequency_hz=frequency,
        oil_bulk_modulus_pa=bulk,
        beam_inertia_about_hinge_kgm2=inertia,
        imu_gain_spread=spread,
        pressure_noise_pa=robust_noise(p_value),
        imu_accel_noise_mps2=robust_noise(i_accel),
        delay_checked_impacts=checked,
        delay_unusual_impacts=unusual,
        ringing_modes_hz=[m.frequency_hz for m in modes] or None,
        ringing_damping_ratios=[m.damping_ratio for m in modes] or None,
        camera_frame_rate_hz=_camera_frame_rate_hz(rebound_stamps_s),
        hysteresis_weights=weights,
        hysteresis_impacts=weighed,
        hysteresis_bin_edges=edges if weights is not None else None,
        **ringing_predictor(params, ringing),
    )
    return _timing_rechecked(params, profile, identify)


def gain_impacts(params: Mapping[str, Any], labels: Sequence[Label]) -> list[Label]:
    """The labels whose impacts the IMU gain and the hysteresis are read from: no other onset
    within the pressure fit's and the impulse's own background before them
    (``pressure_pre_s`` + ``background_after_onset_s``) nor the overlap window after. In a
    dense flow the others' responses and ringing are in both reads: on a lightly damped support
    a flow's impacts read the beam's inertia far too low when all are taken, much nearer it when
    only these are (measured: docs/results/archive.md, "The IMU's gain read from the impacts no
    other crowds")."""
    section = params["identification"]
    before_s = float(section["pressure_pre_s"]) + float(section["background_after_onset_s"])
    return isolated(labels, before_s, float(section["overlap_window_s"]))


def delay_checks(
    params: Mapping[str, Any], labels: Sequence[Label]
) -> tuple[int | None, int | None]:
    """(impacts whose delay from onset to camera stamp the statistical method checked, those it
    found unusual) among a pass's isolated labels (the ones the sensor-timing check counts);
    (None, None) when none was checked."""
    section = params["identification"]
    checks = [
        label.features[UNUSUAL]
        for label in isolated(
            labels,
            TimingConfig.from_params(section["sensor_timing"]).clean_gap_s,
            float(section["overlap_window_s"]),
        )
        if UNUSUAL in label.features
    ]
    if not checks:
        return None, None
    return len(checks), int(sum(value > 0.5 for value in checks))


def _timing_rechecked(
    params: Mapping[str, Any],
    profile: SupportProfile,
    identify: Callable[[dict[str, Any]], Sequence[Label]],
) -> SupportProfile:
    """``profile`` with its delay counts taken again, from a pass with the profile itself, when
    the first pass's counts say the sensors' clocks are offset. That pass ran with config/'s
    beam and camera: a support whose inertia differs gives moment impulses, and a camera that
    stamps the separation itself gives delays, unlike what the check expects of config/'s, and
    counted on that pass alone the profile could start the identifier suspecting the clocks,
    deciding every impact without its delay (measured: docs/results/archive.md, "The clock
    verdict counted with the calibrated beam"). Offset clocks show in the second pass as well."""
    if profile.delay_checked_impacts is None or not judge(
        profile.delay_checked_impacts,
        profile.delay_unusual_impacts or 0,
        TimingConfig.from_params(params["identification"]["sensor_timing"]),
    ):
        return profile
    unjudged = replace(profile, delay_checked_impacts=None, delay_unusual_impacts=None)
    checked, unusual = delay_checks(params, identify(with_profile(params, unjudged)))
    return replace(profile, delay_checked_impacts=checked, delay_unusual_impacts=unusual)


def ringing_predictor(
    params: Mapping[str, Any], ringing: tuple[np.ndarray, np.ndarray] | None
) -> dict[str, Any]:
    """The profile's ``vibration_predictor`` and its rate fitted on the accelerometer's
    recording (``ringing``: stamps s, m/s^2) where identification.detection.
    vibration_innovations asks for it (empty otherwise, or when the fit fails)."""
    detection = (params.get("identification") or {}).get("detection") or {}
    if ringing is None or not detection.get("vibration_innovations", False):
        return {}
    stamp, accel = _finite(*ringing)
    if stamp.size < 2:
        return {}
    # the longest evenly spaced run: fitted across a lost sample, it would take the gap for
    # ringing
    period_s = float(np.median(np.diff(stamp)))
    run = unbroken(np.arange(stamp.size), stamp, period_s)
    coefficients = fit_predictor(accel[run])
    if coefficients is None:
        return {}
    return {
        "vibration_predictor": [float(a) for a in coefficients],
        "vibration_predictor_rate_hz": 1.0 / period_s,
    }


def imu_gain(features: Sequence[Mapping[str, float]]) -> tuple[float, int, float] | None:
    """(gain, impacts used, robust relative spread of the per-impact gains) of the IMU: the
    moment impulse the jack pressure reads (N m s) per m/s of the IMU's impulse, over a
    recording's impacts' features; None with fewer than MIN_IMPACTS impacts or a fit less than
    GAIN_SIGMA standard errors clear of zero.

    A weighted least-squares line through the origin, moment = gain x impulse, each impact
    weighted by the inverse variance of its pressure moment (``moment_impulse_sigma_nms``).
    Every impact counts, however small: a median gain of only the impacts whose pressure moment
    stands well clear of the noise picks those that noise has pushed up, and where few stand
    clear (small particles, such as the paper scene's 25 mm spheres) that reads the beam's
    inertia too high."""
    rows = [
        (
            f["moment_impulse_pressure_nms"],
            f.get("moment_impulse_sigma_nms", math.inf),
            f["imu_impulse_mps"],
        )
        for f in features
        if {"moment_impulse_pressure_nms", "imu_impulse_mps"} <= f.keys()
    ]
    rows = [r for r in rows if all(math.isfinite(v) for v in r) and r[1] >= 0.0 and r[2] > 0.0]
    if len(rows) < MIN_IMPACTS:
        return None
    moment, sigma, impulse = (np.array(column) for column in zip(*rows))
    noisy = sigma > 0.0
    if (
        not noisy.any()
    ):  # noise-free readings: equal weights, and any positive gain is clear of zero
        gain = float(np.sum(moment * impulse) / np.sum(impulse**2))
        if not gain > 0.0:
            return None
    else:
        # A noise-free reading among noisy ones counts as the surest of them, not infinitely sure.
        sigma = np.where(noisy, sigma, sigma[noisy].min())
        w = 1.0 / sigma**2
        information = float(np.sum(w * impulse**2))
        gain = float(np.sum(w * moment * impulse) / information)
        if not gain > GAIN_SIGMA / math.sqrt(information):
            return None
    spread = float(1.4826 * np.median(np.abs(moment / (gain * impulse) - 1.0)))
    return gain, len(rows), spread


def _hysteresis_weights(
    params: Mapping[str, Any],
    labels: Sequence[Label],
    inertia_kgm2: float | None,
    model: Mapping[str, Any] | None,
) -> tuple[list[float] | None, int | None, list[float] | None]:
    """The hysteresis bins' weights from the calibration pass's labels (their IMU moments as
    the calibrated inertia gives them: the pass ran with config/'s beam), the impacts used and
    the bins' edges; (None, None, None) when the statistical model has no hysteresis network."""
    if model is None:
        model = load_model("statistical").get("hysteresis")
    if model is None:
        return None, None, None
    section = params["identification"]["statistical"]["hysteresis"]
    min_impacts = HYSTERESIS.check(section, only=("min_impacts",))["min_impacts"]
    factor = (
        1.0
        if inertia_kgm2 is None
        else inertia_kgm2 / float(params["support"]["beam_inertia_about_hinge_kgm2"])
    )
    features = []
    for label in labels:
        f = dict(label.features)
        if "moment_impulse_imu_nms" in f and IMU_MOMENT_READ not in f:
            # (where the jack's moment stood for the channel's, it does not scale with the beam)
            f["moment_impulse_imu_nms"] *= factor
        features.append(f)
    weights, used = hysteresis.recording_weights(model, features, min_impacts)
    return weights, used, [float(e) for e in model["bin_edges"]]


def _camera_frame_rate_hz(stamps_s: Sequence[float]) -> float | None:
    """The camera's frame rate (Hz) from the grid of the rebound stamps (s); 1 / GRIDLESS_PERIOD_S
    for MIN_REBOUNDS or more stamps on no grid (stamped at the separation itself:
    tail_beam_id.signals.camera); None for fewer."""
    period = measured_period_s([float(t) for t in stamps_s if math.isfinite(float(t))])
    return None if period is None else 1.0 / period


def _finite(stamp_s: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The samples whose stamp and value are finite."""
    stamp_s, values = np.asarray(stamp_s, dtype=float), np.asarray(values, dtype=float)
    keep = np.isfinite(stamp_s) & np.isfinite(values)
    return (stamp_s, values) if keep.all() else (stamp_s[keep], values[keep])


def with_profile(params: Mapping[str, Any], profile: SupportProfile) -> dict[str, Any]:
    """``params`` with the profile's parameters merged in (what ``--config profile.yaml``
    gives)."""
    merged = copy.deepcopy(dict(params))
    deep_merge(merged, profile.parameters()["/**"]["ros__parameters"])
    return merged


def isolated(labels: Sequence[Label], before_s: float, after_s: float) -> list[Label]:
    """The labels whose impact has no other within ``before_s`` (s) before it nor ``after_s``
    after it: the ones the sensor-timing check counts (``identification.sensor_timing.
    clean_gap_s`` before, the overlap window after). The identifier counts from every impact
    it found, labelled or not; this pass has the labels only."""
    at = np.array([label.impact_stamp_s for label in labels], dtype=float)
    stamps = np.sort(at)
    near = np.searchsorted(stamps, at + after_s) - np.searchsorted(stamps, at - before_s)
    return [label for label, count in zip(labels, near) if count <= 1]
