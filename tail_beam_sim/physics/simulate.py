"""Offline simulation of one scene: plan, build, solve, sensors, compare.

``simulate(scene)`` is the one entry point the command line, the nodes' tests and the
benchmarks share. It runs five plain steps, each typed:
:func:`~tail_beam_sim.physics.fidelity.plan`
(tier, structure, solver), :func:`build_problem`, :func:`~tail_beam_sim.physics.solvers.solve`,
:func:`sense` (histories, sensor streams, summary) and, on request,
:func:`~tail_beam_sim.physics.compare.compare` against the next tier up. Its
:class:`~tail_beam_sim.physics.result.SimulationResult` holds the noise-free histories (time
from first contact), the sensor streams (absolute simulation time, as the ROS topics stamp
them) and a summary.
"""

from __future__ import annotations

import gc
import math
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import numpy as np

from tail_beam_sim.physics.compare import compare
from tail_beam_sim.physics.contact import (
    CrushingContact,
    damping_factor,
    effective_modulus_pa,
    hertz_stiffness,
)
from tail_beam_sim.physics.contact_family import ContactFamily
from tail_beam_sim.physics.fidelity import (
    DEFAULT_TIER,
    FidelitySettings,
    Needs,
    Plan,
    plan,
    plan_many,
    shipped_settings,
)
from tail_beam_sim.physics.result import SimulationResult
from tail_beam_sim.physics.scene import Impact, Scene
from tail_beam_sim.physics.sense_many import (
    HISTORY_RATE_HZ,
    layout_key,
    sense_group,
    summary_figures,
    supported,
)
from tail_beam_sim.physics.sense_one import covers, sense_one
from tail_beam_sim.physics.sensors import (
    SensorSuite,
    VibrationBlocks,
    sample_grid,
    specific_force_z,
)
from tail_beam_sim.physics.solvers import ImpactProblem, Samples, Trajectory, solve
from tail_beam_sim.physics.solvers.hybrid import DEFAULT_PULSE_TOLERANCE
from tail_beam_sim.physics.solvers.pulse import shared_pulses
from tail_beam_sim.physics.structure import LinearStructure, rigid_beam
from tail_beam_sim.physics.support import Support, support_indices

__all__ = [
    "HISTORY_RATE_HZ",
    "SimulationResult",
    "build_problem",
    "crushing_contact",
    "histories",
    "history_times",
    "sense",
    "sense_general",
    "simulate",
    "simulate_many",
    "summarise",
]

# Impacts solved together, and scenes sensed together, from this many on (fewer: one by one,
# whose fixed cost is smaller)
MIN_GROUP = 4


def build_problem(
    support: Support,
    impact: Impact,
    contact_model: str,
    window_s: float,
    structure: LinearStructure | None = None,
    q0: np.ndarray | None = None,
    qd0: np.ndarray | None = None,
    crushing: CrushingContact | None = None,
) -> ImpactProblem:
    """Assemble the impact problem of ``impact`` on ``support`` (rigid beam by default;
    ``crushing`` replaces the hysteresis law by the brittle contact)."""
    structure = structure or rigid_beam(support)
    n = structure.size
    return ImpactProblem(
        structure=structure,
        contact_shape=structure.contact_shape(impact.position_m),
        mass_kg=impact.mass_kg,
        hertz_stiffness=hertz_stiffness(impact.material, support.plate, impact.radius_m),
        damping_factor=damping_factor(
            contact_model, impact.restitution, support.contact_damping_scale
        ),
        impact_speed_mps=impact.impact_speed_mps,
        gravity_mps2=support.gravity_mps2,
        window_s=window_s,
        q0=np.zeros(n) if q0 is None else np.asarray(q0, dtype=float),
        qd0=np.zeros(n) if qd0 is None else np.asarray(qd0, dtype=float),
        crushing=crushing,
    )


def summarise(
    scene: Scene, trajectory: Trajectory, history: dict[str, np.ndarray]
) -> dict[str, Any]:
    """The noise-free figures of an impact (the keys of ``tail-beam simulate --json``)."""
    after = history["time_s"] >= 0.0
    return summary_figures(
        scene,
        trajectory,
        float(np.max(history["jack_pressure_pa"][after]) - scene.support.setting_pressure_pa),
        float(np.max(np.abs(history["beam_angular_velocity_radps"][after]))),
        float(np.max(np.abs(history["imu_dynamic_accel_mps2"][after]))),
    )


def history_times(scene: Scene, trajectory: Trajectory) -> np.ndarray:
    """The instants of the histories, s from first contact: HISTORY_RATE_HZ from
    -pre_contact_s to window_s, plus every step of each contact (so peaks are not missed)."""
    uniform = np.arange(
        -scene.pre_contact_s, scene.window_s + 0.5 / HISTORY_RATE_HZ, 1.0 / HISTORY_RATE_HZ
    )
    contact_times = np.concatenate(
        [np.empty(0)] + [seg.t_s for seg in trajectory.segments if hasattr(seg, "force_n")]
    )
    return np.unique(np.concatenate([uniform, contact_times[contact_times <= scene.window_s]]))


def histories(
    scene: Scene, trajectory: Trajectory, state: Samples | None = None
) -> dict[str, np.ndarray]:
    """Noise-free response histories from -pre_contact_s to window_s, time from first contact
    (``state``: the trajectory already sampled at :func:`history_times`)."""
    if state is None:
        state = trajectory.sample(history_times(scene, trajectory))
    times = state.t_s
    structure = trajectory.problem.structure
    return {
        "time_s": times,
        "contact_force_n": state.force_n,
        "jack_pressure_pa": structure.pressure_pa(state.q, state.qd),
        "beam_angle_rad": state.q[0],
        "beam_angular_velocity_radps": state.qd[0],
        "imu_angular_velocity_radps": structure.imu_slope_shape @ state.qd,
        "imu_specific_force_mps2": specific_force_z(trajectory, state),
        "imu_dynamic_accel_mps2": -(structure.imu_shape @ state.qdd),
        "particle_position_m": state.z_m,
        "particle_velocity_mps": state.zd_mps,
    }


def simulate(
    scene: Scene,
    solver: str | None = None,
    *,
    tier: str = DEFAULT_TIER,
    needs: Needs | None = None,
    settings: FidelitySettings | None = None,
    check: bool = False,
    vibration: bool = True,
    **solver_options: Any,
) -> SimulationResult:
    """Simulate one impact of ``scene`` and sample its sensors (reproducible by seed).

    ``tier`` picks the model (``tail_beam_sim.physics.fidelity``: impulse, rigid (default: the
    study's model), modal, brittle, or auto: the cheapest that meets ``needs``); ``settings`` holds
    the bending modes and defaults (default: config/); ``solver`` the method (default: the tier's).
    The summary reports ``tier``, ``solver`` and ``error_estimate`` (relative, of the model and
    the solver together); ``check=True`` also simulates the next tier up and adds the measured
    differences as ``check``. ``vibration=False``: a site without the tail-beam accelerometer
    (no blocks; the other streams are the same, and the accelerometer model, the costliest
    sensor, is not run).
    """
    settings = settings or shipped_settings()
    needs = needs or settings.needs
    # the plan's contact pulse is the solver's when their arguments agree (shared_pulses)
    with shared_pulses():
        chosen, problem, method, options = _prepare(scene, tier, needs, settings, solver)
        # One scene alone: the solver and the per-trajectory sensors (the group path's fixed
        # cost is larger than its saving for one impact; simulate_many takes it for many).
        trajectory = solve(problem, method, **{**options, **solver_options})
    result = _finish(scene, chosen, trajectory, vibration)
    if check and chosen.check_against is not None:
        reference = simulate(scene, tier=chosen.check_against, needs=needs, settings=settings)
        result.summary["check"] = {
            "against": chosen.check_against,
            **compare(result, reference, needs.outputs),
        }
    return result


def simulate_many(
    scenes: Iterable[Scene],
    *,
    tier: str = DEFAULT_TIER,
    needs: Needs | None = None,
    settings: FidelitySettings | None = None,
    vibration: bool | Sequence[bool] = True,
) -> list[SimulationResult]:
    """Full sensor streams of many scenes: the same results as
    ``[simulate(s, tier=tier, needs=needs, settings=settings, vibration=v) for s in scenes]``
    (``vibration``: one flag for all, or one per scene; the same noise, stamps and blocks, the
    signals to rounding), with each distinct impact solved once.

    Scenes that differ only in their sensors (rates, noise, seed: what a data set varies to
    train and evaluate across sensor settings) share one trajectory, since the motion does not
    depend on how it is measured; each scene still gets its own plan (its error estimate and an
    automatic tier depend on its sample rates: scenes share a trajectory only when their plans
    agree on the model and solver) and its own streams.

    Impacts the hybrid solver takes as one contact (most: :mod:`~tail_beam_sim.physics.
    contact_family`) are solved together per structure, and the sensors of scenes that share
    their rates and window are sampled together (:mod:`~tail_beam_sim.physics.sense_many`),
    one array operation per signal for the group, when there are MIN_GROUP or more; the others
    one by one. A grouped result's histories are computed when first read.

    Python's cycle collector is paused meanwhile (:func:`collector_paused`).
    """
    with collector_paused():
        return _simulate_many(scenes, tier, needs, settings, vibration)


@contextmanager
def collector_paused() -> Iterator[None]:
    """Python's cyclic garbage collector off within (on again after, if it was on before).

    A group allocates a few tens of small objects per scene (results, trajectories, segments,
    summaries, generators), most of which outlive the call: left on, the collector walks them
    again and again as they pile up, and its full collections walk the caller's whole heap, a
    cost that grows with the caller rather than with the group. Reference counting still frees
    everything as before; the few cycles left go at the next collection after the call."""
    was_on = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_on:
            gc.enable()


def _simulate_many(
    scenes: Iterable[Scene],
    tier: str,
    needs: Needs | None,
    settings: FidelitySettings | None,
    vibration: bool | Sequence[bool],
) -> list[SimulationResult]:
    """:func:`simulate_many`'s work."""
    settings = settings or shipped_settings()
    needs = needs or settings.needs
    scenes = list(scenes)
    flags = [vibration] * len(scenes) if isinstance(vibration, bool) else list(vibration)
    if len(flags) != len(scenes):
        raise ValueError(f"{len(flags)} vibration flags for {len(scenes)} scenes")
    results: list[SimulationResult | None] = [None] * len(scenes)
    plans = []
    impacts: dict[tuple[Any, ...], int] = {}  # each distinct impact's index in ``distinct``
    distinct: list[tuple[Plan, ImpactProblem, str, dict[str, Any]]] = []
    plans_made = (
        plan_many(scenes, tier, needs, settings)
        if len(scenes) >= MIN_GROUP
        else [plan(scene, tier, needs, settings) for scene in scenes]
    )
    support_index = support_indices()
    for scene, chosen in zip(scenes, plans_made):
        problem, method, options = _problem(scene, chosen, settings, None)
        key = (
            support_index(scene.support),
            scene.impact,
            scene.contact_model,
            scene.window_s,
            chosen.tier.name,
            id(chosen.structure),
            method,
            tuple(sorted(options.items())),
        )
        index = impacts.setdefault(key, len(distinct))  # the key hashed once
        if index == len(distinct):
            distinct.append((chosen, problem, method, options))
        plans.append((chosen, index))
    # the one-contact impacts, per structure and tolerance: one family each
    families: dict[tuple[int, float], tuple[list[int], list[ImpactProblem]]] = {}
    for index, (chosen, problem, method, options) in enumerate(distinct):
        if _family_path(None, chosen, method, options):
            members = families.setdefault(
                (id(chosen.structure), _family_tolerance(options)), ([], [])
            )
            members[0].append(index)
            members[1].append(problem)
    place: dict[int, tuple[ContactFamily, int]] = {}
    for (_, tolerance), (indices, problems) in families.items():
        if len(indices) < MIN_GROUP:
            continue  # solved one by one below
        family = ContactFamily(problems, tolerance)
        for row, index in enumerate(indices):
            if family.ok[row]:
                place[index] = (family, row)
    groups: dict[tuple[Any, ...], list[int]] = {}
    for k, (scene, (chosen, index)) in enumerate(zip(scenes, plans)):
        if index in place and supported(scene.sensors):
            family, _ = place[index]
            groups.setdefault((id(family), layout_key(scene, flags[k])), []).append(k)
    alone = [k for members in groups.values() if len(members) < MIN_GROUP for k in members]
    solved: dict[int, Trajectory] = {}
    grouped = {k for members in groups.values() for k in members}
    for k in sorted(alone) + [k for k in range(len(scenes)) if k not in grouped]:
        chosen, index = plans[k]
        if index in place:
            trajectory = place[index][0].trajectory(place[index][1])
        else:
            trajectory = solved.get(index)
            if trajectory is None:
                _, problem, method, options = distinct[index]
                trajectory = solved[index] = solve(problem, method, **options)
        results[k] = _finish(scenes[k], chosen, trajectory, flags[k])
    for members in groups.values():
        if len(members) < MIN_GROUP:
            continue
        family = place[plans[members[0]][1]][0]
        rows = np.array([place[plans[k][1]][1] for k in members], dtype=np.int64)
        sensed = sense_group(
            family, rows, [scenes[k] for k in members], flags[members[0]], histories
        )
        for k, result in zip(members, sensed):
            _label(result, plans[k][0])
            results[k] = result
    return [r for r in results if r is not None]


def _family_path(scene: Scene | None, chosen: Plan, method: str, options: dict[str, Any]) -> bool:
    """Whether the impact goes the contact family's way: the hybrid solver with its default
    contact handling (only the tier's tolerance given), no crushing, and (given the scene)
    sensors the group path covers."""
    return (
        method == "hybrid"
        and set(options) <= {"pulse_tolerance"}
        and not chosen.tier.brittle
        and (scene is None or supported(scene.sensors))
    )


def _family_tolerance(options: dict[str, Any]) -> float:
    return float(options.get("pulse_tolerance", DEFAULT_PULSE_TOLERANCE))


def _prepare(
    scene: Scene, tier: str, needs: Needs, settings: FidelitySettings, solver: str | None
) -> tuple[Plan, ImpactProblem, str, dict[str, Any]]:
    """The plan of ``scene``, its impact problem, the solver and the plan's options for it
    (none when ``solver`` is another than the tier's)."""
    chosen = plan(scene, tier, needs, settings)
    return (chosen, *_problem(scene, chosen, settings, solver))


def _problem(
    scene: Scene, chosen: Plan, settings: FidelitySettings, solver: str | None
) -> tuple[ImpactProblem, str, dict[str, Any]]:
    """The impact problem of ``scene`` under plan ``chosen``, the solver and its options."""
    crushing = (
        crushing_contact(scene.support, scene.impact, settings.crushing_confinement_factor)
        if chosen.tier.brittle
        else None
    )
    problem = build_problem(
        scene.support,
        scene.impact,
        scene.contact_model,
        scene.window_s,
        structure=chosen.structure,
        crushing=crushing,
    )
    options = chosen.solver_options if solver in (None, chosen.solver) else {}
    return problem, solver or chosen.solver, dict(options)


def _finish(
    scene: Scene, chosen: Plan, trajectory: Trajectory, vibration: bool
) -> SimulationResult:
    """The sensors of ``trajectory`` and the summary's tier and error estimate."""
    result = sense(scene, trajectory, vibration)
    _label(result, chosen)
    return result


def _label(result: SimulationResult, chosen: Plan) -> None:
    """The summary's tier and error estimate (the plan's model error and the solver's own)."""
    # The solver's own estimate is a field of every trajectory (contract:
    # tail_beam_sim.physics.solvers).
    own = result.trajectory.error_estimate
    result.summary["tier"] = chosen.tier.name
    result.summary["error_estimate"] = (
        max(chosen.model_error, own) if math.isfinite(own) else math.nan
    )


def sense(scene: Scene, trajectory: Trajectory, vibration: bool = True) -> SimulationResult:
    """What the support's sensors and the summary make of ``trajectory``: noise-free histories,
    the sampled streams and the rebound (seeded by ``scene.sensors.seed``).

    The contact falls at a seeded instant within the first sample period after
    ``pre_contact_s``, so it is not always aligned with a sample, as it would not be on a
    real support. The lean path (:mod:`~tail_beam_sim.physics.sense_one`) reads the scenes and
    trajectories it covers, :func:`sense_general` the others, with the same results.
    """
    if covers(scene, trajectory):
        return sense_one(scene, trajectory, vibration)
    return sense_general(scene, trajectory, vibration)


def sense_general(
    scene: Scene, trajectory: Trajectory, vibration: bool = True
) -> SimulationResult:
    """:func:`sense` for any scene and trajectory: each sensor's readings from the trajectory's
    own sampling (:meth:`~tail_beam_sim.physics.solvers.Trajectory.sample_many`, every
    sensor's instants in one pass)."""
    spec = scene.sensors
    suite = SensorSuite(spec)
    slowest = min(spec.pressure_rate_hz, spec.imu_rate_hz)
    # phase_rng().uniform(0, 1 / slowest), which is 0 + (1 / slowest) * its first random()
    contact_stamp = scene.pre_contact_s + (0.0 + (1.0 / slowest) * suite.contact_phase())
    end = contact_stamp + scene.window_s
    pressure_stamps = sample_grid(0.0, end, spec.pressure_rate_hz)
    imu_stamps = sample_grid(0.0, end, spec.imu_rate_hz)
    # Every sensor's instants sampled in one pass (the histories', the pressure's, the IMU's and
    # the period before each, the accelerometer's dense instants), each sensor reading its part.
    parts = [
        history_times(scene, trajectory),
        pressure_stamps - contact_stamp,
        *suite.imu_times(imu_stamps, contact_stamp),
        *([suite.vibration_times(end, contact_stamp, trajectory)] if vibration else []),
    ]
    states = trajectory.sample_many(parts)
    history = histories(scene, trajectory, states[0])
    rebound = suite.rebound(trajectory, contact_stamp)
    point = suite.reported_point(scene.impact.position_m, rebound, scene.support)
    return SimulationResult(
        scene=scene,
        trajectory=trajectory,
        contact_stamp_s=contact_stamp,
        history=history,
        pressure=suite.pressure(trajectory, pressure_stamps, contact_stamp, states[1]),
        imu=suite.imu(trajectory, imu_stamps, contact_stamp, (states[2], states[3])),
        rebound=rebound,
        summary=summarise(scene, trajectory, history),
        vibration=suite.vibration(trajectory, end, contact_stamp, states[4])
        if vibration
        else VibrationBlocks.empty(),
        point=point,
    )


def crushing_contact(
    support: Support, impact: Impact, confinement_factor: float
) -> CrushingContact | None:
    """The crushing contact of a coal particle (None for gangue, which stays elastic)."""
    if not impact.material.is_coal:
        return None
    return CrushingContact(
        effective_modulus_pa(impact.material, support.plate),
        impact.radius_m,
        impact.material.crushing_strength_pa * confinement_factor,
    )
