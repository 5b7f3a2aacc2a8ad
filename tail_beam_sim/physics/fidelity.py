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
:func:`plan` picks the first tier within tolerance, with its structure, solver and options and
the tier to check it against (the next one up; ``tail_beam_sim.physics.compare`` measures the
differences). This is the first step of ``simulate``: plan, build, solve, sensors, compare.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from tail_beam_sim.config import load_parameters
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.contact import damping_factor, hertz_stiffness
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.solvers.hybrid import DEFAULT_PULSE_TOLERANCE
from tail_beam_sim.physics.solvers.pulse import contact_pulse, pulse_table
from tail_beam_sim.physics.structure import (
    BendingMode,
    LinearStructure,
    beam_with_modes,
    load_bending_modes,
    reduced_mass_kg,
    rigid_beam,
)
from tail_beam_sim.physics.support import Support, support_indices
from tail_beam_sim.spec import FIDELITY

OUTPUTS = ("rebound", "contact", "pressure", "imu")
PHASES = (0.0, 0.25, 0.5, 0.75)  # where, as a fraction of a sample period, an impulse may fall
# The pulse's finite length and the phases between those tried move the measured difference
# by a few %.
SAMPLED_MARGIN = 1.25
WAVEFORM_OUTPUTS = ("pressure", "imu")


# The crushing law's kink at yield lowers RK4's order: 48 steps leave up to 3e-4 in the rebound,
# 192 steps under 1e-4 (test_fidelity.py), the bound the hybrid reports for integrated contacts.
BRITTLE_STEPS_PER_CONTACT = 192


@dataclass(frozen=True)
class Tier:
    """One fidelity tier: its structure (with or without bending modes), contact, solver and
    the solver's options: fixed ones, and the option (if any) through which the solver takes
    the relative tolerance the scene needs (capped at ``tolerance_cap``)."""

    name: str
    bending_modes: bool
    default_solver: str
    brittle: bool
    fixed_options: tuple[tuple[str, Any], ...] = ()
    tolerance_option: str | None = None
    tolerance_cap: float = math.inf

    def solver_options(self, needs: Needs) -> dict[str, Any]:
        """The options this tier gives its solver for ``needs``."""
        options = dict(self.fixed_options)
        if self.tolerance_option is not None:
            options[self.tolerance_option] = min(self.tolerance_cap, needs.tolerance)
        return options


_PULSE_TOLERANCE = {
    "tolerance_option": "pulse_tolerance",
    "tolerance_cap": DEFAULT_PULSE_TOLERANCE,
}
TIERS: dict[str, Tier] = {
    "impulse": Tier("impulse", False, "impulse", False),
    "rigid": Tier("rigid", False, "hybrid", False, **_PULSE_TOLERANCE),
    "modal": Tier("modal", True, "hybrid", False, **_PULSE_TOLERANCE),
    "brittle": Tier(
        "brittle",
        True,
        "hybrid",
        True,
        fixed_options=(("steps_per_contact", BRITTLE_STEPS_PER_CONTACT),),
    ),
}
ACCURACY_LADDER = ("impulse", "rigid", "modal")
EXACT_TIERS = ("modal", "brittle")  # model error 0 by definition: the estimates' reference
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
            raise InputError(
                "fidelity.outputs",
                sorted(chosen),
                f"must be a non-empty subset of {', '.join(OUTPUTS)}",
            )
        return cls(
            chosen, FIDELITY.check({"tolerance": tolerance}, only=("tolerance",))["tolerance"]
        )


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
        values = FIDELITY.check(params.get("fidelity"))
        return cls(
            tier=values["tier"],
            needs=Needs.of(values["outputs"], values["tolerance"]),
            modes=load_bending_modes(params),
            crushing_confinement_factor=values["crushing_confinement_factor"],
        )


@lru_cache(maxsize=1)
def shipped_settings() -> FidelitySettings:
    """The settings of the shipped config/ files (read once)."""
    return FidelitySettings.from_params(load_parameters())


_STRUCTURES: dict[tuple[Support, int, bool], tuple[Sequence[BendingMode], LinearStructure]] = {}
_RECENT: dict[tuple[int, int, bool], tuple[Support, Sequence[BendingMode], LinearStructure]] = {}
STRUCTURE_CACHE_SIZE = 64


def structure_for(tier: Tier, support: Support, modes: Sequence[BendingMode]) -> LinearStructure:
    """The linear structure ``tier`` uses on ``support`` (built once per support and mode set:
    its eigen-decomposition is the costly part)."""
    # the same support object as a recent call: found by identity, without hashing its fields
    recent = _RECENT.get((id(support), id(modes), tier.bending_modes))
    if recent is not None and recent[0] is support and recent[1] is modes:
        return recent[2]
    key = (support, id(modes), tier.bending_modes)
    cached = _STRUCTURES.get(key)
    if cached is None or cached[0] is not modes:
        cached = _build_structure(key, tier, support, modes)
    if len(_RECENT) >= STRUCTURE_CACHE_SIZE:
        _RECENT.clear()
    # holding ``support`` and ``modes`` keeps their ids from being reused
    _RECENT[(id(support), id(modes), tier.bending_modes)] = (support, modes, cached[1])
    return cached[1]


def _build_structure(
    key: tuple[Support, int, bool], tier: Tier, support: Support, modes: Sequence[BendingMode]
) -> tuple[Sequence[BendingMode], LinearStructure]:
    """The structure of ``tier`` on ``support``, kept under ``key`` with its ``modes``."""
    structure = beam_with_modes(support, modes) if tier.bending_modes else rigid_beam(support)
    if len(_STRUCTURES) >= STRUCTURE_CACHE_SIZE:
        _STRUCTURES.clear()
    cached = _STRUCTURES[key] = (modes, structure)  # holding ``modes`` keeps its id
    return cached


@dataclass
class Plan:
    """The tier chosen for a scene: its structure, solver and options, its estimated model error
    (and every tier's, except for a tier of EXACT_TIERS asked by name, which has only its own),
    and the tier above it to check it against (None at the top)."""

    tier: Tier
    structure: LinearStructure
    solver: str
    solver_options: dict[str, Any]
    model_error: float
    estimates: dict[str, float] = field(default_factory=dict)
    check_against: str | None = None


def plan(scene: Scene, tier: str, needs: Needs, settings: FidelitySettings) -> Plan:
    """Choose (``tier='auto'``) or take the tier, with its structure, solver and options and the
    error estimates."""
    name = tier if tier == "auto" else get_tier(tier).name
    # the richest tiers are the reference of the estimates (no model error of their own): the
    # ladder's estimates are not needed for them
    estimates = {name: 0.0} if name in EXACT_TIERS else model_errors(scene, needs, settings.modes)
    return _plan_of(scene, name, estimates, needs, settings)


def _plan_of(
    scene: Scene,
    name: str,
    estimates: dict[str, float],
    needs: Needs,
    settings: FidelitySettings,
) -> Plan:
    """The plan of ``scene`` for tier ``name`` (``auto``: the first of the ladder whose
    estimated error is within the tolerance, else its last) given its error ``estimates``."""
    if name == "auto":
        name = next(
            (t for t in ACCURACY_LADDER if estimates[t] <= needs.tolerance), ACCURACY_LADDER[-1]
        )
    chosen = TIERS[name]
    return Plan(
        tier=chosen,
        structure=structure_for(chosen, scene.support, settings.modes),
        solver=chosen.default_solver,
        solver_options=chosen.solver_options(needs),
        model_error=estimates.get(name, 0.0),
        estimates=estimates,
        check_against=next_tier_up(name),
    )


def plan_many(
    scenes: Sequence[Scene], tier: str, needs: Needs, settings: FidelitySettings
) -> list[Plan]:
    """:func:`plan` of every scene, the error estimates of all of them at once
    (:func:`model_errors_many`)."""
    name = tier if tier == "auto" else get_tier(tier).name
    if name in EXACT_TIERS:
        estimates: list[dict[str, float]] = [{name: 0.0} for _ in scenes]
    else:
        estimates = model_errors_many(scenes, needs, settings.modes)
    return [_plan_of(s, name, e, needs, settings) for s, e in zip(scenes, estimates)]


def model_errors_many(
    scenes: Sequence[Scene], needs: Needs, modes: Sequence[BendingMode]
) -> list[dict[str, float]]:
    """:func:`model_errors` of every scene (the same estimates to rounding), in array
    operations over the scenes that share a support, sample rates and window."""
    groups: dict[tuple[Any, ...], list[int]] = {}
    support_index = support_indices()
    for k, scene in enumerate(scenes):
        spec = scene.sensors
        key = (
            support_index(scene.support),
            spec.pressure_rate_hz,
            spec.imu_rate_hz,
            scene.window_s,
        )
        groups.setdefault(key, []).append(k)
    out: list[dict[str, float]] = [{} for _ in scenes]
    for members in groups.values():
        group = [scenes[k] for k in members]
        for k, estimate in zip(members, _model_errors_group(group, needs, modes)):
            out[k] = estimate
    return out


def _model_errors_group(
    scenes: Sequence[Scene], needs: Needs, modes: Sequence[BendingMode]
) -> list[dict[str, float]]:
    """:func:`model_errors` of scenes on one support at one set of rates and window."""
    support = scenes[0].support
    rigid = structure_for(TIERS["rigid"], support, modes)
    modal = structure_for(TIERS["modal"], support, modes)
    impacts = [scene.impact for scene in scenes]
    positions = [i.position_m for i in impacts]
    shape_rigid = rigid.contact_shapes(positions)
    shape_modal = modal.contact_shapes(positions)
    c_rigid = np.einsum("si,ij,sj->s", shape_rigid, rigid.inv_mass, shape_rigid)
    c_modal = np.einsum("si,ij,sj->s", shape_modal, modal.inv_mass, shape_modal)
    mass = np.array([i.mass_kg for i in impacts])
    speed = np.array([i.impact_speed_mps for i in impacts])
    reduced = reduced_mass_kg(mass, c_rigid)
    chi = np.array(
        [
            damping_factor(s.contact_model, s.impact.restitution, support.contact_damping_scale)
            for s in scenes
        ]
    )
    stiffness = np.array([hertz_stiffness(i.material, support.plate, i.radius_m) for i in impacts])
    duration, separation, width = pulse_figures(np.minimum(chi, 40.0), stiffness, reduced, speed)
    gravity = support.gravity_mps2 * duration / speed
    waveform = needs.outputs & set(WAVEFORM_OUTPUTS)
    omega_rigid = 2 * math.pi * rigid.fastest_frequency_hz
    impulse_step = np.maximum(gravity, (omega_rigid * width) ** 2 / 2 if waveform else 0.0)
    restitution = np.maximum(separation / speed, 1e-3)
    rebound_step = (
        (1 + restitution)
        / restitution
        * np.abs(reduced_mass_kg(1.0, mass * c_modal) - reduced_mass_kg(1.0, mass * c_rigid))
    )
    rigid_step = rebound_step if needs.outputs & {"rebound", "contact"} else np.zeros(len(scenes))
    if waveform and modes:
        spec = scenes[0].sensors
        both = np.concatenate([shape_modal, shape_rigid], axis=1)
        n = modal.size
        worst = np.zeros(len(scenes))
        for output in sorted(waveform):
            rate = spec.pressure_rate_hz if output == "pressure" else spec.imu_rate_hz
            gram = sampled_gram(rigid, modal, output, rate, scenes[0].window_s)
            difference = np.maximum(np.einsum("pij,sj,si->sp", gram, both, both), 0.0)
            reference = np.einsum("pij,sj,si->sp", gram[:, :n, :n], shape_modal, shape_modal)
            ratio = np.where(
                reference > 0, difference / np.where(reference > 0, reference, 1.0), 0.0
            )
            worst = np.maximum(worst, np.sqrt(ratio.max(axis=1)))
        rigid_step = np.maximum(rigid_step, SAMPLED_MARGIN * worst)
    return [
        {"impulse": float(a + b), "rigid": float(b), "modal": 0.0, "brittle": 0.0}
        for a, b in zip(impulse_step, rigid_step)
    ]


def pulse_figures(
    chi: np.ndarray,
    hertz_stiffness: np.ndarray,
    reduced_mass_kg: np.ndarray,
    speed_mps: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Duration (s), separation speed (m/s) and force-weighted RMS width (s) of the contact
    pulses of many contacts (:func:`~tail_beam_sim.physics.solvers.pulse.contact_pulse`'s)."""
    table = pulse_table()
    row = np.clip(np.searchsorted(table.chi, chi, side="right") - 1, 0, table.chi.size - 2)
    weight = (chi - table.chi[row]) / (table.chi[row + 1] - table.chi[row])
    length = (reduced_mass_kg * speed_mps**2 / hertz_stiffness) ** 0.4
    w = weight[:, None]
    duration = ((1 - weight) * table.duration[row] + weight * table.duration[row + 1]) * (
        length / speed_mps
    )
    separation = speed_mps * (
        (1 - weight) * table.restitution[row] + weight * table.restitution[row + 1]
    )
    force = ((1 - w) * table.rows[row, 2] + w * table.rows[row + 1, 2]) * (
        hertz_stiffness * length**1.5
    )[:, None]
    times = table.fractions * duration[:, None]
    total = force.sum(axis=1)
    centroid = np.einsum("sj,sj->s", force, times) / total
    width = np.sqrt(np.einsum("sj,sj->s", force, (times - centroid[:, None]) ** 2) / total)
    return duration, separation, width


def model_errors(scene: Scene, needs: Needs, modes: Sequence[BendingMode]) -> dict[str, float]:
    """Estimated relative error of each tier of the accuracy ladder against the richest (module
    docstring)."""
    support, impact = scene.support, scene.impact
    rigid = structure_for(TIERS["rigid"], support, modes)
    modal = structure_for(TIERS["modal"], support, modes)
    shape_rigid = rigid.contact_shape(impact.position_m)
    shape_modal = modal.contact_shape(impact.position_m)
    c_rigid = rigid.contact_compliance(shape_rigid)  # 1/kg; 0 over the hinge
    c_modal = modal.contact_compliance(shape_modal)
    mass = impact.mass_kg
    reduced = reduced_mass_kg(mass, c_rigid)
    chi = damping_factor(scene.contact_model, impact.restitution, support.contact_damping_scale)
    stiffness = hertz_stiffness(impact.material, support.plate, impact.radius_m)
    pulse = contact_pulse(min(chi, 40.0), stiffness, reduced, impact.impact_speed_mps)
    width = pulse.width_s
    duration = pulse.duration_s
    gravity = support.gravity_mps2 * duration / impact.impact_speed_mps
    waveform = _waveform_outputs(needs.outputs)
    omega_rigid = 2 * math.pi * rigid.fastest_frequency_hz
    impulse_step = max(gravity, (omega_rigid * width) ** 2 / 2 if waveform else 0.0)
    restitution = max(pulse.separation_mps / impact.impact_speed_mps, 1e-3)
    rebound_step = (
        (1 + restitution)
        / restitution
        * abs(reduced_mass_kg(1.0, mass * c_modal) - reduced_mass_kg(1.0, mass * c_rigid))
    )
    rigid_step = rebound_step if not needs.outputs.isdisjoint(("rebound", "contact")) else 0.0
    if waveform and modes:
        rigid_step = max(
            rigid_step,
            SAMPLED_MARGIN
            * _sampled_difference(scene, (rigid, shape_rigid), (modal, shape_modal), waveform),
        )
    return {
        "impulse": impulse_step + rigid_step,
        "rigid": rigid_step,
        "modal": 0.0,
        "brittle": 0.0,
    }


@lru_cache(maxsize=64)
def _waveform_outputs(outputs: frozenset[str]) -> tuple[str, ...]:
    """The waveform outputs among ``outputs``, sorted (empty: none)."""
    return tuple(sorted(outputs & set(WAVEFORM_OUTPUTS)))


def _sampled_difference(
    scene: Scene,
    rigid: tuple[LinearStructure, np.ndarray],
    modal: tuple[LinearStructure, np.ndarray],
    outputs: tuple[str, ...] | set[str],
) -> float:
    """Relative L2 difference of the two structures' impulse responses as the sensors sample them,
    the worst over where the impulse falls within a sample period (PHASES, evaluated together).

    Each response is linear in the contact shape b(x) (the unit impulse starts the structure at
    q' = M^-1 b), so it is the product of the structure's sampled responses to each coordinate's
    unit load (:func:`unit_responses`, cached per structure and sensor setting) with b (each
    structure comes with its contact shape at the impact's position)."""
    spec = scene.sensors
    (lower, shape_lower), (upper, shape_upper) = rigid, modal
    both = np.concatenate([shape_upper, shape_lower])
    # every output's phases at once (outputs x phases, N, N)
    gram = _output_grams(
        lower,
        upper,
        outputs if isinstance(outputs, tuple) else tuple(sorted(outputs)),
        spec.pressure_rate_hz,
        spec.imu_rate_hz,
        scene.window_s,
    )
    n = upper.size
    # squared L2 norms per phase: of the difference (u b_u - l b_l) and of the reference
    difference = np.maximum((gram @ both) @ both, 0.0)
    reference = (gram[:, :n, :n] @ shape_upper) @ shape_upper
    # the ratio where the reference is positive, 0 elsewhere
    ratio = np.divide(difference, reference, out=np.zeros_like(difference), where=reference > 0)
    return math.sqrt(float(ratio.max()))


_OUTPUT_GRAMS: dict[tuple[Any, ...], tuple[Any, np.ndarray]] = {}


def _output_grams(
    lower: LinearStructure,
    upper: LinearStructure,
    outputs: tuple[str, ...],
    pressure_rate_hz: float,
    imu_rate_hz: float,
    window_s: float,
) -> np.ndarray:
    """The :func:`sampled_gram` of each of ``outputs`` (its sensor's rate), stacked: (outputs x
    phases, N, N), kept per (structures, outputs, rates, window)."""
    key = (id(lower), id(upper), outputs, pressure_rate_hz, imu_rate_hz, window_s)
    cached = _OUTPUT_GRAMS.get(key)
    if cached is not None and cached[0][0] is lower and cached[0][1] is upper:
        return cached[1]
    gram = np.concatenate(
        [
            sampled_gram(
                lower,
                upper,
                output,
                pressure_rate_hz if output == "pressure" else imu_rate_hz,
                window_s,
            )
            for output in outputs
        ]
    )
    if len(_OUTPUT_GRAMS) >= UNIT_RESPONSE_CACHE_SIZE:
        _OUTPUT_GRAMS.clear()
    _OUTPUT_GRAMS[key] = ((lower, upper), gram)  # holding them keeps their ids from being reused
    return gram


_GRAMS: dict[tuple[int, int, str, float, float], tuple[Any, np.ndarray]] = {}


def sampled_gram(
    lower: LinearStructure, upper: LinearStructure, output: str, rate_hz: float, window_s: float
) -> np.ndarray:
    """(phases, n_u + n_l, n_u + n_l): per phase, the Gram matrix of the unit responses
    (:func:`unit_responses`) of ``upper`` and, negated, of ``lower``, over channels and samples.
    With v = [b_u; b_l] the two contact shapes, v^T G v is the squared L2 norm of the
    difference of the two sampled impulse responses and the upper-left block's form in b_u
    that of ``upper``'s own, so that an impact's estimate costs two small products. Kept per
    (structures, output, rate, window)."""
    key = (id(lower), id(upper), output, float(rate_hz), float(window_s))
    cached = _GRAMS.get(key)
    if cached is not None and cached[0][0] is lower and cached[0][1] is upper:
        return cached[1]
    stacked = np.concatenate(
        [
            unit_responses(upper, output, rate_hz, window_s),
            -unit_responses(lower, output, rate_hz, window_s),
        ],
        axis=-1,
    )  # (channels, phases, samples, n_u + n_l)
    per_phase = stacked.transpose(1, 0, 2, 3).reshape(stacked.shape[1], -1, stacked.shape[3])
    gram = per_phase.transpose(0, 2, 1) @ per_phase
    if len(_GRAMS) >= UNIT_RESPONSE_CACHE_SIZE:
        _GRAMS.clear()
    _GRAMS[key] = ((lower, upper), gram)  # holding them keeps their ids from being reused
    return gram


_UNIT_RESPONSES: dict[tuple[int, str, float, float], tuple[LinearStructure, np.ndarray]] = {}
UNIT_RESPONSE_CACHE_SIZE = 64


def unit_responses(
    structure: LinearStructure, output: str, rate_hz: float, window_s: float
) -> np.ndarray:
    """(channels, phases, samples, n): ``output`` of ``structure`` as its sensor samples it at
    ``rate_hz`` over ``window_s``, after a unit impulse on each generalised coordinate falling
    at each of PHASES within a sample period. Pressure: the change from the setting pressure,
    Pa per N s, point samples; IMU: the period-averaged specific force along z (m/s^2 per N s)
    and pitch rate (rad/s per N s). Depends on the structure and the sensor setting only, not
    on the impact, so it is computed once per (structure, output, rate, window)."""
    key = (id(structure), output, float(rate_hz), float(window_s))
    cached = _UNIT_RESPONSES.get(key)
    if cached is not None and cached[0] is structure:
        return cached[1]
    count = int(window_s * rate_hz)
    times = (
        (np.arange(1, count + 1)[None, :] - np.array(PHASES)[:, None]) / rate_hz
    ).ravel()  # (phases x samples)
    n = structure.size
    vectors = structure._eigen[1]
    keep, sigma, omega, weight = structure._half_spectrum
    # The state after a unit impulse on q_j is x(t) = Re sum_k V_k exp(lambda_k t) xi_kj, xi_j
    # the modal amplitudes of [0; M^-1 e_j] (the columns of modal_input), over one eigenvalue
    # of each conjugate pair (weight 2) and the real ones: read through an output row r, every
    # coordinate's response at once is exp(sigma t) (cos(omega t) Re C - sin(omega t) Im C)
    # with C_kj = w_k (r V)_k xi_kj, in real arithmetic.
    growth = np.exp(np.multiply.outer(times, sigma))  # (T, k)
    angle = np.multiply.outer(times, omega)
    cos, sin = growth * np.cos(angle), growth * np.sin(angle)
    inputs = structure.modal_input[keep] * weight[:, None]  # (k, n)

    def read(row: np.ndarray, c: np.ndarray, s: np.ndarray) -> np.ndarray:
        amplitude = (row @ vectors[:, keep])[:, None] * inputs
        return c @ amplitude.real - s @ amplitude.imag  # (T, n)

    if output == "pressure":
        row = (
            np.concatenate(
                [
                    structure.jack_stiffness_npm * structure.jack_shape,
                    structure.jack_damping_nspm * structure.jack_shape,
                ]
            )
            / structure.piston_area_m2
        )
        rows = [row]
        signals = [read(row, cos, sin)]
    else:
        zero_n = np.zeros(n)
        rows = [
            np.concatenate([zero_n, structure.imu_shape]),
            np.concatenate([structure.imu_slope_shape, zero_n]),
        ]
        # one sample period earlier: exp(lambda (t - T)) = exp(lambda t) exp(-lambda T), the
        # beam at rest before the impulse
        period = 1.0 / rate_hz
        decay = np.exp(-sigma * period)
        turn_cos, turn_sin = np.cos(omega * period), np.sin(omega * period)
        cos_before = decay * (cos * turn_cos + sin * turn_sin)
        sin_before = decay * (sin * turn_cos - cos * turn_sin)
        early = times < period
        signals = []
        for row in rows:
            then = read(row, cos_before, sin_before)
            then[early] = 0.0
            signals.append((read(row, cos, sin) - then) * rate_hz)
    responses = np.stack(signals).reshape(len(rows), len(PHASES), count, n)
    if len(_UNIT_RESPONSES) >= UNIT_RESPONSE_CACHE_SIZE:
        _UNIT_RESPONSES.clear()
    _UNIT_RESPONSES[key] = (structure, responses)  # holding it keeps its id from being reused
    return responses


def next_tier_up(name: str) -> str | None:
    """The tier above ``name`` on the accuracy ladder (None at the top)."""
    if name in ACCURACY_LADDER[:-1]:
        return ACCURACY_LADDER[ACCURACY_LADDER.index(name) + 1]
    return None
