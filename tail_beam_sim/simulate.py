"""Offline simulation of one scene: solve, sample the sensors, summarise.

``simulate(scene)`` is the one entry point the command line, the nodes' tests and the
benchmarks share. Its result holds the noise-free histories (time from first contact), the
sensor streams (absolute simulation time, as the ROS topics stamp them) and a summary.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tail_beam_sim.contact import CrushingContact, damping_factor, effective_modulus_pa, hertz_stiffness
from tail_beam_sim.fidelity import DEFAULT_TIER, FidelitySettings, Needs, compare, next_tier_up, plan, shipped_settings, structure_for
from tail_beam_sim.scene import Impact, Scene
from tail_beam_sim.sensors import ImuStream, PressureStream, Rebound, SensorSuite, sample_grid, specific_force_z
from tail_beam_sim.solvers import ImpactProblem, Trajectory, solve
from tail_beam_sim.structure import LinearStructure, rigid_beam
from tail_beam_sim.support import Support

HISTORY_RATE_HZ = 20000.0
# Relative error bound of a hybrid contact integrated by RK4: measured in test_solvers.py (Hertz
# with hysteresis, 48 steps) and test_fidelity.py (crushing, the brittle tier's 192 steps).
RK4_CONTACT_ERROR = 1e-4


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
        damping_factor=damping_factor(contact_model, impact.restitution),
        impact_speed_mps=impact.impact_speed_mps,
        gravity_mps2=support.gravity_mps2,
        window_s=window_s,
        q0=np.zeros(n) if q0 is None else np.asarray(q0, dtype=float),
        qd0=np.zeros(n) if qd0 is None else np.asarray(qd0, dtype=float),
        crushing=crushing,
    )


@dataclass
class SimulationResult:
    """Everything one scene produced. ``history`` arrays share ``history['time_s']``."""

    scene: Scene
    trajectory: Trajectory
    contact_stamp_s: float
    history: dict[str, np.ndarray]
    pressure: PressureStream
    imu: ImuStream
    rebound: Rebound
    summary: dict[str, Any] = field(default_factory=dict)

    def truth(self) -> dict[str, Any]:
        """The ``impact_truth`` JSON object of this impact (contract: interface.md)."""
        impact = self.scene.impact
        first = self.trajectory.contacts[0]
        return {
            "impact_id": impact.impact_id,
            "material": impact.material.name,
            "material_class": impact.material.material_class,
            "label": "coal" if impact.material.is_coal else "gangue",
            "radius_m": impact.radius_m,
            "drop_height_m": impact.drop_height_m,
            "impact_speed_mps": impact.impact_speed_mps,
            "position_m": impact.position_m,
            "restitution_material": impact.restitution,
            "contact_model": self.scene.contact_model,
            "contact_start_stamp": self.contact_stamp_s,
            "contact_end_stamp": self.contact_stamp_s + first.end_s,
            "final_separation_stamp": self.contact_stamp_s + self.trajectory.final_separation_s,
            "rebound_stamp": self.rebound.stamp_s,
            **{k: v for k, v in self.summary.items() if k not in ("material", "radius_m", "position_m", "impact_speed_mps")},
        }


def summarise(scene: Scene, trajectory: Trajectory, history: dict[str, np.ndarray]) -> dict[str, Any]:
    """The noise-free figures of an impact (the keys of ``tail-beam simulate --json``)."""
    impact = scene.impact
    after = history["time_s"] >= 0.0
    rebound = trajectory.rebound_velocity_mps
    return {
        "material": impact.material.name,
        "radius_m": impact.radius_m,
        "mass_kg": impact.mass_kg,
        "position_m": impact.position_m,
        "drop_height_m": impact.drop_height_m,
        "impact_speed_mps": impact.impact_speed_mps,
        "rebound_speed_mps": max(rebound, 0.0),
        "restitution": max(rebound, 0.0) / impact.impact_speed_mps,
        "contact_duration_s": trajectory.contacts[0].duration_s,
        "peak_contact_force_n": max(c.peak_force_n for c in trajectory.contacts),
        "peak_jack_pressure_change_pa": float(np.max(history["jack_pressure_pa"][after]) - scene.support.setting_pressure_pa),
        "peak_beam_angular_velocity_radps": float(np.max(np.abs(history["beam_angular_velocity_radps"][after]))),
        "peak_imu_dynamic_accel_mps2": float(np.max(np.abs(history["imu_dynamic_accel_mps2"][after]))),
        "n_contacts": len(trajectory.contacts),
        "particle_at_rest": trajectory.particle_at_rest,
        "contact_model": scene.contact_model,
        "solver": trajectory.solver,
        "window_s": scene.window_s,
    }


def histories(scene: Scene, trajectory: Trajectory) -> dict[str, np.ndarray]:
    """Noise-free response histories from -pre_contact_s to window_s, time from first contact."""
    uniform = np.arange(-scene.pre_contact_s, scene.window_s + 0.5 / HISTORY_RATE_HZ, 1.0 / HISTORY_RATE_HZ)
    contact_times = np.concatenate([np.empty(0)] + [seg.t_s for seg in trajectory.segments if hasattr(seg, "force_n")])
    times = np.unique(np.concatenate([uniform, contact_times[contact_times <= scene.window_s]]))
    state = trajectory.sample(times)
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
    **solver_options: Any,
) -> SimulationResult:
    """Simulate one impact of ``scene`` and sample its sensors (reproducible by seed).

    ``tier`` picks the model (``tail_beam_sim.fidelity``: impulse, rigid (default: the study's
    model), modal, brittle, or auto: the cheapest that meets ``needs``); ``settings`` holds the
    bending modes and defaults (default: config/); ``solver`` the method (default: the tier's).
    The summary reports ``tier``, ``solver`` and ``error_estimate`` (relative, of the model and
    the solver together); ``check=True`` also simulates the next tier up and adds the measured
    differences as ``check``.
    """
    settings = settings or shipped_settings()
    needs = needs or settings.needs
    chosen = plan(scene, tier, needs, settings)
    structure = structure_for(chosen.tier, scene.support, settings.modes)
    crushing = crushing_contact(scene.support, scene.impact, settings.crushing_confinement_factor) if chosen.tier.brittle else None
    problem = build_problem(scene.support, scene.impact, scene.contact_model, scene.window_s, structure=structure, crushing=crushing)
    options = {**chosen.solver_options, **solver_options} if solver in (None, chosen.solver) else solver_options
    trajectory = solve(problem, solver or chosen.solver, **options)
    spec = scene.sensors
    suite = SensorSuite(spec)
    # The contact falls at a seeded instant within the first sample period after pre_contact_s,
    # so it is not always aligned with a sample, as it would not be on a real support.
    phase_rng = np.random.default_rng(np.random.SeedSequence(spec.seed).spawn(4)[3])
    slowest = min(spec.pressure_rate_hz, spec.imu_rate_hz)
    contact_stamp = scene.pre_contact_s + float(phase_rng.uniform(0.0, 1.0 / slowest))
    end = contact_stamp + scene.window_s
    history = histories(scene, trajectory)
    result = SimulationResult(
        scene=scene,
        trajectory=trajectory,
        contact_stamp_s=contact_stamp,
        history=history,
        pressure=suite.pressure(trajectory, sample_grid(0.0, end, spec.pressure_rate_hz), contact_stamp),
        imu=suite.imu(trajectory, sample_grid(0.0, end, spec.imu_rate_hz), contact_stamp),
        rebound=suite.rebound(trajectory, contact_stamp),
    )
    result.summary = summarise(scene, trajectory, history)
    result.summary["tier"] = chosen.tier.name
    solver_error = solver_error_estimate(trajectory)
    result.summary["error_estimate"] = max(chosen.model_error, solver_error) if math.isfinite(solver_error) else math.nan
    if check:
        upper = next_tier_up(chosen.tier.name)
        if upper is not None:
            reference = simulate(scene, tier=upper, needs=needs, settings=settings)
            result.summary["check"] = {"against": upper, **compare(result, reference, needs.outputs)}
    return result


def solver_error_estimate(trajectory: Trajectory) -> float:
    """The solver's own relative error estimate: the pulse's (hybrid, impulse), ``rtol`` for
    scipy's methods, RK4_CONTACT_ERROR for integrated hybrid contacts, nan when unknown."""
    stats = trajectory.stats
    if trajectory.solver in ("hybrid", "impulse"):
        estimate = stats.get("pulse_error_estimate", 0.0)
        return max(estimate, RK4_CONTACT_ERROR if stats.get("rk4_contacts") else 0.0)
    return stats.get("rtol", math.nan)


def crushing_contact(support: Support, impact: Impact, confinement_factor: float) -> CrushingContact | None:
    """The crushing contact of a coal particle (None for gangue, which stays elastic)."""
    if not impact.material.is_coal:
        return None
    return CrushingContact(
        effective_modulus_pa(impact.material, support.plate), impact.radius_m,
        impact.material.crushing_strength_pa * confinement_factor,
    )

