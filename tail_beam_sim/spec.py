"""The suite's parameters declared once: per section, each field's name, kind, unit, allowed
range, default and meaning.

A :class:`Section` checks its part of the merged parameters (``config/*.yaml``, ``-p``,
``--params-file``) and returns the validated values by name; every refusal is the
:class:`~tail_beam_sim.errors.InputError` naming the dotted field, the value and what is
allowed, unit included. The same tables render the parameter reference::

    python -m tail_beam_sim.spec > docs/parameters.md

and let a test check that config/ and the tables agree (:func:`unspecified_keys`,
:func:`missing_keys`).

A bound may be a number or the name of another field of the section checked before it (a
jack pin on the beam: ``high="beam_length_m"``), or of a value the caller passes in
``context`` (a bound that comes from another section: the support's largest particle). A
bound that names nothing given is no bound.
"""

from __future__ import annotations

import fnmatch
import math
import sys
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tail_beam_sim.config import default_config_dir, flatten, read_parameter_file
from tail_beam_sim.errors import InputError, require_range, require_section, shorten

KINDS = ("float", "int", "bool", "str", "choice", "pair", "floats", "strs", "mapping")


class _Required:
    """The default of a field that has none: the config must give it."""

    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED: Any = _Required()
Bound = float | str | None  # a number, the name of a field or context value, or no bound


@dataclass(frozen=True)
class Field:
    """One parameter: ``name`` within its section, ``kind`` (one of :data:`KINDS`), ``unit``
    (appended to the allowed range), bounds ``low``/``high`` (``low_open`` excludes ``low``),
    ``choices`` (kind choice), ``off``: a value outside the range that switches the feature
    off (``off_meaning`` says what it means), ``default`` when the config leaves it out
    (:data:`REQUIRED`: none; None: absent stays None) and a one-line ``meaning``.

    Kind ``pair`` is ``[low, high]``, both within the bounds and ``low <= high``; ``floats``
    and ``strs`` are lists; ``mapping`` is a table whose keys are documented in ``meaning``.
    """

    name: str
    meaning: str
    kind: str = "float"
    unit: str = ""
    low: Bound = None
    high: Bound = None
    low_open: bool = False
    choices: tuple[str, ...] = ()
    off: float | None = None
    off_meaning: str = ""
    default: Any = REQUIRED

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"{self.name}: kind {self.kind!r} is not one of {KINDS}")

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def allowed(self, low: float | None = None, high: float | None = None) -> str:
        """What the field allows, as an InputError says it (bounds already resolved)."""
        suffix = f" {self.unit}" if self.unit else ""
        if self.kind == "int":
            text = _int_range(low, high) + suffix
        elif self.kind == "bool":
            return "must be true or false"
        elif self.kind == "str":
            return "must be text"
        elif self.kind == "choice":
            return f"must be one of {', '.join(self.choices)}"
        elif self.kind == "floats":
            return "must be a list of finite numbers"
        elif self.kind == "strs":
            return "must be a list of text"
        elif self.kind == "mapping":
            return "must be a parameter section (names with their values)"
        elif self.kind == "pair":
            text = f"must be [low, high]{f' in {self.unit}' if self.unit else ''}"
        elif low is None and high is None:
            text = "must be a finite number"
        elif high is None:
            text = f"must be {'>' if self.low_open else '>='} {low:g}{suffix}"
        elif low is None:
            text = f"must be <= {high:g}{suffix}"
        else:
            text = f"must be in {'(' if self.low_open else '['}{low:g}, {high:g}]{suffix}"
        if self.off is not None:
            text += f", or {self.off:g} ({self.off_meaning})"
        return text

    def check(
        self, dotted: str, value: object, low: float | None = None, high: float | None = None
    ) -> Any:
        """``value`` validated (a number as float or int), or InputError naming ``dotted``."""
        if self.off is not None and _is_number(value) and float(value) == self.off:
            return float(value) if self.kind == "float" else int(self.off)
        kind = self.kind
        if kind == "float":
            try:
                return require_range(
                    dotted, value, low, high, low_open=self.low_open, unit=self.unit
                )
            except InputError:
                if self.off is None:
                    raise
                raise InputError(dotted, value, self.allowed(low, high)) from None
        if kind == "int":
            number = _integral(value)
            too_low = number is not None and low is not None and number < low
            too_high = number is not None and high is not None and number > high
            if number is None or too_low or too_high:
                raise InputError(dotted, value, self.allowed(low, high))
            return number
        if kind == "bool":
            if not isinstance(value, bool):
                raise InputError(dotted, value, self.allowed())
            return value
        if kind == "str":
            if not isinstance(value, str):
                raise InputError(dotted, value, self.allowed())
            return value
        if kind == "choice":
            if not isinstance(value, str) or value not in self.choices:
                raise InputError(dotted, value, self.allowed())
            return value
        if kind == "pair":
            if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != 2:
                raise InputError(dotted, value, self.allowed())
            first = require_range(
                f"{dotted}[0]", value[0], low, high, low_open=self.low_open, unit=self.unit
            )
            second = require_range(f"{dotted}[1]", value[1], first, high, unit=self.unit)
            return (first, second)
        if kind == "floats":
            if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
                raise InputError(dotted, value, self.allowed())
            if not all(_is_number(x) for x in value):
                raise InputError(dotted, value, self.allowed())
            return [float(x) for x in value]
        if kind == "strs":
            if isinstance(value, str) or not isinstance(value, Sequence):
                raise InputError(dotted, value, self.allowed())
            if not all(isinstance(x, str) for x in value):
                raise InputError(dotted, value, self.allowed())
            return list(value)
        return require_section(dotted, value)  # mapping

    def range_text(self) -> str:
        """The allowed values as the reference page shows them (bounds by name where named)."""
        if self.kind in ("bool", "str", "floats", "strs", "mapping"):
            return {
                "bool": "true, false",
                "floats": "list of numbers",
                "strs": "list of names",
            }.get(self.kind, "")
        if self.kind == "choice":
            return " \\| ".join(self.choices)
        if self.low is None and self.high is None:
            text = "any integer" if self.kind == "int" else "any number"
        else:
            low = "-inf" if self.low is None else _bound_text(self.low)
            high = "inf" if self.high is None else _bound_text(self.high)
            opening = "(" if self.low_open or self.low is None else "["
            closing = ")" if self.high is None else "]"
            text = f"{opening}{low}, {high}{closing}"
            if self.kind == "pair":
                text = f"[low, high] in {text}"
        if self.off is not None:
            text += f", or {self.off:g} ({self.off_meaning})"
        return text


@dataclass(frozen=True)
class Section:
    """The fields of one parameter section.

    ``path`` is its dotted place in the merged parameters (``identification.contact_fit``;
    a ``*`` segment stands for every entry, as in ``materials.*``; "" is the top level).
    ``sections`` names keys that are sections of their own, ``file`` the config file that
    ships it.
    """

    path: str
    meaning: str
    fields: tuple[Field, ...]
    file: str = ""
    sections: tuple[str, ...] = ()
    _by_name: dict[str, Field] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_by_name", {f.name: f for f in self.fields})
        if len(self._by_name) != len(self.fields):
            raise ValueError(f"section {self.path!r} declares a field twice")

    def __getitem__(self, name: str) -> Field:
        return self._by_name[name]

    def __contains__(self, name: object) -> bool:
        return name in self._by_name

    def __iter__(self) -> Iterator[Field]:
        return iter(self.fields)

    def default(self, name: str) -> Any:
        """The default of field ``name`` (a field without one: ValueError, a slip in code)."""
        value = self._by_name[name].default
        if value is REQUIRED:
            raise ValueError(f"{self.path}.{name} has no default")
        return value

    def check(
        self,
        values: object,
        *,
        where: str | None = None,
        context: Mapping[str, Any] | None = None,
        only: Iterable[str] | None = None,
    ) -> dict[str, Any]:
        """Validate ``values`` (this section's mapping) and return every field's value by name,
        defaults filled in.

        ``where`` is the dotted prefix errors name (default: ``path``; "" names the bare field,
        for values a command line gave), ``context`` holds bounds and choices from outside the
        section, ``only`` limits the check to those fields (in table order).
        """
        prefix = self.path if where is None else where
        given = require_section(prefix or "parameters", values)
        context = context or {}
        chosen = self.fields if only is None else [self._by_name[n] for n in only]
        out: dict[str, Any] = {}
        for spec in chosen:
            dotted = f"{prefix}.{spec.name}" if prefix else spec.name
            low = _resolve(spec.low, out, context)
            high = _resolve(spec.high, out, context)
            if spec.name in given:
                out[spec.name] = spec.check(dotted, given[spec.name], low, high)
            elif spec.required:
                raise InputError(
                    dotted, None, f"missing from the config ({spec.allowed(low, high)})"
                )
            elif spec.default is None:
                out[spec.name] = None
            else:
                out[spec.name] = spec.check(dotted, spec.default, low, high)
        return out


def _resolve(bound: Bound, checked: Mapping[str, Any], context: Mapping[str, Any]) -> Any:
    if not isinstance(bound, str):
        return bound
    if bound in checked:
        return checked[bound]
    return context.get(bound)


def _bound_text(bound: float | str) -> str:
    if isinstance(bound, str):
        return bound
    if isinstance(bound, int) and abs(bound) >= 1e6:
        return f"2^{int(math.log2(bound))}" if bound & (bound - 1) == 0 else f"{bound:g}"
    return f"{bound:g}"


def _int_range(low: float | None, high: float | None) -> str:
    if low is not None and high is not None:
        return f"must be an integer in [{int(low)}, {int(high)}]"
    if low is not None:
        return f"must be an integer >= {int(low)}"
    if high is not None:
        return f"must be an integer <= {int(high)}"
    return "must be an integer"


def _is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _integral(value: object) -> int | None:
    """``value`` as an int if it is a whole number (2, 2.0, "2"), else None (True, 2.5, NaN)."""
    if isinstance(value, str):
        try:
            value = float(value) if any(c in value for c in ".eE") else int(value)
        except ValueError:
            return None
    if not _is_number(value):
        return None
    if isinstance(value, float) and not value.is_integer():
        return None
    return int(value)


def _f(name: str, meaning: str, unit: str = "", low: Bound = None, high: Bound = None, **kw: Any):
    """A float field (the tables' shorthand)."""
    return Field(name, meaning, "float", unit, low, high, **kw)


def _open(name: str, meaning: str, unit: str = "", low: Bound = 0.0, high: Bound = None, **kw):
    """A float field whose low bound (0 unless given) is excluded."""
    return Field(name, meaning, "float", unit, low, high, low_open=True, **kw)


def _int(name: str, meaning: str, low: Bound = None, high: Bound = None, **kw: Any) -> Field:
    return Field(name, meaning, "int", kw.pop("unit", ""), low, high, **kw)


def _str(name: str, meaning: str, **kw: Any) -> Field:
    return Field(name, meaning, "str", **kw)


def _bool(name: str, meaning: str, **kw: Any) -> Field:
    return Field(name, meaning, "bool", **kw)


def _choice(name: str, meaning: str, choices: Sequence[str], **kw: Any) -> Field:
    return Field(name, meaning, "choice", choices=tuple(choices), **kw)


def _kind(kind: str, name: str, meaning: str, **kw: Any) -> Field:
    return Field(name, meaning, kind, **kw)


# --- tail_beam_sim: the support and its model -------------------------------------------------

MATERIAL_CLASSES = ("coal", "gangue", "structure")
CONTACT_LAWS = (
    "hertz",
    "lankarani_nikravesh",
    "hunt_crossley",
    "flores",
    "gonthier",
    "calibrated",
)
TIER_NAMES = ("impulse", "rigid", "modal", "brittle")
FIDELITY_OUTPUTS = ("rebound", "contact", "pressure", "imu")
SCENARIO_SOURCES = ("none", "file", "generated")
MAX_GENERATED = 100_000  # most impacts a generated scenario may hold (memory, start-up time)
MAX_QOS_DEPTH = 1_000_000  # deepest history a subscription or publisher may keep, messages
MIB = 2**20

SUPPORT = Section(
    "support",
    "The hydraulic support: beam, plate, jack and the limits of what may strike it.",
    (
        _f("gravity_mps2", "Gravitational acceleration.", "m/s^2", 0.0, 100.0),
        _open("beam_length_m", "Tail beam length from the hinge to its tip.", "m", high=20.0),
        _open("beam_mass_kg", "Mass of the tail beam.", "kg"),
        _open(
            "beam_inertia_about_hinge_kgm2", "Beam's moment of inertia about the hinge.", "kg m^2"
        ),
        _str("plate_material", "Material of the impact plate (a materials entry)."),
        _open("plate_thickness_m", "Impact plate thickness.", "m", high=1.0),
        _f(
            "contact_damping_scale",
            "Factor on the contact law's hysteresis (1 = as published).",
            "(dimensionless)",
            0.1,
            10.0,
            default=1.0,
        ),
        _open(
            "jack_pin_from_hinge_m",
            "Jack pin's distance from the hinge.",
            "m",
            high="beam_length_m",
        ),
        _open("jack_angle_to_beam_deg", "Angle between the jack and the beam.", "deg", high=90.0),
        _open("jack_bore_m", "Jack cylinder bore.", "m", high=2.0),
        _open("jack_oil_column_m", "Length of the jack's oil column.", "m", high=10.0),
        _open("jack_wall_thickness_m", "Jack cylinder wall thickness.", "m", high=1.0),
        _open("jack_wall_youngs_modulus_pa", "Young's modulus of the cylinder wall.", "Pa"),
        _open("oil_bulk_modulus_pa", "Bulk modulus of the hydraulic oil.", "Pa"),
        _f("jack_damping_nspm", "Viscous damping of the jack.", "N s/m", 0.0),
        _f("jack_extra_compliance_mpn", "Compliance added in series with the jack.", "m/N", 0.0),
        _f("setting_pressure_pa", "Static (setting) pressure of the jack.", "Pa", 0.0),
        _f("imu_from_hinge_m", "IMU's distance from the hinge.", "m", 0.0, "beam_length_m"),
        _f(
            "impact_zone_min_m", "Nearest impact position to the hinge.", "m", 0.0, "beam_length_m"
        ),
        _f("impact_zone_max_m", "Farthest impact position.", "m", 0.0, "beam_length_m"),
        _open("particle_radius_min_m", "Smallest particle radius accepted.", "m"),
        _f("particle_radius_max_m", "Largest particle radius.", "m", "particle_radius_min_m"),
        _open("drop_height_min_m", "Lowest drop height accepted.", "m"),
        _f("drop_height_max_m", "Highest drop height.", "m", "drop_height_min_m"),
        _open("impact_speed_min_mps", "Slowest impact speed accepted.", "m/s"),
        _f("impact_speed_max_mps", "Fastest impact speed.", "m/s", "impact_speed_min_mps"),
    ),
    file="support.yaml",
)

MATERIAL = Section(
    "materials.*",
    "One particle or plate material (an entry per name).",
    (
        _choice("class", "What it is.", MATERIAL_CLASSES),
        _open("density_kgpm3", "Density.", "kg/m^3", high=30000.0),
        _open("youngs_modulus_pa", "Young's modulus.", "Pa", high=2e12),
        _open("poisson_ratio", "Poisson's ratio.", low=-1.0, high=0.5),
        _open("restitution", "Nominal coefficient of restitution on steel.", low=0.0, high=1.0),
        _kind(
            "pair",
            "restitution_range",
            "Restitution a realistic scene draws from (absent: the nominal one).",
            low=0.0,
            high=1.0,
            low_open=True,
            default=None,
        ),
        _open(
            "crushing_strength_pa",
            "Uniaxial crushing strength (a brittle contact only).",
            "Pa",
            default=1e12,
        ),
    ),
    file="materials.yaml",
)

SENSOR_RATE = (1.0, 1e6)  # sample and frame rates any sensor may have, Hz
SENSORS = Section(
    "sensors",
    "Sensor layout: rates, noise and sampling filters of the jack pressure, IMU, camera and "
    "tail-beam accelerometer.",
    (
        _int("seed", "Seed of the sensors' noise.", 0, default=0),
        _f("pressure_rate_hz", "Jack pressure sample rate.", "Hz", *SENSOR_RATE),
        _f("pressure_noise_pa", "Pressure noise RMS.", "Pa", 0.0),
        _f("pressure_range_min_pa", "Lowest pressure the transducer reads.", "Pa"),
        _open(
            "pressure_range_max_pa", "Highest pressure it reads.", "Pa", "pressure_range_min_pa"
        ),
        _f("imu_rate_hz", "IMU sample rate.", "Hz", *SENSOR_RATE),
        _f(
            "imu_noise_nominal_rate_hz",
            "Rate at which the IMU noise RMS below holds (it scales with sqrt of the rate).",
            "Hz",
            *SENSOR_RATE,
        ),
        _f("imu_accel_noise_mps2", "IMU specific-force noise RMS.", "m/s^2", 0.0),
        _f("imu_gyro_noise_radps", "IMU angular-rate noise RMS.", "rad/s", 0.0),
        _int(
            "imu_antialias_order",
            "IMU sampling filter: 0 = mean over the sample period, N = Butterworth order.",
            0,
            10,
            default=0,
        ),
        _open(
            "imu_antialias_cutoff_fraction",
            "Its cut-off over the sample rate.",
            high=0.5,
            default=0.25,
        ),
        _int("imu_oversample", "Beam response computed per IMU sample.", 2, 32, default=4),
        _f("camera_frame_rate_hz", "Rebound camera frame rate.", "Hz", *SENSOR_RATE),
        _f("camera_velocity_noise_mps", "Rebound-velocity noise RMS.", "m/s", 0.0),
        _f(
            "camera_velocity_noise_fraction", "Rebound-velocity noise as a fraction.", "", 0.0, 1.0
        ),
        _f(
            "vibration_rate_hz",
            "Tail-beam accelerometer sample rate.",
            "Hz",
            1000.0,
            100000.0,
            default=25600.0,
        ),
        _int("vibration_block_samples", "Samples per vibration message.", 1, 65536, default=128),
        _f(
            "vibration_noise_density_mps2_rthz",
            "Accelerometer white-noise density.",
            "m/s^2/sqrt(Hz)",
            0.0,
            default=0.002,
        ),
        _open(
            "vibration_range_mps2", "Accelerometer full scale.", "m/s^2", high=1e6, default=2000.0
        ),
        _int("vibration_antialias_order", "Its Butterworth filter order.", 1, 10, default=4),
        _open(
            "vibration_antialias_cutoff_fraction",
            "Its cut-off over the sample rate.",
            high=0.5,
            default=0.4,
        ),
        _int("vibration_oversample", "Beam response computed per sample.", 2, 32, default=4),
    ),
    file="sensors.yaml",
)

SCENE = Section(
    "scene",
    "The impact of `tail-beam simulate` and the window simulated (impact fields are checked "
    "against the support's limits).",
    (
        _str("material", "Particle material (a coal or gangue materials entry)."),
        _f(
            "radius_m",
            "Particle radius.",
            "m",
            "support.particle_radius_min_m",
            "support.particle_radius_max_m",
        ),
        _f(
            "drop_height_m",
            "Drop height (or impact_speed_mps).",
            "m",
            "support.drop_height_min_m",
            "support.drop_height_max_m",
        ),
        _f("position_m", "Impact position from the hinge.", "m", 0.0, "support.beam_length_m"),
        _choice("contact_model", "Contact law.", CONTACT_LAWS, default="calibrated"),
        _open("window_s", "Time simulated after first contact.", "s", high=10.0, default=0.05),
        _f("pre_contact_s", "Time simulated before first contact.", "s", 0.0, 10.0, default=0.005),
    ),
    file="scene.yaml",
)

MODES = Section(
    "modes",
    "The beam's bending modes (derived by `tail-beam modes`).",
    (
        _int("count", "How many of the bending_N modes the model uses.", 0, "bending_modes"),
        _kind("mapping", "derived_from", "The beam model the modes were derived from."),
        _kind("floats", "stations_m", "Positions along the beam the shapes are given at, m."),
    ),
    file="modes.yaml",
    sections=("bending_*",),
)

BENDING_MODE = Section(
    "modes.bending_*",
    "One bending mode.",
    (
        _open("frequency_hz", "Undamped frequency (beam held at hinge and jack pin).", "Hz"),
        _f("damping_ratio", "Modal damping ratio.", "", 0.0, 1.0),
        _open("modal_mass_kg", "Modal mass (shape normalised to 1 at the tip).", "kg"),
        _f("rigid_coupling_kgm", "Mass coupling with the rigid rotation.", "kg m"),
        _kind("floats", "shape", "Mode shape at modes.stations_m."),
        _kind("floats", "slope_radpm", "Its slope at modes.stations_m, rad/m."),
    ),
    file="modes.yaml",
)

FIDELITY = Section(
    "fidelity",
    "How much model a scene gets (`tail-beam simulate`).",
    (
        _choice(
            "tier", "Model tier when --tier is not given.", ("auto", *TIER_NAMES), default="auto"
        ),
        _kind(
            "strs",
            "outputs",
            "What the scene needs, for the automatic choice (rebound, contact, pressure, imu).",
            default=list(FIDELITY_OUTPUTS),
        ),
        _open("tolerance", "Relative error the automatic choice accepts.", high=1.0, default=0.01),
        _open(
            "crushing_confinement_factor",
            "Brittle tier: crushing pressure over the material's crushing strength.",
            high=100.0,
            default=3.0,
        ),
    ),
    file="fidelity.yaml",
)

STREAM = Section(
    "stream",
    "sim_node's continuous simulation.",
    (
        _choice("tier", "Model tier of the stream.", TIER_NAMES, default="rigid"),
        _f("min_impact_gap_s", "Least time between two contacts.", "s", 0.0, 60.0),
        _open(
            "command_lead_s", "How far ahead of the stream a command is scheduled.", "s", high=60.0
        ),
        _int("max_queued_impacts", "Most impacts waiting to be simulated.", 1),
    ),
    file="sim_node.yaml",
)

_QOS_DEPTH = _int(
    "qos_depth", "History depth of the stream topics, messages (0 = keep all).", 0, MAX_QOS_DEPTH
)
_WAIT_FOR = _int(
    "wait_for_subscribers", "Subscribers each stream waits for before publishing.", 0, 1000
)
_SETTLE = _f(
    "subscriber_settle_s", "Wait after they matched, for discovery to settle.", "s", 0.0, 60.0
)

SIM_NODE = Section(
    "sim_node",
    "sim_node's pacing and publishing.",
    (
        _f(
            "realtime_factor",
            "Simulation speed over wall clock (0 = as fast as possible).",
            "",
            0.0,
            1e6,
        ),
        _open("publish_period_s", "Timer period, wall clock.", "s", high=10.0),
        _open("max_chunk_s", "Most simulation time advanced per tick.", "s", high=10.0),
        _f("max_lag_s", "Lag behind real time after which it runs slower.", "s", 0.0, 3600.0),
        _WAIT_FOR,
        _SETTLE,
        _bool("publish_clock", "Publish simulation time on /clock."),
        _QOS_DEPTH,
        _f(
            "exit_after_idle_s",
            "Exit after this long with nothing to simulate (0 = never).",
            "s",
            0.0,
            off=-1.0,
            off_meaning="auto: 1 s after a scenario, else never",
        ),
    ),
    file="sim_node.yaml",
)

SCENARIO = Section(
    "scenario",
    "sim_node's start-up impacts: none, a file, or a generated caving stream.",
    (
        _choice("source", "Where the impacts come from.", SCENARIO_SOURCES, default="none"),
        _str("file", "Scenario file (source file).", default=""),
        _int("count", "Impacts generated.", 0, MAX_GENERATED),
        _f("gangue_fraction", "Share of gangue among them.", "", 0.0, 1.0),
        _kind(
            "pair",
            "radius_m",
            "Radius range.",
            unit="m",
            low=0.0,
            high="particle_radius_max_m",
            low_open=True,
        ),
        _kind(
            "pair",
            "drop_height_m",
            "Drop height range.",
            unit="m",
            low=0.0,
            high="drop_height_max_m",
            low_open=True,
        ),
        _kind("pair", "position_m", "Impact position range.", unit="m", low=0.0, low_open=True),
        _kind(
            "pair",
            "interval_s",
            "Time between contacts.",
            unit="s",
            low=0.0,
            high=3600.0,
            low_open=True,
        ),
        _f("start_s", "Simulation time of the first contact.", "s", 0.0, default=0.0),
        _int("seed", "Seed of the generated stream.", 0, default=0),
    ),
    file="sim_node.yaml",
)

RECORDER = Section(
    "recorder",
    "bag_recorder: what it writes and how often.",
    (
        _str("bag_path", 'Bag directory to create ("" = out/bags/tail_beam_<UTC time>).'),
        _str("storage", "Storage plugin: mcap or sqlite3."),
        _str("compression", "mcap chunk compression: zstd or none."),
        _open("segment_s", "Log time per segment file.", "s", high=3600.0),
        _open("flush_s", "Wall time between flushes (what a SIGKILL may lose).", "s", high=3600.0),
        _f(
            "max_bag_duration_s",
            "Start a new file after this much log time.",
            "s",
            1.0,
            1e7,
            off=0.0,
            off_meaning="never split",
        ),
        _int(
            "max_bag_size_bytes",
            "Start a new file at this size.",
            MIB,
            2**62,
            unit="bytes",
            off=0,
            off_meaning="never split",
        ),
        _QOS_DEPTH,
    ),
    file="recorder.yaml",
)

REPLAY = Section(
    "replay",
    "bag_replay: which bag, what of it and how fast.",
    (
        _str("bag_path", "Bag directory to publish (required)."),
        _kind("strs", "topics", "Contract topics published."),
        _str("namespace", 'Namespace of the bag\'s topics to play ("" = the only one).'),
        _f("start_offset_s", "Log time skipped from the first message.", "s", 0.0, 1e9),
        _bool("loop", "Start again at the end."),
        _f("rate", "Playback speed over the recorded one.", "", 0.01, 100.0),
        _bool("publish_clock", "Publish the log time on /clock."),
        _WAIT_FOR,
        _SETTLE,
        _open("publish_period_s", "Timer period, wall clock.", "s", high=10.0),
        _QOS_DEPTH,
    ),
    file="replay.yaml",
)

SEND = Section(
    "send",
    "`tail-beam send` (the command line checks these, naming its options).",
    (
        _open("timeout_s", "How long to wait for sim_node.", "s", high=86400.0),
        _open("truth_timeout_s", "How long --wait-truth waits.", "s", high=86400.0),
    ),
    file="send.yaml",
)

# --- tail_beam_id ------------------------------------------------------------------------------

ID_METHODS = ("threshold", "statistical", "physics")

ID_NODE_TOP = Section(
    "",
    "Top-level parameters of id_node.",
    (_str("method", 'Identification method ("" = identification.method).'),),
    file="id_node.yaml",
)

ID_NODE = Section(
    "id_node",
    "id_node: pacing, arrival order and online calibration (wall-clock s unless said).",
    (
        _open("poll_period_s", "Period at which samples go to the identifier.", "s", high=10.0),
        _QOS_DEPTH,
        _open(
            "flush_after_idle_s", "With no message this long, pending impacts are decided.", "s"
        ),
        _f(
            "reorder_s",
            "Hold after arrival before a sample is handed on in stamp order.",
            "s",
            0.0,
            10.0,
        ),
        _open(
            "stream_idle_s",
            "A silent stream stops holding the others back after this.",
            "s",
            high=60.0,
        ),
        _open(
            "time_jump_s", "Stamps going back more than this start a new time base.", "s", high=1e6
        ),
        _f(
            "calibrate_online_s",
            "Stamp time of data to self-calibrate from (0 = never).",
            "s",
            0.0,
            3600.0,
        ),
    ),
    file="id_node.yaml",
)

_WINDOW = dict(unit="s", high=10.0)
IDENTIFICATION = Section(
    "identification",
    "Coal-gangue identification: method, windows and timeouts (stamp time, s).",
    (
        _choice("method", "Identification method.", ID_METHODS),
        _bool(
            "self_calibrate",
            "`tail-beam identify` calibrates to the bag's support first.",
            default=True,
        ),
        _open("window_s", "Signal after the onset every method waits for.", **_WINDOW),
        _open(
            "vibration_window_s",
            "The same for an impact found in the accelerometer's stream (absent: window_s).",
            "s",
            high="window_s",
            default=None,
        ),
        _open(
            "pressure_pre_s",
            "Pressure before the onset the fit learns the background from.",
            **_WINDOW,
        ),
        _open(
            "impulse_pre_s", "IMU background fitted over this much before the pulse.", **_WINDOW
        ),
        _open(
            "impulse_skip_s", "Plate velocity fitted from this long after the onset.", **_WINDOW
        ),
        _open("impulse_post_s", "... up to this long after it (<= window_s).", **_WINDOW),
        _open("stream_timeout_s", "A continuous stream lagging this much is stopped.", **_WINDOW),
        _open("camera_timeout_s", "Wait for the camera after the rebound window.", **_WINDOW),
        _open("overlap_window_s", "Onsets closer than this overlap (<= window_s).", **_WINDOW),
        _f(
            "overlap_confidence_cap",
            "Most confidence of an overlapping impact's label.",
            "",
            0.5,
            1.0,
        ),
        _open(
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
        "statistical",
        "threshold",
        "physics",
    ),
)

SENSOR_TIMING = Section(
    "identification.sensor_timing",
    "The check of the camera's and the acceleration channel's clocks.",
    (
        _int(
            "min_impacts",
            "Impacts checked before a recording is judged.",
            1,
            MAX_QOS_DEPTH,
            default=10,
        ),
        _open(
            "agreeing_rate",
            "Share of unusual delays agreeing clocks give.",
            high=0.5,
            default=0.03,
        ),
        _open(
            "false_alarm", "Share of agreeing recordings called suspect.", high=0.5, default=1e-3
        ),
        _f(
            "confidence_cap",
            "Confidence cap of a suspect recording's delay labels.",
            "",
            0.5,
            1.0,
            default=0.6,
        ),
    ),
    file="identification.yaml",
)

_FIT_S = dict(unit="s", high=0.1)
CONTACT_FIT = Section(
    "identification.contact_fit",
    "The contact's duration read from the acceleration pulse (feature contact_duration_s).",
    (
        _open(
            "ring_start_s",
            "Ring-down read from this long after the onset.",
            default=0.0015,
            **_FIT_S,
        ),
        _open(
            "ring_end_s", "... to this long after it (> ring_start_s).", default=0.006, **_FIT_S
        ),
        _open("before_s", "Fit from this long before the onset.", default=0.0003, **_FIT_S),
        _open(
            "early_ring_start_s",
            "Second pass: ring-down not before this.",
            default=0.0005,
            **_FIT_S,
        ),
        _open(
            "ring_after_contact_s",
            "Second pass: this after the first pass's contact.",
            default=0.0001,
            **_FIT_S,
        ),
        _f(
            "ring_after_contact_factor",
            "... plus this many first-pass durations.",
            "",
            1.0,
            10.0,
            default=1.5,
        ),
        _open("after_s", "Fit to this long after the onset.", default=0.003, **_FIT_S),
        _open("min_duration_s", "Shortest half-sine force tried.", default=3.0e-5, **_FIT_S),
        _open("max_duration_s", "Longest half-sine force tried.", default=0.002, **_FIT_S),
        _int("max_modes", "Most damped sinusoids read from the ring-down.", 1, 8, default=4),
        _int("min_ring_samples", "Fewer ring-down samples: no fit.", 8, 10000, default=24),
        _f(
            "min_mode_frequency_hz",
            "Slower poles are left to the sway.",
            "Hz",
            0.0,
            1e5,
            default=150.0,
        ),
        _f(
            "max_fit_rate_hz",
            "A faster channel is decimated to at most this.",
            "Hz",
            1000.0,
            1e6,
            default=51200.0,
        ),
    ),
    file="identification.yaml",
)

_SIGMA = dict(high=1e3)
_DET_S = dict(unit="s", high=1.0)
DETECTION = Section(
    "identification.detection",
    "Impact detection in the IMU, accelerometer and pressure streams (thresholds in noise RMS).",
    (
        _open("accel_threshold_sigma", "A pulse starts below -this.", **_SIGMA),
        _open("extend_threshold_sigma", "The pulse extends over samples beyond this.", **_SIGMA),
        _open("onset_threshold_sigma", "Its onset: the first sample beyond this.", **_SIGMA),
        _open("onset_lookback_s", "Onset looked for up to this before the detection.", **_DET_S),
        _open("baseline_window_s", "Background fitted over this before the pulse.", **_DET_S),
        _open("sway_window_s", "Free sway fitted over this before the look-back.", **_DET_S),
        _open("noise_block_s", "Noise RMS estimated over blocks of this.", "s", high=100.0),
        _open("max_contact_s", "Longest contact a pulse may span.", **_DET_S),
        _open(
            "rebound_early_tolerance_s",
            "A rebound this early still belongs to the pulse.",
            **_DET_S,
        ),
        _open("unconfirmed_pulse_sigma", "An unconfirmed pulse must be this strong.", high=1e6),
        _open(
            "pressure_confirm_sigma",
            "Moment impulse confirming a pulse, standard errors.",
            **_SIGMA,
        ),
        _open(
            "pressure_threshold_sigma",
            "Pressure-only detection threshold, standard errors.",
            **_SIGMA,
        ),
        _open("ring_fraction", "Threshold over the ringing's envelope after a pulse.", high=100.0),
        _open("ring_decay_s", "Decay time of that envelope.", "s", high=10.0),
        _open("ring_window_s", "How long the raised threshold lasts.", "s", high=10.0),
        _open(
            "rebound_onset_lead_s", "Onset of a rebound-only impact before its stamp.", **_DET_S
        ),
        _open(
            "pressure_onset_uncertainty_s",
            "Onset uncertainty of pressure-only detection.",
            **_DET_S,
        ),
        _open(
            "onset_before_rebound_max_s",
            "Contact began at most this before the rebound.",
            **_DET_S,
        ),
        _open(
            "rebound_frame_allowance_s",
            "Camera frame the rebound window allows for.",
            default=0.0005,
            **_DET_S,
        ),
        _f(
            "pressure_drift_confirm_sigma",
            "Moment impulse kept against a drifting sway.",
            "",
            0.0,
            1e3,
            default=2.5,
        ),
        _f(
            "late_rebound_max_s",
            "A late rebound up to this after the onset (0 = off).",
            "s",
            0.0,
            1.0,
            default=0.025,
        ),
    ),
    file="identification.yaml",
)

EVALUATION = Section(
    "identification.evaluation",
    "Scene sets of `tail-beam evaluate` and of training (checked where they are used).",
    (
        _kind("mapping", "seeds", "Seed of each scene set."),
        _int("training_seed", "Seed of the training set."),
        _int("impacts_per_set", "Impacts per scene set."),
        _kind("floats", "noise_factors", "Noise factors evaluated."),
        _choice("tier", "Model the impacts are simulated with.", ("rigid", "modal")),
        _f("pre_contact_s", "Signal simulated before each contact.", "s"),
        _f("window_s", "Signal simulated after each contact.", "s"),
        _kind("mapping", "rates", "Sensor settings by name (Hz)."),
        _kind("strs", "default_rates", "Sensor settings a plain evaluate runs."),
        _kind("mapping", "material_mix", "Each material's share of a scene set."),
        _kind("mapping", "paper", "The paper scene's impact ranges."),
        _kind("mapping", "stream", "The stream scene's impact ranges."),
        _f("support_perturbation", "Mismatch set: scale of the support's perturbation."),
        _kind("strs", "mismatch_contact_models", "Mismatch set: contact laws."),
        _kind("mapping", "supports", "Ranges supports other than the nominal one are drawn from."),
        _int("foreign_supports", "Supports of the foreign set."),
        _int("foreign_impacts_per_support", "Impacts per foreign support."),
        _f("stream_gap_s", "Least time between the foreign set's impacts.", "s"),
        _kind("floats", "size_bins_m", "Radius bins of the accuracy-by-size table, m."),
    ),
    file="identification.yaml",
)

_CAP = dict(low=0.5, high=1.0)
STATISTICAL = Section(
    "identification.statistical",
    "The statistical method.",
    (
        _f(
            "outside_confidence_cap",
            "Confidence cap outside the training envelope.",
            default=0.6,
            **_CAP,
        ),
        _open(
            "reference_camera_frame_rate_hz",
            "Camera frame rate of the training's streams.",
            "Hz",
            high=1e6,
            default=5000.0,
        ),
        _open(
            "slowest_delay_camera_frame_rate_hz",
            "Slower cameras are decided without the rebound delay.",
            "Hz",
            high=1e6,
            default=2000.0,
        ),
    ),
    file="identification.yaml",
    sections=("hysteresis",),
)

HYSTERESIS = Section(
    "identification.statistical.hysteresis",
    "The support's contact hysteresis read by self-calibration.",
    (
        _open("reference_restitution", "Gangue restitution the latent refers to.", high=0.999),
        _kind("floats", "bin_edges", "Edges of the latent's bins (increasing)."),
        _int(
            "min_impacts",
            "Impacts with every signal needed to read it.",
            1,
            MAX_QOS_DEPTH,
            default=8,
        ),
    ),
    file="identification.yaml",
)

THRESHOLD = Section(
    "identification.threshold",
    "The threshold method.",
    (_f("extrapolation_confidence_cap", "Confidence cap outside the tuned range.", **_CAP),),
    file="identification.yaml",
)

PHYSICS = Section(
    "identification.physics",
    "The physics method's inversion: priors and observation errors.",
    (
        _kind(
            "pair", "prior_radius_m", "Prior radius range (log-uniform).", low=0.0, low_open=True
        ),
        _kind("pair", "prior_drop_height_m", "Prior drop height range.", low=0.0, low_open=True),
        _kind("pair", "prior_position_m", "Prior impact position range.", low=0.0, low_open=True),
        _int("prior_samples", "Prior particles per material.", 100, MAX_QOS_DEPTH),
        _int("seed", "Seed of the prior.", default=0),
        _f("moment_model_error", "Relative error of the rigid-beam moment impulse.", "", 0.0, 1.0),
        _f("duration_model_error", "Relative error of the Hertz contact duration.", "", 0.0, 1.0),
        _open("rebound_noise_mps", "Camera rebound-velocity noise RMS.", "m/s"),
        _f("rebound_noise_fraction", "... plus this fraction of the reading.", "", 0.0, 1.0),
        _f("outlier_log_likelihood", "Below this no particle explains the impact.", "", None, 0.0),
        _f("outlier_confidence_cap", "Confidence cap of such an impact.", **_CAP),
    ),
    file="identification.yaml",
)

SECTIONS: tuple[Section, ...] = (
    SUPPORT,
    MATERIAL,
    SENSORS,
    SCENE,
    MODES,
    BENDING_MODE,
    FIDELITY,
    STREAM,
    SIM_NODE,
    SCENARIO,
    RECORDER,
    REPLAY,
    SEND,
    ID_NODE_TOP,
    ID_NODE,
    IDENTIFICATION,
    SENSOR_TIMING,
    CONTACT_FIT,
    DETECTION,
    EVALUATION,
    STATISTICAL,
    HYSTERESIS,
    THRESHOLD,
    PHYSICS,
)
NOT_PARAMETERS = ("impacts.yaml",)  # config/ files that hold a scene list, not parameters


# --- config/ against the tables ------------------------------------------------------------------


def _matches(path: str, pattern: str) -> bool:
    """Segment-wise match of a dotted path against a pattern whose segments may hold ``*``."""
    if pattern == "":
        return path == ""
    parts, wanted = path.split("."), pattern.split(".")
    return len(parts) == len(wanted) and all(map(fnmatch.fnmatchcase, parts, wanted))


def section_for(path: str) -> Section | None:
    """The section declared for the dotted section ``path`` (``materials.coal``), if any."""
    return next((s for s in SECTIONS if _matches(path, s.path)), None)


def shipped_parameters(config_dir: Path | None = None) -> dict[str, dict[str, Any]]:
    """Every parameter file of config/ by name, as read (impacts.yaml left out)."""
    folder = config_dir or default_config_dir()
    return {
        p.name: read_parameter_file(p)
        for p in sorted(folder.glob("*.yaml"))
        if p.name not in NOT_PARAMETERS
    }


def unspecified_keys(params: Mapping[str, Any]) -> list[str]:
    """Dotted names in ``params`` that no section declares (a mapping field covers its keys)."""
    out = []
    for name in flatten(params):
        parent, _, leaf = name.rpartition(".")
        covered = False
        prefix = ""
        for part in name.split("."):
            section = section_for(prefix)
            if section is not None and part in section and section[part].kind == "mapping":
                covered = True
                break
            prefix = f"{prefix}.{part}" if prefix else part
        section = section_for(parent)
        if not covered and (section is None or leaf not in section):
            out.append(name)
    return out


def _mappings(params: Mapping[str, Any], prefix: str = "") -> Iterator[tuple[str, Mapping]]:
    yield prefix, params
    for key, value in params.items():
        if isinstance(value, Mapping):
            yield from _mappings(value, f"{prefix}.{key}" if prefix else key)


def missing_keys(params: Mapping[str, Any], sections: Iterable[Section] = SECTIONS) -> list[str]:
    """Required fields of ``sections`` that ``params`` has the section of but not the field."""
    out = []
    found = list(_mappings(params))
    for section in sections:
        for path, body in found:
            if path and _matches(path, section.path) or (section.path == path == ""):
                if section.path == "" and not any(f.name in body for f in section):
                    continue  # the top level holds another file's sections
                prefix = f"{path}." if path else ""
                out += [f"{prefix}{f.name}" for f in section if f.required and f.name not in body]
    return out


# --- the reference page -------------------------------------------------------------------------


def _default_text(value: Any) -> str:
    if value is REQUIRED or value is None:
        return "—"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return f'`"{value}"`' if value == "" else f"`{value}`"
    if isinstance(value, Mapping):
        return "(table)"
    text = shorten(value, 40)
    return f"`{text}`"


def render_reference(config_dir: Path | None = None) -> str:
    """The parameter reference (docs/parameters.md) as Markdown: a table per section with each
    field's unit, allowed range, default (config/'s value, else the built-in one) and meaning."""
    files = shipped_parameters(config_dir)
    lines = [
        "# Parameter reference",
        "",
        "Generated from the tables of `tail_beam_sim/spec.py`; do not edit by hand.",
        "Regenerate with",
        "",
        "    python -m tail_beam_sim.spec > docs/parameters.md",
        "",
        "Every parameter is a ROS 2 parameter of the nodes that read its file (`-p name:=value`,",
        "`--params-file`) and is read by the commands from the same files. A range `(a, b]`",
        "excludes a; a bound given by name is that parameter's value. A default is config/'s",
        "value; a parameter config/ leaves out takes the built-in one; `—` means required.",
        "",
    ]
    for section in SECTIONS:
        title = section.path or "(top level)"
        lines += [f"## `{title}`", "", section.meaning, ""]
        if section.file:
            lines += [f"File: `config/{section.file}`.", ""]
        lines += ["| name | unit | range | default | meaning |", "|---|---|---|---|---|"]
        shipped = files.get(section.file, {})
        body = _first_instance(shipped, section.path)
        for spec in section:
            value = body.get(spec.name, spec.default) if body is not None else spec.default
            if spec.kind == "floats" and isinstance(value, list) and len(value) > 6:
                value = f"{len(value)} values"
            unit = spec.unit if spec.kind not in ("int",) or spec.unit else ""
            lines.append(
                f"| `{spec.name}` | {unit or ''} | {spec.range_text()} | {_default_text(value)} "
                f"| {spec.meaning} |"
            )
        lines.append("")
    return "\n".join(lines)


def _first_instance(params: Mapping[str, Any], pattern: str) -> Mapping[str, Any] | None:
    for path, body in _mappings(params):
        if _matches(path, pattern):
            return body
    return None


def main(argv: Sequence[str] | None = None) -> int:
    """Print the parameter reference (``python -m tail_beam_sim.spec > docs/parameters.md``)."""
    sys.stdout.write(render_reference())
    return 0


if __name__ == "__main__":
    sys.exit(main())
