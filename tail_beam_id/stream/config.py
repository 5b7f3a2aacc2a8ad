"""The ``identification`` parameter section, validated once for the stream identifier."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from tail_beam_id.methods import METHODS
from tail_beam_id.signals.contact_fit import ContactFitConfig
from tail_beam_id.signals.imu_detection import DetectionConfig
from tail_beam_id.signals.timing import TimingConfig
from tail_beam_sim.config import fingerprint
from tail_beam_sim.errors import InputError, require_section
from tail_beam_sim.spec import Field, Section, choice, flag, integer, number, of_kind, positive

LOOK_BACKS_KEPT = 4.0  # how many of the longest look-back (s) are kept before what is needed

_WINDOW = dict(unit="s", high=10.0)

IDENTIFICATION = Section(
    "identification",
    "Coal-gangue identification: method, windows and timeouts (stamp time, s).",
    (
        choice("method", "Identification method.", tuple(METHODS)),
        flag(
            "self_calibrate",
            "`tail-beam identify` calibrates to the bag's support first.",
            default=True,
        ),
        positive("window_s", "Signal after the onset every method waits for.", **_WINDOW),
        positive(
            "vibration_window_s",
            "The same for an impact found in the accelerometer's stream (absent: window_s).",
            "s",
            high="window_s",
            default=None,
        ),
        number(
            "vibration_window_mode_periods",
            "... or, on a support whose profile measured its bending modes, this many periods "
            "of the slowest, if longer (at most window_s; 0: never).",
            "",
            0.0,
            10.0,
            default=1.5,
        ),
        positive(
            "pressure_pre_s",
            "Pressure before the onset the fit learns the background from.",
            **_WINDOW,
        ),
        positive(
            "impulse_pre_s", "IMU background fitted over this much before the pulse.", **_WINDOW
        ),
        positive(
            "pressure_background_s",
            "Pressure background fitted over up to this much while no earlier onset is in the"
            " way (>= pressure_pre_s; absent: pressure_pre_s).",
            "s",
            high=1.0,
            default=None,
        ),
        positive(
            "impulse_background_s",
            "IMU background fitted over up to this much while no earlier onset is in the way"
            " (>= impulse_pre_s; absent: impulse_pre_s).",
            "s",
            high=1.0,
            default=None,
        ),
        positive(
            "background_after_onset_s",
            "A background stretch starts at least this long after an earlier onset.",
            "s",
            high=0.1,
            default=0.005,
        ),
        positive(
            "impulse_skip_s", "Plate velocity fitted from this long after the onset.", **_WINDOW
        ),
        positive("impulse_post_s", "... up to this long after it (<= window_s).", **_WINDOW),
        positive(
            "stream_timeout_s", "A continuous stream lagging this much is stopped.", **_WINDOW
        ),
        positive("camera_timeout_s", "Wait for the camera after the rebound window.", **_WINDOW),
        positive("overlap_window_s", "Onsets closer than this overlap (<= window_s).", **_WINDOW),
        flag(
            "neighbour_fit",
            "The pressure fit reads known neighbouring impacts' impulses with the impact's.",
            default=True,
        ),
        flag(
            "impulse_neighbour_fit",
            "The acceleration's velocity step reads other impacts in its window with the "
            "impact's.",
            default=True,
        ),
        number(
            "neighbour_min_separation_s",
            "Neighbouring onsets closer than this are read together.",
            "s",
            0.0,
            0.1,
            default=0.001,
        ),
        number(
            "overlap_confidence_cap",
            "Most confidence of an overlapping impact's label.",
            "",
            0.5,
            1.0,
        ),
        number(
            "ringing_window_s",
            "An impact this long or less after another known onset strikes the beam still "
            "ringing from it (0: never).",
            "s",
            0.0,
            0.1,
            default=0.02,
        ),
        number(
            "ringing_confidence_cap",
            "Most confidence of such an impact's label.",
            "",
            0.5,
            1.0,
            default=0.8,
        ),
        positive(
            "match_tolerance_s",
            "Scoring: a label's onset within this of the contact start.",
            "s",
            high=0.1,
        ),
    ),
    file="identification.yaml",
    sections=(
        "sensor_timing",
        "contact_fit",
        "detection",
        "evaluation",
        "gangue_share",
        "statistical",
        "threshold",
        "physics",
    ),
)

# The fields IdentifierConfig holds (the method's and scoring's are read where they are used).
CHECKED = (
    "method",
    "window_s",
    "vibration_window_s",
    "vibration_window_mode_periods",
    "pressure_pre_s",
    "impulse_pre_s",
    "pressure_background_s",
    "impulse_background_s",
    "background_after_onset_s",
    "impulse_skip_s",
    "impulse_post_s",
    "stream_timeout_s",
    "camera_timeout_s",
    "overlap_window_s",
    "neighbour_fit",
    "impulse_neighbour_fit",
    "neighbour_min_separation_s",
    "overlap_confidence_cap",
    "ringing_window_s",
    "ringing_confidence_cap",
)

EVALUATION = Section(
    "identification.evaluation",
    "Scene sets of `tail-beam evaluate` and of training (checked where they are used).",
    (
        of_kind("mapping", "seeds", "Seed of each scene set."),
        integer("training_seed", "Seed of the training set."),
        integer("impacts_per_set", "Impacts per scene set."),
        of_kind("floats", "noise_factors", "Noise factors evaluated."),
        choice("tier", "Model the impacts are simulated with.", ("rigid", "modal")),
        number("pre_contact_s", "Signal simulated before each contact.", "s"),
        number("window_s", "Signal simulated after each contact.", "s"),
        of_kind("mapping", "rates", "Sensor settings by name (Hz)."),
        of_kind("strs", "default_rates", "Sensor settings a plain evaluate runs."),
        of_kind("mapping", "material_mix", "Each material's share of a scene set."),
        of_kind("mapping", "paper", "The paper scene's impact ranges."),
        of_kind("mapping", "stream", "The stream scene's impact ranges."),
        number("support_perturbation", "Mismatch set: scale of the support's perturbation."),
        of_kind("strs", "mismatch_contact_models", "Mismatch set: contact laws."),
        of_kind(
            "mapping", "supports", "Ranges supports other than the nominal one are drawn from."
        ),
        integer("foreign_supports", "Supports of the foreign set."),
        integer("foreign_impacts_per_support", "Impacts per foreign support."),
        number("stream_gap_s", "Least time between the foreign set's impacts.", "s"),
        of_kind("floats", "size_bins_m", "Radius bins of the accuracy-by-size table, m."),
    ),
    file="identification.yaml",
)


# The support profile ``tail-beam calibrate`` writes (tail_beam_id.calibration.offline
# .SupportProfile); every field may be absent (not measurable on that recording). Checked where
# it is read, so that a hand-edited profile is refused by name rather than taken as measured.
PROFILE = Section(
    "calibration",
    "A support profile measured on the support's own recording (`tail-beam calibrate --out`).",
    (
        number("duration_s", "Recording the profile was read from.", "s", 0.0, default=None),
        integer("impacts_used", "Impacts the profile rests on.", 0, default=None),
        number(
            "imu_mount_sign",
            "IMU mounting: +1 right way up, -1 upside down.",
            "",
            -1.0,
            1.0,
            default=None,
        ),
        positive(
            "rigid_mode_frequency_hz",
            "The beam's sway on the jack.",
            "Hz",
            high=1000.0,
            default=None,
        ),
        number("oil_bulk_modulus_pa", "Oil bulk modulus read.", "Pa", 1e7, 1e11, default=None),
        number(
            "beam_inertia_about_hinge_kgm2",
            "Beam inertia read.",
            "kg m^2",
            1.0,
            1e6,
            default=None,
        ),
        number(
            "imu_gain_spread", "Robust relative spread of the IMU gains.", "", 0.0, default=None
        ),
        number("pressure_noise_pa", "Jack pressure noise RMS.", "Pa", 0.0, default=None),
        number("imu_accel_noise_mps2", "IMU acceleration noise RMS.", "m/s^2", 0.0, default=None),
        integer(
            "delay_checked_impacts", "Impacts whose camera delay was checked.", 0, default=None
        ),
        integer(
            "delay_unusual_impacts",
            "Of those, unusual ones.",
            0,
            high="delay_checked_impacts",
            default=None,
        ),
        Field(
            "ringing_modes_hz",
            "Bending modes read from the ringing.",
            "floats",
            "Hz",
            1.0,
            1e5,
            default=None,
        ),
        Field(
            "ringing_damping_ratios", "Their damping ratios.", "floats", "", 0.0, 1.0, default=None
        ),
        number(
            "camera_frame_rate_hz",
            "Camera frame rate read from the rebound stamps.",
            "Hz",
            1.0,
            1e6,
            default=None,
        ),
        Field(
            "vibration_predictor",
            "The accelerometer's one-step ringing predictor a_k: x[n] ~ sum a_k x[n-k].",
            "floats",
            "",
            -1e3,
            1e3,
            default=None,
        ),
        positive(
            "vibration_predictor_rate_hz",
            "The accelerometer rate the predictor was fitted at.",
            "Hz",
            high=1e6,
            default=None,
        ),
        of_kind("floats", "hysteresis_weights", "Weight of each hysteresis bin.", default=None),
        integer("hysteresis_impacts", "Impacts the hysteresis rests on.", 0, default=None),
        of_kind("floats", "hysteresis_bin_edges", "Bins the weights are of.", default=None),
    ),
)


MAX_PREDICTOR_ORDER = 64  # the most coefficients a profile's ringing predictor may hold


def check_profile(merged: Mapping[str, Any]) -> dict[str, Any]:
    """The ``calibration`` section of ``merged`` validated field by field ({} when absent)."""
    section = merged.get("calibration")
    if section is None:
        return {}
    given = {k: v for k, v in require_section("calibration", section).items() if v is not None}
    checked = {k: v for k, v in PROFILE.check(given).items() if v is not None}
    predictor = checked.get("vibration_predictor")
    if predictor is not None and len(predictor) > MAX_PREDICTOR_ORDER:
        # each coefficient costs a multiply per sample of every buffered accelerometer sample
        raise InputError(
            "calibration.vibration_predictor",
            f"{len(predictor)} coefficients",
            f"must hold at most {MAX_PREDICTOR_ORDER}",
        )
    return checked


CONFIG_CACHE_SIZE = 64
_CONFIGS: dict[str, IdentifierConfig] = {}


@dataclass(frozen=True)
class IdentifierConfig:
    """The ``identification`` parameter section, validated (times in s of stamp time)."""

    method: str
    window_s: float
    vibration_window_s: float  # the data window of an impact the accelerometer found (s)
    # ... at least this many periods of the support's slowest measured bending mode
    vibration_window_mode_periods: float
    pressure_pre_s: float
    impulse_pre_s: float
    # The background stretches (s) while no earlier onset is in the way (tail_beam_id.signals.
    # features.background_s); absent in the parameters: pressure_pre_s and impulse_pre_s.
    pressure_background_s: float
    impulse_background_s: float
    background_after_onset_s: float
    impulse_skip_s: float
    impulse_post_s: float
    stream_timeout_s: float
    camera_timeout_s: float
    overlap_window_s: float
    neighbour_fit: bool  # the pressure fit reads neighbouring onsets' impulses jointly
    impulse_neighbour_fit: bool  # ... and the acceleration's velocity step (signals.features)
    neighbour_min_separation_s: float  # closer neighbouring onsets are read together (s)
    overlap_confidence_cap: float
    # An impact at most ringing_window_s after another known onset: its label's cap (s, 0..1).
    ringing_window_s: float
    ringing_confidence_cap: float
    detection: DetectionConfig
    timing: TimingConfig
    contact_fit: ContactFitConfig

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> IdentifierConfig:
        """The validated section (built once per content: an identifier per impact reads the
        same section again)."""
        key = fingerprint(params) if isinstance(params, Mapping) else None
        known = _CONFIGS.get(key) if key is not None else None
        if known is None:
            known = cls._from_params(params)
            if key is not None:
                if len(_CONFIGS) >= CONFIG_CACHE_SIZE:
                    _CONFIGS.clear()
                _CONFIGS[key] = known
        return known

    @classmethod
    def _from_params(cls, params: Mapping[str, Any]) -> IdentifierConfig:
        if not isinstance(params, Mapping):
            raise InputError("identification", params, "missing parameter section")

        checked = IDENTIFICATION.check(params, only=CHECKED)
        window = checked["window_s"]
        if checked["impulse_post_s"] > window:
            raise InputError(
                "identification.impulse_post_s",
                params.get("impulse_post_s"),
                f"must be <= window_s ({window:g} s)",
            )
        if checked["overlap_window_s"] > window:
            raise InputError(
                "identification.overlap_window_s",
                checked["overlap_window_s"],
                f"must be <= window_s ({window:g} s)",
            )
        if checked["vibration_window_s"] is None:
            checked["vibration_window_s"] = window
        for stretch, least in (
            ("pressure_background_s", "pressure_pre_s"),
            ("impulse_background_s", "impulse_pre_s"),
        ):
            if checked[stretch] is None:
                checked[stretch] = checked[least]
            elif checked[stretch] < checked[least]:
                raise InputError(
                    f"identification.{stretch}",
                    checked[stretch],
                    f"must be >= {least} ({checked[least]:g} s)",
                )
        config = cls(
            **checked,
            detection=DetectionConfig.from_params(
                require_section("identification.detection", params.get("detection"))
            ),
            timing=TimingConfig.from_params(
                require_section("identification.sensor_timing", params.get("sensor_timing"))
            ),
            contact_fit=ContactFitConfig.from_params(
                require_section("identification.contact_fit", params.get("contact_fit"))
            ),
        )
        if config.timing.clean_gap_s > config.kept_s:
            raise InputError(
                "identification.sensor_timing.clean_gap_s",
                config.timing.clean_gap_s,
                f"must be <= {config.kept_s:g} s (the identifier keeps the onsets of "
                f"{LOOK_BACKS_KEPT:g} x max(detection.noise_block_s, the longest background "
                "stretch + window_s) before the oldest it still needs)",
            )
        return config

    @property
    def kept_s(self) -> float:
        """How far before the oldest stamp a pending decision needs the identifier keeps data
        and decided onsets, s (:mod:`tail_beam_id.stream.retention`)."""
        longest = max(self.pressure_background_s, self.impulse_background_s)
        return LOOK_BACKS_KEPT * max(self.detection.noise_block_s, longest + self.window_s)


__all__ = ["PROFILE", "IdentifierConfig", "check_profile"]
