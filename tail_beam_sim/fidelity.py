"""Fidelity tiers: how much model a scene gets, and the automatic choice of the cheapest.

Tiers, cheapest first:

* ``impulse``: rigid beam, each contact an instantaneous impulse (closed form);
* ``rigid``: the study's model, rigid beam on the jack, contact resolved (hybrid solver);
* ``modal``: rigid beam plus the bending modes of ``config/modes.yaml``;
* ``brittle``: ``modal`` with the crushing contact for coal (past the study; never chosen
  automatically, only on request: it changes the physics, not the accuracy).

A scene states what it needs (:class:`Needs`: outputs among rebound, contact, pressure, imu,
and a relative tolerance; the sensors' bandwidth comes from their sample rates).
:func:`model_errors` estimates each tier's error against the richest one, cheaply:

* impulse vs rigid: an impulse at the pulse's centroid instead of the pulse changes a mode of
  angular frequency omega by about (omega sigma)^2 / 2 (sigma the pulse's RMS width), and the
  pulse leaves out gravity and the plate's forces during the contact (see solvers/pulse.py);
* rigid vs modal: both structures' responses to the same impulse, sampled as the sensors
  sample them (point pressure samples, period-averaged IMU), compared in relative L2 over the
  window (the worst of four phases of the impulse within a sample period, with a 25 % margin);
  and for the rebound, the change in the plate's effective mass at the contact point.

The errors add up the ladder (the impulse tier errs by its own step plus the rigid one's), and
:func:`plan` picks the first tier within tolerance. :func:`check_against_next` simulates the
next tier up and reports the measured differences.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from tail_beam_sim.config import load_parameters
from tail_beam_sim.contact import damping_factor, hertz_stiffness
from tail_beam_sim.errors import InputError, require_range
from tail_beam_sim.sensors import imu_samples
from tail_beam_sim.solvers.hybrid import DEFAULT_PULSE_TOLERANCE
from tail_beam_sim.solvers.pulse import contact_pulse
from tail_beam_sim.structure import BendingMode, LinearStructure, beam_with_modes, load_bending_modes, rigid_beam
from tail_beam_sim.support import Support

OUTPUTS = ("rebound", "contact", "pressure", "imu")
PHASES = (0.0, 0.25, 0.5, 0.75)  # where, as a fraction of a sample period, an impulse may fall
SAMPLED_MARGIN = 1.25  # the pulse's finite length and the phases between those tried move the measured difference by a few %
WAVEFORM_OUTPUTS = ("pressure", "imu")


@dataclass(frozen=True)
class Tier:
    """One fidelity tier: its structure (with or without bending modes), solver and contact."""

    name: str
    bending_modes: bool
    default_solver: str
    brittle: bool


TIERS: dict[str, Tier] = {
    "impulse": Tier("impulse", False, "impulse", False),
    "rigid": Tier("rigid", False, "hybrid", False),
    "modal": Tier("modal", True, "hybrid", False),
    "brittle": Tier("brittle", True, "hybrid", True),
}
ACCURACY_LADDER = ("impulse", "rigid", "modal")
# The crushing law's kink at yield lowers RK4's order: 48 steps leave up to 3e-4 in the rebound,
# 192 steps under 1e-4 (test_fidelity.py), the bound simulate reports for integrated contacts.
BRITTLE_STEPS_PER_CONTACT = 192
DEFAULT_TIER = "rigid"
TIER_CHOICES = ("auto", *TIERS)


def get_tier(name: str) -> Tier:
    """The tier called ``name``, or InputError listing the tiers."""
    try:
        return TIERS[name]
    except KeyError:
        raise InputError("tier", name, f"must be one of {', '.join(TIER_CHOICES)}") from None


@dataclass(frozen=True)
class Needs:
    """What a scene asks of the simulation: which outputs, to what relative tolerance."""

    outputs: frozenset[str] = frozenset(OUTPUTS)
    tolerance: float = 0.01

    @classmethod
    def of(cls, outputs: Iterable[str], tolerance: float) -> Needs:
        """Validated needs (InputError naming the field)."""
        chosen = frozenset(outputs)
        unknown = sorted(chosen - set(OUTPUTS))
        if unknown or not chosen:
            raise InputError("fidelity.outputs", sorted(chosen), f"must be a non-empty subset of {', '.join(OUTPUTS)}")
        return cls(chosen, require_range("fidelity.tolerance", tolerance, 0.0, 1.0, low_open=True))


@dataclass(frozen=True)
class FidelitySettings:
    """The ``fidelity`` and ``modes`` parameter sections: default tier and needs, bending modes,
    and the confinement factor of the crushing contact (dimensionless)."""

    tier: str
    needs: Needs
    modes: tuple[BendingMode, ...]
    crushing_confinement_factor: float

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> FidelitySettings:
        section = params.get("fidelity") or {}
        if not isinstance(section, Mapping):
            raise InputError("fidelity", section, "must be a parameter section")
        tier = section.get("tier", "auto")
        if tier not in TIER_CHOICES:
            raise InputError("fidelity.tier", tier, f"must be one of {', '.join(TIER_CHOICES)}")
        return cls(
            tier=tier,
            needs=Needs.of(section.get("outputs", OUTPUTS), section.get("tolerance", 0.01)),
            modes=load_bending_modes(params),
            crushing_confinement_factor=require_range(
                "fidelity.crushing_confinement_factor", section.get("crushing_confinement_factor", 3.0), 0.0, 100.0, low_open=True
            ),
        )


@lru_cache(maxsize=1)
def shipped_settings() -> FidelitySettings:
    """The settings of the shipped config/ files (read once)."""
    return FidelitySettings.from_params(load_parameters())


_STRUCTURES: dict[tuple[Support, int, bool], tuple[Sequence[BendingMode], LinearStructure]] = {}
STRUCTURE_CACHE_SIZE = 64


def structure_for(tier: Tier, support: Support, modes: Sequence[BendingMode]) -> LinearStructure:
    """The linear structure ``tier`` uses on ``support`` (built once per support and mode set:
    its eigen-decomposition is the costly part)."""
    key = (support, id(modes), tier.bending_modes)
    cached = _STRUCTURES.get(key)
    if cached is not None and cached[0] is modes:
        return cached[1]
    structure = beam_with_modes(support, modes) if tier.bending_modes else rigid_beam(support)
    if len(_STRUCTURES) >= STRUCTURE_CACHE_SIZE:
        _STRUCTURES.clear()
    _STRUCTURES[key] = (modes, structure)  # holding ``modes`` keeps its id from being reused
    return structure


@dataclass
class Plan:
    """The tier and solver chosen for a scene, with every tier's estimated model error."""

    tier: Tier
    solver: str
    solver_options: dict[str, Any]
    model_error: float
    estimates: dict[str, float] = field(default_factory=dict)


def plan(scene: Any, tier: str, needs: Needs, settings: FidelitySettings) -> Plan:
    """Choose (``tier='auto'``) or take the tier, its solver and options, with error estimates."""
    estimates = model_errors(scene, needs, settings.modes)
    if tier == "auto":
        name = next((t for t in ACCURACY_LADDER if estimates[t] <= needs.tolerance), ACCURACY_LADDER[-1])
    else:
        name = get_tier(tier).name
    chosen = TIERS[name]
    options: dict[str, Any] = {}
    if chosen.brittle:
        options["steps_per_contact"] = BRITTLE_STEPS_PER_CONTACT
    elif chosen.default_solver == "hybrid":
        options["pulse_tolerance"] = min(DEFAULT_PULSE_TOLERANCE, needs.tolerance)
    return Plan(chosen, chosen.default_solver, options, estimates.get(name, 0.0), estimates)


def model_errors(scene: Any, needs: Needs, modes: Sequence[BendingMode]) -> dict[str, float]:
    """Estimated relative error of each tier of the accuracy ladder against the richest (module docstring)."""
    support, impact = scene.support, scene.impact
    rigid = structure_for(TIERS["rigid"], support, modes)
    modal = structure_for(TIERS["modal"], support, modes)
    shape_rigid = rigid.contact_shape(impact.position_m)
    shape_modal = modal.contact_shape(impact.position_m)
    m_rigid = 1.0 / float(shape_rigid @ rigid.inv_mass @ shape_rigid)
    m_modal = 1.0 / float(shape_modal @ modal.inv_mass @ shape_modal)
    mass = impact.mass_kg
    reduced = mass * m_rigid / (mass + m_rigid)
    chi = damping_factor(scene.contact_model, impact.restitution)
    stiffness = hertz_stiffness(impact.material, support.plate, impact.radius_m)
    pulse = contact_pulse(min(chi, 40.0), stiffness, reduced, impact.impact_speed_mps)
    width = pulse.width_s
    duration = pulse.duration_s
    gravity = support.gravity_mps2 * duration / impact.impact_speed_mps
    waveform = needs.outputs & set(WAVEFORM_OUTPUTS)
    omega_rigid = 2 * math.pi * float(rigid.natural_frequencies_hz().max())
    impulse_step = max(gravity, (omega_rigid * width) ** 2 / 2 if waveform else 0.0)
    restitution = max(pulse.separation_mps / impact.impact_speed_mps, 1e-3)
    rebound_step = (1 + restitution) / restitution * abs(mass / (mass + m_modal) - mass / (mass + m_rigid))
    rigid_step = rebound_step if needs.outputs & {"rebound", "contact"} else 0.0
    if waveform and modes:
        rigid_step = max(rigid_step, SAMPLED_MARGIN * _sampled_difference(scene, rigid, modal, waveform))
    return {"impulse": impulse_step + rigid_step, "rigid": rigid_step, "modal": 0.0, "brittle": 0.0}


def _sampled_difference(scene: Any, rigid: LinearStructure, modal: LinearStructure, outputs: set[str]) -> float:
    """Relative L2 difference of the two structures' impulse responses as the sensors sample them,
    the worst over where the impulse falls within a sample period (PHASES, evaluated together)."""
    spec, x = scene.sensors, scene.impact.position_m
    worst = 0.0
    for output in outputs:
        rate = spec.pressure_rate_hz if output == "pressure" else spec.imu_rate_hz
        count = int(scene.window_s * rate)
        times = ((np.arange(1, count + 1)[None, :] - np.array(PHASES)[:, None]) / rate).ravel()  # (phases x samples)
        signals = []
        for structure in (rigid, modal):
            qd0 = structure.inv_mass @ structure.contact_shape(x)
            zero = np.zeros(structure.size)
            q, qd = structure.propagate(zero, qd0, times)
            if output == "pressure":
                signals.append(structure.pressure_pa(q, qd) - structure.setting_pressure_pa)
            else:
                early = times < 1.0 / rate  # the beam is at rest before the impulse
                before_q, before_qd = structure.propagate(zero, qd0, np.maximum(times - 1.0 / rate, 0.0))
                before_q[:, early], before_qd[:, early] = 0.0, 0.0
                signals.append(np.stack([structure.imu_shape @ (qd - before_qd), structure.imu_slope_shape @ (q - before_q)]) * rate)
        lower, upper = (signal.reshape(-1, len(PHASES), count) for signal in signals)
        reference = np.sqrt((upper**2).sum(axis=(0, 2)))
        difference = np.sqrt(((upper - lower) ** 2).sum(axis=(0, 2)))
        worst = max(worst, float(np.max(np.where(reference > 0, difference / np.where(reference > 0, reference, 1.0), 0.0))))
    return worst


def next_tier_up(name: str) -> str | None:
    """The tier above ``name`` on the accuracy ladder (None at the top)."""
    if name in ACCURACY_LADDER[:-1]:
        return ACCURACY_LADDER[ACCURACY_LADDER.index(name) + 1]
    return None


def sensor_view(result: Any) -> dict[str, np.ndarray]:
    """Noise-free pressure change (Pa) and dynamic IMU readings (m/s^2, rad/s) at the streams'
    stamps, sampled as the sensors sample them (IMU averaged over its period)."""
    trajectory, start = result.trajectory, result.contact_stamp_s
    structure = trajectory.problem.structure
    state = trajectory.sample(result.pressure.stamp_s - start)
    gyro, accel = imu_samples(trajectory, result.imu.stamp_s - start, 1.0 / result.scene.sensors.imu_rate_hz)
    return {
        "pressure": structure.pressure_pa(state.q, state.qd) - structure.setting_pressure_pa,
        "imu": np.concatenate([accel[:, 0], accel[:, 2] - structure.gravity_mps2, gyro[:, 1]]),
    }


def compare(lower: Any, upper: Any, outputs: Iterable[str]) -> dict[str, float]:
    """Measured relative differences between two simulations of one scene, per requested output.

    rebound: rebound speed; contact: peak contact force and duration; pressure: peak jack
    pressure change and the sampled pressure stream (relative L2); imu: the sampled IMU
    stream (relative L2). Streams are noise-free, at the sensors' stamps.
    """
    a, b = lower.summary, upper.summary

    def rel(x: float, y: float) -> float:
        return abs(x - y) / abs(y) if y else abs(x - y)

    chosen = set(outputs)
    out: dict[str, float] = {}
    if "rebound" in chosen:
        out["rebound"] = rel(a["rebound_speed_mps"], b["rebound_speed_mps"])
    if "contact" in chosen:
        out["contact_peak_force"] = rel(a["peak_contact_force_n"], b["peak_contact_force_n"])
        out["contact_duration"] = rel(a["contact_duration_s"], b["contact_duration_s"])
    if chosen & set(WAVEFORM_OUTPUTS):
        view_a, view_b = sensor_view(lower), sensor_view(upper)
        if "pressure" in chosen:
            out["peak_pressure_change"] = rel(a["peak_jack_pressure_change_pa"], b["peak_jack_pressure_change_pa"])
        for key in chosen & set(WAVEFORM_OUTPUTS):
            norm = float(np.linalg.norm(view_b[key]))
            out[f"{key}_stream"] = float(np.linalg.norm(view_a[key] - view_b[key])) / norm if norm else 0.0
    return out
