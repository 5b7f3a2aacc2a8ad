"""The suite's parameters declared once: per section, each field's name, kind, unit, allowed
range, default and meaning.

A :class:`Section` checks its part of the merged parameters (``config/*.yaml``, ``-p``,
``--params-file``) and returns the validated values by name; every refusal is the
:class:`~tail_beam_sim.errors.InputError` naming the dotted field, the value and what is
allowed, unit included. The same tables render the parameter reference::

    python -m tail_beam_sim.spec > docs/parameters.md

(another package's sections join with its module named after the command) and let a test
check that config/ and the tables agree (:func:`unspecified_keys`, :func:`missing_keys`).

A bound may be a number or the name of another field of the section checked before it (a
jack pin on the beam: ``high="beam_length_m"``), or of a value the caller passes in
``context`` (a bound that comes from another section: the support's largest particle). A
bound that names nothing given is no bound.
"""

from __future__ import annotations

import fnmatch
import importlib
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
            return [
                require_range(
                    f"{dotted}[{k}]", x, low, high, low_open=self.low_open, unit=self.unit
                )
                for k, x in enumerate(value)
            ]
        if kind == "strs":
            if isinstance(value, str) or not isinstance(value, Sequence):
                raise InputError(dotted, value, self.allowed())
            if not all(isinstance(x, str) for x in value):
                raise InputError(dotted, value, self.allowed())
            return list(value)
        return require_section(dotted, value)  # mapping

    def range_text(self) -> str:
        """The allowed values as the reference page shows them (bounds by name where named)."""
        bounded = self.low is not None or self.high is not None
        if self.kind in ("bool", "str", "strs", "mapping") or (
            self.kind == "floats" and not bounded
        ):
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
            elif self.kind == "floats":
                text = f"list of numbers in {text}"
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


def number(
    name: str, meaning: str, unit: str = "", low: Bound = None, high: Bound = None, **kw: Any
):
    """A float field (the tables' shorthand)."""
    return Field(name, meaning, "float", unit, low, high, **kw)


def positive(name: str, meaning: str, unit: str = "", low: Bound = 0.0, high: Bound = None, **kw):
    """A float field whose low bound (0 unless given) is excluded."""
    return Field(name, meaning, "float", unit, low, high, low_open=True, **kw)


def integer(name: str, meaning: str, low: Bound = None, high: Bound = None, **kw: Any) -> Field:
    return Field(name, meaning, "int", kw.pop("unit", ""), low, high, **kw)


def text(name: str, meaning: str, **kw: Any) -> Field:
    return Field(name, meaning, "str", **kw)


def flag(name: str, meaning: str, **kw: Any) -> Field:
    return Field(name, meaning, "bool", **kw)


def choice(name: str, meaning: str, choices: Sequence[str], **kw: Any) -> Field:
    return Field(name, meaning, "choice", choices=tuple(choices), **kw)


def of_kind(kind: str, name: str, meaning: str, **kw: Any) -> Field:
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
SCENARIO_SOURCES = ("none", "file", "generated", "flow")
MAX_GENERATED = 100_000  # most impacts a generated scenario may hold (memory, start-up time)
MAX_QOS_DEPTH = 1_000_000  # deepest history a subscription or publisher may keep, messages
MIB = 2**20

SUPPORT = Section(
    "support",
    "The hydraulic support: beam, plate, jack and the limits of what may strike it.",
    (
        number("gravity_mps2", "Gravitational acceleration.", "m/s^2", 0.0, 100.0),
        positive("beam_length_m", "Tail beam length from the hinge to its tip.", "m", high=20.0),
        positive("beam_mass_kg", "Mass of the tail beam.", "kg"),
        number(
            "beam_inertia_about_hinge_kgm2",
            "Beam's moment of inertia about the hinge (a rigid wall: very large).",
            "kg m^2",
            1.0,
        ),
        text("plate_material", "Material of the impact plate (a materials entry)."),
        positive("plate_thickness_m", "Impact plate thickness.", "m", high=1.0),
        positive(
            "plate_width_m",
            "Impact plate width across the beam (impact_point.point.y within +-half).",
            "m",
            high=20.0,
            default=1.5,
        ),
        number(
            "contact_damping_scale",
            "Factor on the contact law's hysteresis (1 = as published).",
            "(dimensionless)",
            0.1,
            10.0,
            default=1.0,
        ),
        positive(
            "jack_pin_from_hinge_m",
            "Jack pin's distance from the hinge.",
            "m",
            high="beam_length_m",
        ),
        positive(
            "jack_angle_to_beam_deg", "Angle between the jack and the beam.", "deg", high=90.0
        ),
        positive("jack_bore_m", "Jack cylinder bore.", "m", high=2.0),
        positive("jack_oil_column_m", "Length of the jack's oil column.", "m", high=10.0),
        positive("jack_wall_thickness_m", "Jack cylinder wall thickness.", "m", high=1.0),
        positive("jack_wall_youngs_modulus_pa", "Young's modulus of the cylinder wall.", "Pa"),
        positive("oil_bulk_modulus_pa", "Bulk modulus of the hydraulic oil.", "Pa"),
        number("jack_damping_nspm", "Viscous damping of the jack.", "N s/m", 0.0),
        number(
            "jack_extra_compliance_mpn", "Compliance added in series with the jack.", "m/N", 0.0
        ),
        number("setting_pressure_pa", "Static (setting) pressure of the jack.", "Pa", 0.0),
        number("imu_from_hinge_m", "IMU's distance from the hinge.", "m", 0.0, "beam_length_m"),
        number(
            "impact_zone_min_m", "Nearest impact position to the hinge.", "m", 0.0, "beam_length_m"
        ),
        number("impact_zone_max_m", "Farthest impact position.", "m", 0.0, "beam_length_m"),
        positive("particle_radius_min_m", "Smallest particle radius accepted.", "m"),
        number("particle_radius_max_m", "Largest particle radius.", "m", "particle_radius_min_m"),
        positive("drop_height_min_m", "Lowest drop height accepted.", "m"),
        number("drop_height_max_m", "Highest drop height.", "m", "drop_height_min_m"),
        positive("impact_speed_min_mps", "Slowest impact speed accepted.", "m/s"),
        number("impact_speed_max_mps", "Fastest impact speed.", "m/s", "impact_speed_min_mps"),
    ),
    file="support.yaml",
)

MATERIAL = Section(
    "materials.*",
    "One particle or plate material (an entry per name).",
    (
        choice("class", "What it is.", MATERIAL_CLASSES),
        positive("density_kgpm3", "Density.", "kg/m^3", high=30000.0),
        positive("youngs_modulus_pa", "Young's modulus.", "Pa", high=2e12),
        positive("poisson_ratio", "Poisson's ratio.", low=-1.0, high=0.5),
        positive("restitution", "Nominal coefficient of restitution on steel.", low=0.0, high=1.0),
        of_kind(
            "pair",
            "restitution_range",
            "Restitution a realistic scene draws from (absent: the nominal one).",
            low=0.0,
            high=1.0,
            low_open=True,
            default=None,
        ),
        positive(
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
        integer("seed", "Seed of the sensors' noise.", 0, default=0),
        number("pressure_rate_hz", "Jack pressure sample rate.", "Hz", *SENSOR_RATE),
        number("pressure_noise_pa", "Pressure noise RMS.", "Pa", 0.0),
        number("pressure_range_min_pa", "Lowest pressure the transducer reads.", "Pa"),
        positive(
            "pressure_range_max_pa", "Highest pressure it reads.", "Pa", "pressure_range_min_pa"
        ),
        number("imu_rate_hz", "IMU sample rate.", "Hz", *SENSOR_RATE),
        number(
            "imu_noise_nominal_rate_hz",
            "Rate at which the IMU noise RMS below holds (it scales with sqrt of the rate).",
            "Hz",
            *SENSOR_RATE,
        ),
        number("imu_accel_noise_mps2", "IMU specific-force noise RMS.", "m/s^2", 0.0),
        number("imu_gyro_noise_radps", "IMU angular-rate noise RMS.", "rad/s", 0.0),
        integer(
            "imu_antialias_order",
            "IMU sampling filter: 0 = mean over the sample period, N = Butterworth order.",
            0,
            10,
            default=0,
        ),
        positive(
            "imu_antialias_cutoff_fraction",
            "Its cut-off over the sample rate.",
            high=0.5,
            default=0.25,
        ),
        integer("imu_oversample", "Beam response computed per IMU sample.", 2, 32, default=4),
        number("camera_frame_rate_hz", "Rebound camera frame rate.", "Hz", *SENSOR_RATE),
        number("camera_velocity_noise_mps", "Rebound-velocity noise RMS.", "m/s", 0.0),
        number(
            "camera_velocity_noise_fraction", "Rebound-velocity noise as a fraction.", "", 0.0, 1.0
        ),
        number(
            "vibration_rate_hz",
            "Tail-beam accelerometer sample rate.",
            "Hz",
            1000.0,
            100000.0,
            default=25600.0,
        ),
        integer(
            "vibration_block_samples", "Samples per vibration message.", 1, 65536, default=128
        ),
        number(
            "vibration_noise_density_mps2_rthz",
            "Accelerometer white-noise density.",
            "m/s^2/sqrt(Hz)",
            0.0,
            default=0.002,
        ),
        positive(
            "vibration_range_mps2", "Accelerometer full scale.", "m/s^2", high=1e6, default=2000.0
        ),
        integer("vibration_antialias_order", "Its Butterworth filter order.", 1, 10, default=4),
        positive(
            "vibration_antialias_cutoff_fraction",
            "Its cut-off over the sample rate.",
            high=0.5,
            default=0.4,
        ),
        integer("vibration_oversample", "Beam response computed per sample.", 2, 32, default=4),
        flag(
            "camera_reports_impact_point",
            "The rebound camera also publishes where the particle struck (impact_point).",
            default=False,
        ),
        number(
            "impact_point_noise_m",
            "Impact point noise RMS, per coordinate on the plate.",
            "m",
            0.0,
            1.0,
            default=0.01,
        ),
    ),
    file="sensors.yaml",
)

SCENE = Section(
    "scene",
    "The impact of `tail-beam simulate` and the window simulated (impact fields are checked "
    "against the support's limits).",
    (
        text("material", "Particle material (a coal or gangue materials entry)."),
        number(
            "radius_m",
            "Particle radius.",
            "m",
            "support.particle_radius_min_m",
            "support.particle_radius_max_m",
        ),
        number(
            "drop_height_m",
            "Drop height (or impact_speed_mps).",
            "m",
            "support.drop_height_min_m",
            "support.drop_height_max_m",
        ),
        number("position_m", "Impact position from the hinge.", "m", 0.0, "support.beam_length_m"),
        choice("contact_model", "Contact law.", CONTACT_LAWS, default="calibrated"),
        positive("window_s", "Time simulated after first contact.", "s", high=10.0, default=0.05),
        number(
            "pre_contact_s", "Time simulated before first contact.", "s", 0.0, 10.0, default=0.005
        ),
    ),
    file="scene.yaml",
)

MODES = Section(
    "modes",
    "The beam's bending modes (derived by `tail-beam modes`).",
    (
        integer("count", "How many of the bending_N modes the model uses.", 0, "bending_modes"),
        of_kind("mapping", "derived_from", "The beam model the modes were derived from."),
        of_kind("floats", "stations_m", "Positions along the beam the shapes are given at, m."),
    ),
    file="modes.yaml",
    sections=("bending_*",),
)

BENDING_MODE = Section(
    "modes.bending_*",
    "One bending mode.",
    (
        positive("frequency_hz", "Undamped frequency (beam held at hinge and jack pin).", "Hz"),
        number("damping_ratio", "Modal damping ratio.", "", 0.0, 1.0),
        positive("modal_mass_kg", "Modal mass (shape normalised to 1 at the tip).", "kg"),
        number("rigid_coupling_kgm", "Mass coupling with the rigid rotation.", "kg m"),
        of_kind("floats", "shape", "Mode shape at modes.stations_m."),
        of_kind("floats", "slope_radpm", "Its slope at modes.stations_m, rad/m."),
    ),
    file="modes.yaml",
)

FIDELITY = Section(
    "fidelity",
    "How much model a scene gets (`tail-beam simulate`).",
    (
        choice(
            "tier", "Model tier when --tier is not given.", ("auto", *TIER_NAMES), default="auto"
        ),
        of_kind(
            "strs",
            "outputs",
            "What the scene needs, for the automatic choice (rebound, contact, pressure, imu).",
            default=list(FIDELITY_OUTPUTS),
        ),
        positive(
            "tolerance", "Relative error the automatic choice accepts.", high=1.0, default=0.01
        ),
        positive(
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
        choice("tier", "Model tier of the stream.", TIER_NAMES, default="rigid"),
        number("min_impact_gap_s", "Least time between two contacts.", "s", 0.0, 60.0),
        positive(
            "command_lead_s", "How far ahead of the stream a command is scheduled.", "s", high=60.0
        ),
        integer("max_queued_impacts", "Most impacts waiting to be simulated.", 1),
    ),
    file="sim_node.yaml",
)

QOS_DEPTH = integer(
    "qos_depth", "History depth of the stream topics, messages (0 = keep all).", 0, MAX_QOS_DEPTH
)
WAIT_FOR_SUBSCRIBERS = integer(
    "wait_for_subscribers", "Subscribers each stream waits for before publishing.", 0, 1000
)
SUBSCRIBER_SETTLE = number(
    "subscriber_settle_s", "Wait after they matched, for discovery to settle.", "s", 0.0, 60.0
)

SIM_NODE = Section(
    "sim_node",
    "sim_node's pacing and publishing.",
    (
        number(
            "realtime_factor",
            "Simulation speed over wall clock (0 = as fast as possible).",
            "",
            0.0,
            1e6,
        ),
        positive("publish_period_s", "Timer period, wall clock.", "s", high=10.0),
        positive("max_chunk_s", "Most simulation time advanced per tick.", "s", high=10.0),
        number("max_lag_s", "Lag behind real time after which it runs slower.", "s", 0.0, 3600.0),
        WAIT_FOR_SUBSCRIBERS,
        SUBSCRIBER_SETTLE,
        flag("publish_clock", "Publish simulation time on /clock."),
        QOS_DEPTH,
        number(
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
    "sim_node's start-up impacts: none, a file, a generated caving stream, or a drawing "
    "opening's flow (section flow, opened and closed on window_cmd).",
    (
        choice("source", "Where the impacts come from.", SCENARIO_SOURCES, default="none"),
        text("file", "Scenario file (source file).", default=""),
        integer("count", "Impacts generated.", 0, MAX_GENERATED),
        number("gangue_fraction", "Share of gangue among them.", "", 0.0, 1.0),
        of_kind(
            "pair",
            "radius_m",
            "Radius range.",
            unit="m",
            low=0.0,
            high="particle_radius_max_m",
            low_open=True,
        ),
        of_kind(
            "pair",
            "drop_height_m",
            "Drop height range.",
            unit="m",
            low=0.0,
            high="drop_height_max_m",
            low_open=True,
        ),
        of_kind("pair", "position_m", "Impact position range.", unit="m", low=0.0, low_open=True),
        of_kind(
            "pair",
            "interval_s",
            "Time between contacts.",
            unit="s",
            low=0.0,
            high=3600.0,
            low_open=True,
        ),
        number("start_s", "Simulation time of the first contact.", "s", 0.0, default=0.0),
        integer("seed", "Seed of the generated stream.", 0, default=0),
    ),
    file="sim_node.yaml",
)

FLOW_CONTACT_METHODS = ("pulse", "auto", "rk4")  # the hybrid solver's contact option
FLOW_RATE_KINDS = ("lumps", "mass")  # flow.rate_kind: lumps per second or kilograms per second
MAX_FLOW_LUMPS_PER_S = 1000.0  # the densest flow the simulator takes, lumps/s
MAX_FLOW_MASS_RATE_KGPS = 5000.0  # the largest mass rate it takes, kg/s
FLOW = Section(
    "flow",
    "A drawing opening's flow of coal and gangue lumps (scenario.source flow; "
    "tail_beam_sim.physics.flow, docs/flow.md).",
    (
        choice(
            "rate_kind",
            "What sets the arrival rate: lumps (lumps_per_s) or mass (mass_rate_kgps).",
            FLOW_RATE_KINDS,
            default="lumps",
        ),
        positive(
            "lumps_per_s",
            "Mean lumps striking the beam per second (rate_kind lumps; Poisson arrivals).",
            "lumps/s",
            high=MAX_FLOW_LUMPS_PER_S,
            default=50.0,
        ),
        positive(
            "mass_rate_kgps",
            "Mean mass striking the beam per second (rate_kind mass).",
            "kg/s",
            high=MAX_FLOW_MASS_RATE_KGPS,
            default=100.0,
        ),
        positive(
            "radius_median_m",
            "Median lump radius of the log-normal size distribution.",
            "m",
            high="particle_radius_max_m",
            default=0.04,
        ),
        number(
            "radius_log_sigma",
            "Log-normal spread of the radius (standard deviation of ln radius; 0: one size).",
            "",
            0.0,
            2.0,
            default=0.4,
        ),
        of_kind(
            "pair",
            "radius_m",
            "Radius range the distribution is truncated to.",
            unit="m",
            low="particle_radius_min_m",
            high="particle_radius_max_m",
            default=[0.015, 0.12],
        ),
        of_kind(
            "pair",
            "drop_height_m",
            "Drop height range (opening above the beam), drawn uniformly.",
            unit="m",
            low=0.0,
            high="drop_height_max_m",
            low_open=True,
            default=[1.0, 3.0],
        ),
        of_kind(
            "pair",
            "position_m",
            "Strike positions from the hinge (the opening's footprint), drawn uniformly.",
            unit="m",
            low=0.0,
            high="impact_zone_max_m",
            low_open=True,
            default=[0.3, 1.3],
        ),
        text("coal_material", "Material of the coal lumps.", default="coal"),
        of_kind(
            "strs",
            "gangue_materials",
            "Materials of the gangue lumps, drawn uniformly.",
            default=["mudstone", "sandstone"],
        ),
        of_kind(
            "floats",
            "share_drawn_mass_kg",
            "Share curve: drawn mass since the window first opened, strictly increasing.",
            unit="kg",
            low=0.0,
            default=[0.0, 10000.0],
        ),
        of_kind(
            "floats",
            "share_gangue",
            "Share curve: gangue share by mass of the flow at each drawn mass (linear between, "
            "held beyond the ends).",
            low=0.0,
            high=1.0,
            default=[0.0, 0.0],
        ),
        positive(
            "interval_s", "Length of a gangue_share_truth interval.", "s", high=60.0, default=1.0
        ),
        number(
            "onset_delay_s",
            "Time from the window opening to the first lump's fall reaching the beam.",
            "s",
            0.0,
            10.0,
            default=0.5,
        ),
        integer(
            "seed", "Seed of the lumps (rate, sizes, materials, heights, positions).", 0, default=0
        ),
        choice(
            "contact",
            "How the hybrid solver takes each lump's contact: pulse (the pre-integrated pulse "
            "always), auto (integrated when the pulse's error estimate is large), rk4.",
            FLOW_CONTACT_METHODS,
            default="pulse",
        ),
        number(
            "open_at_s",
            "Simulation time the window opens at start-up (sim_node, tail-beam simulate --flow).",
            "s",
            0.0,
            1e6,
            off=-1.0,
            off_meaning="stays closed until window_cmd opens it",
            default=-1.0,
        ),
        positive(
            "duration_s",
            "Simulation time a start-up opening stays open (then closes).",
            "s",
            high=1e6,
            off=0.0,
            off_meaning="open until window_cmd closes it",
            default=0.0,
        ),
    ),
    file="flow.yaml",
)

RECORDER = Section(
    "recorder",
    "bag_recorder: what it writes and how often.",
    (
        text("bag_path", 'Bag directory to create ("" = out/bags/tail_beam_<UTC time>).'),
        text("storage", "Storage plugin: mcap or sqlite3."),
        text("compression", "mcap chunk compression: zstd or none."),
        positive("segment_s", "Wall time per closed segment file of the bag.", "s", high=3600.0),
        positive(
            "flush_s", "Wall time between flushes (what a SIGKILL may lose).", "s", high=3600.0
        ),
        number(
            "max_bag_duration_s",
            "Start a new file after this much log time.",
            "s",
            1.0,
            1e7,
            off=0.0,
            off_meaning="never split",
        ),
        integer(
            "max_bag_size_bytes",
            "Start a new file at this size.",
            MIB,
            2**62,
            unit="bytes",
            off=0,
            off_meaning="never split",
        ),
        QOS_DEPTH,
    ),
    file="recorder.yaml",
)

MAX_HOST_SUPPORTS = 64  # supports one face_host process may run

FACE_HOST = Section(
    "face_host",
    "face_host: several supports' sim_node and id_node (and bag_recorder) in one process.",
    (
        integer(
            "supports",
            "Supports run, as /support_001 .. (face_host.namespaces, when given, wins).",
            1,
            MAX_HOST_SUPPORTS,
        ),
        of_kind(
            "strs",
            "namespaces",
            'Absolute namespaces of the supports run ([""] = /support_001 .. by count).',
        ),
        flag("record", "Run each support's bag_recorder too (a bag per support)."),
        integer(
            "seed_stride",
            "Support k (from 0; NNN - 1 of a namespace ending support_NNN) runs flow.seed, "
            "scenario.seed and sensors.seed plus k times this.",
            0,
            1_000_000,
        ),
    ),
    file="face_host.yaml",
)

REPLAY = Section(
    "replay",
    "bag_replay: which bag, what of it and how fast.",
    (
        text("bag_path", "Bag directory to publish (required)."),
        of_kind("strs", "topics", "Contract topics published."),
        text("namespace", 'Namespace of the bag\'s topics to play ("" = the only one).'),
        number("start_offset_s", "Log time skipped from the first message.", "s", 0.0, 1e9),
        flag("loop", "Start again at the end."),
        number("rate", "Playback speed over the recorded one.", "", 0.01, 100.0),
        flag("publish_clock", "Publish the log time on /clock."),
        WAIT_FOR_SUBSCRIBERS,
        SUBSCRIBER_SETTLE,
        positive("publish_period_s", "Timer period, wall clock.", "s", high=10.0),
        QOS_DEPTH,
    ),
    file="replay.yaml",
)

SEND = Section(
    "send",
    "`tail-beam send` (the command line checks these, naming its options).",
    (
        positive("timeout_s", "How long to wait for sim_node.", "s", high=86400.0),
        positive("truth_timeout_s", "How long --wait-truth waits.", "s", high=86400.0),
    ),
    file="send.yaml",
)

# --- the face: top-coal drawing and the caving windows' closing rules ---------------------------

DRAWING_SEQUENCES = ("single_round", "multi_round", "interval")
MAX_FACE_SUPPORTS = 300  # supports a face may hold (the longest faces hold about 170)

FACE = Section(
    "face",
    "The face's top-coal drawing (tail_beam_sim.physics.face, docs/caving.md).",
    (
        integer("supports", "Supports whose windows are drawn.", 1, MAX_FACE_SUPPORTS),
        positive("support_width_m", "Width of one support along the face.", "m", high=5.0),
        positive(
            "cut_depth_m", "Web of one cut: the slice of top coal one round draws.", "m", high=10.0
        ),
        positive("top_coal_height_m", "Top coal above the openings.", "m", high=50.0),
        positive("cell_size_m", "Side of the drawing model's cells.", "m", 0.01, 2.0),
        number(
            "lateral_step_probability",
            "The climbing void's chance per cell row of stepping sideways (draw body width).",
            "",
            0.0,
            1.0,
        ),
        integer("margin_supports", "Undrawn supports' widths of top coal beyond each end.", 0, 50),
        positive("coal_density_kgpm3", "Bulk density of the broken top coal.", "kg/m^3"),
        positive("gangue_density_kgpm3", "Bulk density of the caved gangue.", "kg/m^3"),
        positive("mass_rate_kgps", "Mass drawn per second through an open window.", "kg/s"),
        number("close_delay_s", "Time a window takes to close, still drawing.", "s", 0.0, 60.0),
        positive(
            "max_window_s", "Longest a window stays open if nothing closes it.", "s", high=1e4
        ),
        positive(
            "share_window_kg", "Drawn mass the instantaneous gangue share is taken over.", "kg"
        ),
        choice("sequence", "Order of the windows within a group.", DRAWING_SEQUENCES),
        integer("group_size", "Supports drawn as one group, groups one after another.", 1),
        integer(
            "rounds", "Rounds of a multi-round sequence (the last closes on the rule).", 1, 10
        ),
        number(
            "round_draw_fraction",
            "Share of a support's top coal mass each early round of multi_round draws.",
            "",
            0.0,
            1.0,
            low_open=True,
        ),
        integer("seed", "Seed of the void's steps and the opening's draw column.", 0),
    ),
    file="face.yaml",
)

CAVING = Section(
    "caving",
    "The windows' closing rules and the offline caving study (docs/caving.md).",
    (
        positive("fixed_time_s", "fixed_time: drawing time per window.", "s", high=1e4),
        number(
            "first_gangue_min_confidence",
            "first_gangue: least confidence of the gangue label that closes.",
            "",
            0.0,
            1.0,
        ),
        integer(
            "last_labels", "share rules: labels the gangue share is counted over (K).", 1, 1000
        ),
        of_kind(
            "floats",
            "share_levels",
            "share rules: one rule per level of the gangue share among the last K labels.",
            low=0.0,
            high=1.0,
            low_open=True,
        ),
        number(
            "sprt_share_low",
            "sprt: gangue share of a window still on coal (H0).",
            "",
            0.0,
            1.0,
            low_open=True,
        ),
        number(
            "sprt_share_high", "sprt: gangue share to close at (H1).", "", "sprt_share_low", 1.0
        ),
        number(
            "sprt_alpha",
            "sprt: chance of closing on coal (false alarm).",
            "",
            0.0,
            0.5,
            low_open=True,
        ),
        number(
            "sprt_beta", "sprt: chance of missing the share (miss).", "", 0.0, 0.5, low_open=True
        ),
        number(
            "estimate_level",
            "share_estimate: level the gangue_share interval's lower bound crosses; "
            "share_alarm: the level of the share's crossing rule.",
            "",
            0.0,
            1.0,
            low_open=True,
        ),
        number(
            "oracle_level",
            "oracle: true instantaneous gangue share the window closes at.",
            "",
            0.0,
            1.0,
            low_open=True,
        ),
        of_kind(
            "floats",
            "oracle_curve_levels",
            "oracle curve (tail-beam caving --oracle-curve): the levels the oracle closes at, "
            "to draw the best recovery each gangue content allows.",
            low=0.0,
            high=1.0,
            low_open=True,
        ),
        integer("seeds", "Seeds of the study (intervals are over them).", 1, 1000),
    ),
    file="face.yaml",
    sections=("labels", "pipeline"),
)

CAVING_LABELS = Section(
    "caving.labels",
    "A stand-in for the identifier in the caving study: labels drawn from the true lumps.",
    (
        positive(
            "impacts_per_tonne", "Lumps striking the tail beam per tonne drawn.", "1/t", high=1e4
        ),
        number("accuracy", "Chance a lump's label is right.", "", 0.5, 1.0),
        number("confidence_right", "Mean confidence of a right label.", "", 0.5, 1.0),
        number("confidence_wrong", "Mean confidence of a wrong label.", "", 0.5, 1.0),
        positive(
            "confidence_concentration", "Beta concentration of the confidences.", "", high=1e4
        ),
        number("latency_s", "From a lump's impact to its label.", "s", 0.0, 60.0),
        positive(
            "share_interval_s", "Length of a gangue_share estimate's interval.", "s", high=600.0
        ),
    ),
    file="face.yaml",
)

CAVING_PIPELINE = Section(
    "caving.pipeline",
    "The caving study's identified sources: the drawn flow through the sensors and the "
    "identifier.",
    (
        choice(
            "lumps",
            "Lumps struck per drawn cell: struck (caving.labels.impacts_per_tonne per tonne, the "
            "truth source's lumps) or drawn (the cell's whole mass as flow-sized lumps).",
            ("struck", "drawn"),
        ),
    ),
    file="face.yaml",
)

PARAMETER_SECTIONS: tuple[Section, ...] = (
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
    FLOW,
    RECORDER,
    FACE_HOST,
    REPLAY,
    SEND,
    FACE,
    CAVING,
    CAVING_LABELS,
    CAVING_PIPELINE,
)
NOT_PARAMETERS = ("impacts.yaml",)  # config/ files that hold a scene list, not parameters


# --- config/ against the tables ------------------------------------------------------------------


def sections_of(modules: Iterable[str] = ()) -> tuple[Section, ...]:
    """This module's sections and the ``PARAMETER_SECTIONS`` of each of ``modules`` (dotted
    module names: another package declares its own sections where it reads them)."""
    found = list(PARAMETER_SECTIONS)
    for name in modules:
        found += [s for s in importlib.import_module(name).PARAMETER_SECTIONS if s not in found]
    return tuple(found)


def _matches(path: str, pattern: str) -> bool:
    """Segment-wise match of a dotted path against a pattern whose segments may hold ``*``."""
    if pattern == "":
        return path == ""
    parts, wanted = path.split("."), pattern.split(".")
    return len(parts) == len(wanted) and all(map(fnmatch.fnmatchcase, parts, wanted))


def section_for(path: str, sections: Iterable[Section] = PARAMETER_SECTIONS) -> Section | None:
    """The section declared for the dotted section ``path`` (``materials.coal``), if any."""
    return next((s for s in sections if _matches(path, s.path)), None)


def shipped_parameters(config_dir: Path | None = None) -> dict[str, dict[str, Any]]:
    """Every parameter file of config/ by name, as read (impacts.yaml left out)."""
    folder = config_dir or default_config_dir()
    return {
        p.name: read_parameter_file(p)
        for p in sorted(folder.glob("*.yaml"))
        if p.name not in NOT_PARAMETERS
    }


def unspecified_keys(
    params: Mapping[str, Any], sections: Iterable[Section] = PARAMETER_SECTIONS
) -> list[str]:
    """Dotted names in ``params`` that none of ``sections`` declares (a ``mapping`` field
    covers the keys under it)."""
    sections = tuple(sections)
    out = []
    for name in flatten(params):
        parts = name.split(".")
        covered = False
        for depth in range(len(parts) - 1):
            section = section_for(".".join(parts[:depth]), sections)
            head = parts[depth]
            if section is not None and head in section and section[head].kind == "mapping":
                covered = True
                break
        section = section_for(".".join(parts[:-1]), sections)
        if not covered and (section is None or parts[-1] not in section):
            out.append(name)
    return out


def _mappings(params: Mapping[str, Any], prefix: str = "") -> Iterator[tuple[str, Mapping]]:
    """Every mapping in ``params`` with its dotted path ("" for ``params`` itself)."""
    yield prefix, params
    for key, value in params.items():
        if isinstance(value, Mapping):
            yield from _mappings(value, f"{prefix}.{key}" if prefix else key)


def missing_keys(
    params: Mapping[str, Any], sections: Iterable[Section] = PARAMETER_SECTIONS
) -> list[str]:
    """Required fields of ``sections`` that ``params`` holds the section of but not the field
    (the top-level section only where ``params`` holds one of its fields)."""
    out = []
    found = list(_mappings(params))
    for section in sections:
        for path, body in found:
            if not _matches(path, section.path):
                continue
            if not path and not any(f.name in body for f in section):
                continue  # the top level of a file that holds other sections only
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
    if isinstance(value, list) and len(value) > 6:
        return f"{len(value)} values"
    return f"`{shorten(value, 40)}`"


def render_reference(
    sections: Iterable[Section] = PARAMETER_SECTIONS,
    command: str = "python -m tail_beam_sim.spec",
    config_dir: Path | None = None,
) -> str:
    """The parameter reference as Markdown: a table per section with each field's unit,
    allowed range, default (config/'s value, else the built-in one) and meaning; the header
    names ``command``, which prints it."""
    files = shipped_parameters(config_dir)
    lines = [
        "# Parameter reference",
        "",
        "Generated from the parameter tables (`tail_beam_sim/spec.py` and the sections each",
        "package declares where it reads them); do not edit by hand. Regenerate with",
        "",
        f"    {command} > docs/parameters.md",
        "",
        "Every parameter is a ROS 2 parameter of the nodes that read its file (`-p name:=value`,",
        "`--params-file`) and is read by the commands from the same files. A range `(a, b]`",
        "excludes a; a bound given by name is that parameter's value. A default is config/'s",
        "value; a parameter config/ leaves out takes the built-in one; `—` means required.",
        "",
    ]
    for section in sections:
        lines += [f"## `{section.path or '(top level)'}`", "", section.meaning, ""]
        if section.file:
            lines += [f"File: `config/{section.file}`.", ""]
        lines += ["| name | unit | range | default | meaning |", "|---|---|---|---|---|"]
        body = _first_instance(files.get(section.file, {}), section.path)
        for spec in section:
            value = body.get(spec.name, spec.default) if body is not None else spec.default
            lines.append(
                f"| `{spec.name}` | {spec.unit} | {spec.range_text()} | {_default_text(value)} "
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
    """Print the parameter reference of this module's sections and those of the modules
    named on the command line (``python -m tail_beam_sim.spec <module> ...``)."""
    modules = list(sys.argv[1:] if argv is None else argv)
    command = " ".join(["python -m tail_beam_sim.spec", *modules])
    try:
        sections = sections_of(modules)
    except (ImportError, AttributeError) as exc:
        print(f"tail_beam_sim.spec: error: {exc}", file=sys.stderr)
        return 2
    sys.stdout.write(render_reference(sections, command))
    return 0


if __name__ == "__main__":
    sys.exit(main())
