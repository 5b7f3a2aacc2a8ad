"""Supports other than the nominal one: draws of plausible tail beams and their sensors.

Every real support differs from ``config/`` (beam section, wear plate, jack, oil, how and where
the IMU is bolted, what the sensors sample at), so the identification methods are trained on
supports drawn from wide ranges and judged on supports drawn from wider ones (the ``foreign``
scene set), never on the nominal one alone. A draw scales or replaces the parameters of the
merged parameter dict; ranges live in ``identification.evaluation.supports``
(config/identification.yaml):

- ``inertia_scale``, ``jack_stiffness_scale``, ``jack_damping_scale``: factors on the nominal
  beam inertia about the hinge, the oil's bulk modulus (the jack's stiffness) and its damping;
- ``bending_1_frequency_hz`` (log-uniform) and ``damping_ratio``: the first bending mode (the
  higher ones keep their nominal ratio to it) and every mode's damping;
- ``imu_from_hinge_m``: where the IMU is bolted;
- ``imu_rate_hz``, ``pressure_rate_hz``, ``camera_frame_rate_hz`` (log-uniform) and
  ``noise_factor`` (log-uniform, x every nominal noise RMS);
- ``contact_models``: the hysteresis laws a particle may follow;
- ``contact_damping_scale`` (optional, log-uniform): a factor on the law's hysteresis factor chi
  (``support.contact_damping_scale``), so that a support's hysteresis may lie between and beyond
  the published laws; drawn after everything else and only when the ranges name it, so that
  ranges without it draw every support as before;
- ``vibration_share`` and ``vibration_rate_hz`` (log-uniform): whether the support has the
  tail-beam accelerometer (topic ``vibration``) and at what rate; ``vibration_rate_hz`` is 0 in
  a draw without it (the IMU alone is then the acceleration channel). Drawn from a generator of
  its own (:func:`draw_support`), so adding it left every other draw of a seed unchanged;
- ``exact_camera_share`` (optional, 0..1): the share of supports whose camera stamps the
  contact's end itself (EXACT_CAMERA_RATE_HZ in place of the drawn frame rate), drawn last.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.structure import euler_bernoulli_modes

SCALED = {
    "inertia_scale": ("support", "beam_inertia_about_hinge_kgm2"),
    "jack_stiffness_scale": ("support", "oil_bulk_modulus_pa"),
    "jack_damping_scale": ("support", "jack_damping_nspm"),
}
# The parameter sections SupportDraw.apply changes: its copy of the parameters owns them.
APPLIED_SECTIONS = ("sensors", "scene", "support", "modes")
NOISE_FIELDS = (
    "pressure_noise_pa",
    "imu_accel_noise_mps2",
    "imu_gyro_noise_radps",
    "camera_velocity_noise_mps",
    "camera_velocity_noise_fraction",
    "vibration_noise_density_mps2_rthz",
)
LOG_UNIFORM = {
    "bending_1_frequency_hz",
    "imu_rate_hz",
    "pressure_rate_hz",
    "camera_frame_rate_hz",
    "noise_factor",
    "vibration_rate_hz",
    "contact_damping_scale",
}
RANGES = (
    *SCALED,
    "bending_1_frequency_hz",
    "damping_ratio",
    "imu_from_hinge_m",
    "imu_rate_hz",
    "pressure_rate_hz",
    "camera_frame_rate_hz",
    "noise_factor",
    "vibration_rate_hz",
)
OPTIONAL_RANGES = ("contact_damping_scale",)  # drawn (log-uniform) only when the ranges name them
# A drawn structure's ranges (the ``structure`` mapping): name -> log-uniform?
STRUCTURE_RANGES = {
    "held_at_m": False,  # where the beam is held (the jack pin), m from the hinge
    "inner_stiffness": True,  # x the nominal bending stiffness, hinge to the held point
    "inner_mass": True,  # x the nominal mass per length, there
    "outer_stiffness": True,  # ... beyond the held point
    "outer_mass": True,
    "tip_mass_kg": False,  # a point mass at the tip (a wear plate's edge, a lip), kg
    "modal_mass_kg": True,  # the first mode's modal mass (peak-normalised shape), kg
}
# The frame rate (Hz) of a camera that stamps the contact's end itself (``exact_camera_share``
# of the drawn supports, where the ranges name it): its 1 us frames lie on no grid the
# identifier reads (tail_beam_id.signals.camera.GRIDLESS_PERIOD_S), as a camera's that
# interpolates the separation between frames; the fastest rate a sensor may have.
EXACT_CAMERA_RATE_HZ = 1e6
STRUCTURE_ELEMENTS = 32  # finite elements of a drawn beam (nodes every 0.05 m on 1.6 m)
MAX_MODES = 4  # bending modes a drawn structure keeps (those below max_mode_frequency_hz)
STRUCTURE_TRIES = 200  # draws of a structure before the one nearest mode_ratio is kept
MAX_COUPLED_SHARE = 0.8  # the most of the beam's inertia the modes' mass couplings may take


@dataclass(frozen=True)
class SupportDraw:
    """One drawn support and sensor layout: the values drawn (units in their names;
    ``vibration_rate_hz`` 0 or absent = no accelerometer) and the contact law of the particle
    that strikes it."""

    values: dict[str, float]
    contact_model: str

    @property
    def vibration_rate_hz(self) -> float:
        """The accelerometer's rate, Hz; 0 when the support has none."""
        return float(self.values.get("vibration_rate_hz", 0.0))

    def apply(self, params: Mapping[str, Any]) -> dict[str, Any]:
        """A copy of the merged parameters describing this support, its sensors (rates, every
        noise RMS scaled by ``noise_factor``) and the particles' contact law. The sections it
        changes (APPLIED_SECTIONS) are copied deeply; the others are shared with ``params``,
        read-only like it (copying every section cost more than simulating the impact)."""
        varied = dict(params)
        for section in APPLIED_SECTIONS:
            if section in params:
                varied[section] = copy.deepcopy(params[section])
        for name in NOISE_FIELDS:
            varied["sensors"][name] = float(params["sensors"][name]) * self.values["noise_factor"]
        varied.setdefault("scene", {})["contact_model"] = self.contact_model
        for key, (section, name) in SCALED.items():
            varied[section][name] = float(params[section][name]) * self.values[key]
        varied["support"]["imu_from_hinge_m"] = self.values["imu_from_hinge_m"]
        if "contact_damping_scale" in self.values:
            varied["support"]["contact_damping_scale"] = self.values["contact_damping_scale"]
        modes = varied["modes"]
        names = sorted(
            (k for k in modes if k.startswith("bending_")), key=lambda k: int(k.split("_")[1])
        )
        if "structure_held_at_m" in self.values:
            support = varied["support"]
            lever_m = float(support["jack_pin_from_hinge_m"]) * math.sin(
                math.radians(float(support["jack_angle_to_beam_deg"]))
            )
            held_m = self.values["structure_held_at_m"]
            support["jack_pin_from_hinge_m"] = held_m
            support["jack_angle_to_beam_deg"] = math.degrees(math.asin(min(lever_m / held_m, 1.0)))
            varied["modes"] = structure_modes(self.values, params["modes"], support)
            names = []
        if names:
            ratio = self.values["bending_1_frequency_hz"] / float(modes[names[0]]["frequency_hz"])
            for name in names:
                # A lighter or heavier beam of the same mass distribution: its modal masses and
                # couplings scale with its inertia (so the mass matrix stays positive).
                mode = modes[name]
                mode["frequency_hz"] = float(mode["frequency_hz"]) * ratio
                mode["damping_ratio"] = self.values["damping_ratio"]
                mode["modal_mass_kg"] = float(mode["modal_mass_kg"]) * self.values["inertia_scale"]
                mode["rigid_coupling_kgm"] = (
                    float(mode["rigid_coupling_kgm"]) * self.values["inertia_scale"]
                )
        for rate in ("imu_rate_hz", "pressure_rate_hz", "camera_frame_rate_hz"):
            varied["sensors"][rate] = self.values[rate]
        if self.vibration_rate_hz > 0.0:
            varied["sensors"]["vibration_rate_hz"] = self.vibration_rate_hz
        return varied

    @property
    def mode_frequencies_hz(self) -> tuple[float, ...]:
        """A drawn structure's bending modes as held at the jack pin, Hz (empty otherwise)."""
        count = int(self.values.get("structure_modes", 0))
        return tuple(self.values[f"structure_mode_{k + 1}_hz"] for k in range(count))

    def with_sensors(
        self, rates_hz: Mapping[str, float], vibration_rate_hz: float, noise_factor: float
    ) -> SupportDraw:
        """The same support and contact law with other sensors: ``rates_hz`` (pressure, IMU and
        camera rates, Hz), the accelerometer's rate (Hz, 0 = none) and the noise factor."""
        values = {
            **self.values,
            **{k: float(v) for k, v in rates_hz.items()},
            "vibration_rate_hz": float(vibration_rate_hz),
            "noise_factor": float(noise_factor),
        }
        return SupportDraw(values, self.contact_model)

    def describe(self) -> str:
        v = self.values
        return (
            f"inertia x{v['inertia_scale']:.2f}, jack x{v['jack_stiffness_scale']:.2f}, mode 1 "
            f"{v['bending_1_frequency_hz']:.0f} Hz "
            f"zeta {100 * v['damping_ratio']:.1f} %, IMU {v['imu_rate_hz'] / 1e3:.1f} kHz at "
            f"{v['imu_from_hinge_m']:.2f} m, "
            f"noise x{v['noise_factor']:.2f}, "
            + (
                f"accelerometer {self.vibration_rate_hz / 1e3:.1f} kHz, "
                if self.vibration_rate_hz > 0
                else "no accelerometer, "
            )
            + (
                f"structure held at {v['structure_held_at_m']:.2f} m, modes "
                f"{'/'.join(f'{f:.0f}' for f in self.mode_frequencies_hz)} Hz, "
                if "structure_held_at_m" in v
                else ""
            )
            + f"{self.contact_model}"
            + (f" x{v['contact_damping_scale']:.2f}" if "contact_damping_scale" in v else "")
        )


def tabulated_modes(
    modes: Mapping[str, Any], table: Sequence[tuple[float, float]], damping_ratio: float = 0.02
) -> dict[str, Any]:
    """A ``modes`` parameter section with the bending modes of ``table`` ((frequency Hz, modal
    mass kg) each, lowest first): the k-th takes the k-th shape of ``modes`` (cycling when
    there are fewer) and no mass coupling with the rigid rotation, so that each mode rings at
    its own frequency (a support measured mode by mode, as a modal test reports it)."""
    names = sorted(
        (k for k in modes if k.startswith("bending_")), key=lambda k: int(k.split("_")[1])
    )
    if not names:
        raise InputError("modes", None, "needs at least one bending_N mode for its shape")
    section: dict[str, Any] = {
        "count": len(table),
        "stations_m": list(modes["stations_m"]),
    }
    for k, (frequency_hz, mass_kg) in enumerate(table):
        shape = modes[names[k % len(names)]]
        section[f"bending_{k + 1}"] = {
            "frequency_hz": float(frequency_hz),
            "damping_ratio": float(damping_ratio),
            "modal_mass_kg": float(mass_kg),
            "rigid_coupling_kgm": 0.0,
            "shape": list(shape["shape"]),
            "slope_radpm": list(shape["slope_radpm"]),
        }
    return section


def support_ranges(evaluation: Mapping[str, Any], which: str) -> Mapping[str, Any]:
    """The ``supports.<which>`` ranges (training or foreign), checked."""
    supports = evaluation.get("supports")
    if not isinstance(supports, Mapping) or not isinstance(supports.get(which), Mapping):
        raise InputError(
            f"identification.evaluation.supports.{which}",
            None,
            "missing parameter section (config/identification.yaml)",
        )
    ranges = supports[which]
    where = f"identification.evaluation.supports.{which}"
    for name in (*RANGES, *(n for n in OPTIONAL_RANGES if n in ranges)):
        _check_pair(ranges.get(name), f"{where}.{name}")
    if "structure" in ranges:
        structure = ranges["structure"]
        if not isinstance(structure, Mapping):
            raise InputError(f"{where}.structure", structure, "must be a parameter section")
        for name in (*STRUCTURE_RANGES, "mode_ratio"):
            _check_pair(
                structure.get(name), f"{where}.structure.{name}", zero=name == "tip_mass_kg"
            )
        top = structure.get("max_mode_frequency_hz")
        if isinstance(top, bool) or not isinstance(top, (int, float)) or not top > 0:
            raise InputError(
                f"{where}.structure.max_mode_frequency_hz", top, "must be a frequency > 0 Hz"
            )
    for name in (
        "vibration_share",
        *(n for n in ("structure_share", "exact_camera_share") if n in ranges),
    ):
        share = ranges.get(name)
        if (
            isinstance(share, bool)
            or not isinstance(share, (int, float))
            or not 0.0 <= share <= 1.0
        ):
            raise InputError(
                f"identification.evaluation.supports.{which}.{name}",
                share,
                "must be a fraction in [0, 1]",
            )
    laws = ranges.get("contact_models")
    if not isinstance(laws, (list, tuple)) or not laws:
        raise InputError(
            f"identification.evaluation.supports.{which}.contact_models",
            laws,
            "must be a non-empty list of contact laws",
        )
    return ranges


def _check_pair(pair: Any, field: str, zero: bool = False) -> None:
    """A [low, high] range: numbers, 0 < low <= high (0 <= low with ``zero``)."""
    if not (
        isinstance(pair, (list, tuple))
        and len(pair) == 2
        and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in pair)
        and (0 <= pair[0] if zero else 0 < pair[0])
        and pair[0] <= pair[1]
    ):
        raise InputError(
            field, pair, f"must be [low, high] with {'0 <=' if zero else '0 <'} low <= high"
        )


def draw_support(
    ranges: Mapping[str, Any],
    rng: np.random.Generator,
    vibration_rng: np.random.Generator | None = None,
    modes: Mapping[str, Any] | None = None,
) -> SupportDraw:
    """One support from ``ranges`` (uniform, or log-uniform for frequencies, rates and noise).
    The accelerometer (present with probability ``vibration_share``, and its rate) is drawn from
    ``vibration_rng`` (default ``rng``), so a caller that gives it a generator of its own draws
    every other value as it did before the accelerometer was drawn. ``modes``: the nominal
    ``modes`` section, which ranges with a ``structure`` need (:func:`draw_structure`); with a
    ``structure_share`` as well, only that fraction of the supports has a drawn structure, the
    rest the nominal modes rescaled."""
    values = {}
    for name in RANGES:
        if name == "vibration_rate_hz":
            continue
        values[name] = _draw(ranges[name], name, rng)
    laws = list(ranges["contact_models"])
    draw_law = str(laws[int(rng.integers(len(laws)))])
    vib = rng if vibration_rng is None else vibration_rng
    present = vib.uniform() < float(ranges["vibration_share"])
    rate = _draw(ranges["vibration_rate_hz"], "vibration_rate_hz", vib)
    values["vibration_rate_hz"] = rate if present else 0.0
    for name in OPTIONAL_RANGES:
        if name in ranges:
            values[name] = _draw(ranges[name], name, rng)
    if "structure" in ranges and (
        "structure_share" not in ranges or rng.uniform() < float(ranges["structure_share"])
    ):
        if modes is None:
            raise InputError(
                "modes.derived_from", None, "a drawn structure needs the nominal beam"
            )
        values.update(draw_structure(ranges["structure"], values, rng, modes))
    if "exact_camera_share" in ranges and rng.uniform() < float(ranges["exact_camera_share"]):
        # Drawn last and only where named, so naming it leaves every other draw of a seed the same.
        values["camera_frame_rate_hz"] = EXACT_CAMERA_RATE_HZ
    return SupportDraw(values, draw_law)


def _draw(pair: Any, name: str, rng: np.random.Generator) -> float:
    low, high = (float(x) for x in pair)
    return (
        float(math.exp(rng.uniform(math.log(low), math.log(high))))
        if name in LOG_UNIFORM
        else float(rng.uniform(low, high))
    )


def _beam_modes(values: Mapping[str, float], modes: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The bending modes (euler_bernoulli_modes) of the beam ``values`` describe, before the
    scaling to the drawn first frequency and modal mass: the nominal beam (``modes.derived_from``)
    held at the hinge and ``structure_held_at_m``, its sections scaled inside and outside that
    point, a tip mass."""
    beam = modes["derived_from"]
    length_m = float(beam["beam_length_m"])
    held_m = values["structure_held_at_m"]
    middle = (np.arange(STRUCTURE_ELEMENTS) + 0.5) * length_m / STRUCTURE_ELEMENTS
    inside = middle < held_m
    return euler_bernoulli_modes(
        length_m,
        [0.0, held_m],
        float(beam["bending_stiffness_nm2"]),
        float(beam["mass_per_length_kgpm"]),
        MAX_MODES,
        STRUCTURE_ELEMENTS,
        element_stiffness_scale=np.where(
            inside, values["structure_inner_stiffness"], values["structure_outer_stiffness"]
        ),
        element_mass_scale=np.where(
            inside, values["structure_inner_mass"], values["structure_outer_mass"]
        ),
        tip_mass_kg=values["structure_tip_mass_kg"],
    )


def draw_structure(
    ranges: Mapping[str, Any],
    values: Mapping[str, float],
    rng: np.random.Generator,
    nominal: Mapping[str, Any],
) -> dict[str, float]:
    """A beam's structure (STRUCTURE_RANGES, ``structure_<name>`` in the result) whose second
    bending mode lies within ``mode_ratio`` times its first (the nearest of STRUCTURE_TRIES
    draws otherwise), and its modes' frequencies once scaled so that the first is
    ``values['bending_1_frequency_hz']`` (``structure_mode_<k>_hz``, those below
    ``max_mode_frequency_hz``: ``structure_modes`` of them, at least one). ``nominal``: the
    ``modes`` section whose ``derived_from`` beam the sections scale."""
    low, high = (float(x) for x in ranges["mode_ratio"])
    best: tuple[float, dict[str, float], list[dict[str, Any]]] | None = None
    for _ in range(STRUCTURE_TRIES):
        drawn = {}
        for name, log in STRUCTURE_RANGES.items():
            a, b = (float(x) for x in ranges[name])
            if name == "held_at_m":  # on a node of the beam's elements
                step = float(nominal["derived_from"]["beam_length_m"]) / STRUCTURE_ELEMENTS
                drawn["structure_" + name] = step * round(float(rng.uniform(a, b)) / step)
            else:
                drawn["structure_" + name] = (
                    float(math.exp(rng.uniform(math.log(a), math.log(b))))
                    if log
                    else float(rng.uniform(a, b))
                )
        found = _beam_modes(drawn, nominal)
        ratio = found[1]["frequency_hz"] / found[0]["frequency_hz"]
        miss = max(low - ratio, ratio - high, 0.0)
        if best is None or miss < best[0]:
            best = (miss, drawn, found)
        if miss == 0.0:
            break
    assert best is not None
    _, drawn, found = best
    scale = values["bending_1_frequency_hz"] / found[0]["frequency_hz"]
    below = [m["frequency_hz"] * scale for m in found]
    kept = [f for f in below if f < float(ranges["max_mode_frequency_hz"])] or below[:1]
    return {
        **drawn,
        "structure_modes": float(len(kept)),
        **{f"structure_mode_{k + 1}_hz": f for k, f in enumerate(kept)},
    }


def structure_modes(
    values: Mapping[str, float], modes: Mapping[str, Any], support: Mapping[str, Any]
) -> dict[str, Any]:
    """The ``modes`` parameter section of a drawn structure (:func:`draw_structure`): its
    beam's modes (``modes.derived_from`` with the drawn sections), the mass scaled so that the
    first mode's modal mass is the drawn one and the stiffness so that its frequency is, each
    mode damped ``damping_ratio``. The mass couplings with the rigid rotation come with the
    beam's mass; where they would take more than MAX_COUPLED_SHARE of the support's inertia
    about the hinge (``support``; the rest of the beam's inertia sits at the hinge lugs) they
    are scaled down to it, so that the mass matrix stays positive."""
    found = _beam_modes(values, modes)
    mass_scale = values["structure_modal_mass_kg"] / found[0]["modal_mass_kg"]
    count = int(values["structure_modes"])
    couplings = np.array([m["rigid_coupling_kgm"] * mass_scale for m in found[:count]])
    masses = np.array([m["modal_mass_kg"] * mass_scale for m in found[:count]])
    inertia = float(support["beam_inertia_about_hinge_kgm2"])
    share = float(np.sum(couplings**2 / masses)) / inertia
    if share > MAX_COUPLED_SHARE:
        couplings *= math.sqrt(MAX_COUPLED_SHARE / share)
    section: dict[str, Any] = {
        "count": count,
        "stations_m": [float(x) for x in found[0]["stations_m"]],
        "derived_from": dict(modes["derived_from"]),
    }
    for k in range(count):
        section[f"bending_{k + 1}"] = {
            "frequency_hz": values[f"structure_mode_{k + 1}_hz"],
            "damping_ratio": values["damping_ratio"],
            "modal_mass_kg": float(masses[k]),
            "rigid_coupling_kgm": float(couplings[k]),
            "shape": [float(x) for x in found[k]["shape"]],
            "slope_radpm": [float(x) for x in found[k]["slope_radpm"]],
        }
    return section
