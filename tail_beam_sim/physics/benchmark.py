"""Speed against accuracy: every solver setting and every tier timed and measured against a
converged reference, with the Pareto front; batch throughput; real-time factor.

Timings are medians of repeated runs and are quoted as ratios to scipy's Radau at rtol 1e-8
timed in the same run, because the machine is shared and absolute times are noisy. Errors are
relative, against a reference solved by Radau at ``REFERENCE_RTOL`` and checked by refinement
(the same solve at ten times the tolerance must agree to within the reported bound):

* rebound speed, peak contact force, peak jack pressure change (the pressure sampled at 20 kHz
  plus every step of each contact, the same for every solver);
* the IMU waveform: the period-averaged accelerometer at the IMU rate over the window, relative L2.

:func:`simulate_speed` times the whole of ``simulate()`` (plan, solve, every sensor of the
layout, summary) against Radau at rtol 1e-8 solving the same impact, per stage;
:func:`simulate_throughput` the full streams of many impacts per second through
``simulate_many``.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from tail_beam_sim.physics import batch as batch_path
from tail_beam_sim.physics.fidelity import (
    DEFAULT_TIER,
    TIERS,
    FidelitySettings,
    get_tier,
    plan,
    structure_for,
)
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.sensors import SensorSuite, imu_samples, sample_grid
from tail_beam_sim.physics.simulate import (
    HISTORY_RATE_HZ,
    build_problem,
    sense,
    simulate,
    simulate_many,
)
from tail_beam_sim.physics.solvers import ImpactProblem, Trajectory, solve

REFERENCE_RTOL = 1e-11
BASELINE = ("Radau", {"rtol": 1e-8})
METRICS = ("rebound", "peak_force", "peak_pressure", "imu_l2")
MIN_TIMED_S = 0.3  # time spent timing a fast setting, s
MAX_RUNS = 2000
CPU_REPEATS = 5  # runs of simulate_many timed in CPU seconds, at least

# (solver, options) of the default run and the extra settings of --full.
QUICK_SETTINGS: list[tuple[str, dict[str, Any]]] = [
    ("hybrid", {}),
    ("hybrid", {"contact": "rk4", "steps_per_contact": 12}),
    ("hybrid", {"contact": "rk4", "steps_per_contact": 48}),
    ("hybrid", {"contact": "rk4", "steps_per_contact": 192}),
    ("impulse", {}),
    ("euler", {"dt_s": 5e-6}),
    ("verlet", {"dt_s": 5e-6}),
    ("rk4", {"dt_s": 2e-5}),
    ("rk4", {"dt_s": 5e-6}),
    *[(m, {"rtol": r}) for m in ("RK45", "DOP853", "LSODA", "BDF", "Radau") for r in (1e-5, 1e-8)],
]
FULL_EXTRA: list[tuple[str, dict[str, Any]]] = [
    ("euler", {"dt_s": 1e-6}),
    ("verlet", {"dt_s": 1e-6}),
    ("rk4", {"dt_s": 1e-6}),
    ("hybrid", {"contact": "rk4", "steps_per_contact": 768}),
    *[
        (m, {"rtol": r})
        for m in ("RK45", "DOP853", "LSODA", "BDF", "Radau")
        for r in (1e-3, 1e-10)
    ],
]


@dataclass
class Row:
    """One solver setting or tier: times (s), errors (relative) and its ratio to the baseline."""

    name: str
    setting: str
    times_s: list[float]
    errors: dict[str, float]
    ratio: float = float("nan")
    pareto: bool = False
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def median_s(self) -> float:
        return statistics.median(self.times_s)

    @property
    def spread(self) -> float:
        """Spread of the repeated timings over their median: 10-90 % range (max - min under 10
        runs)."""
        low, high = (
            np.percentile(self.times_s, [10, 90])
            if len(self.times_s) >= 10
            else (min(self.times_s), max(self.times_s))
        )
        return float(high - low) / self.median_s if self.median_s > 0 else 0.0

    def as_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "setting": self.setting,
            "median_s": self.median_s,
            "spread": self.spread,
            "runs": len(self.times_s),
            "ratio_to_radau_1e-8": self.ratio,
            "pareto": self.pareto,
            **{f"err_{k}": v for k, v in self.errors.items()},
            **self.extra,
        }


def describe(options: dict[str, Any]) -> str:
    return (
        " ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in options.items())
        or "default"
    )


def timed(
    function: Callable[[], Any], repeats: int, min_time_s: float = MIN_TIMED_S
) -> tuple[list[float], Any]:
    """Wall times of at least ``repeats`` calls after one warm-up call, more for fast functions
    (until ``min_time_s`` of timing or MAX_RUNS), so that one preempted run cannot move the
    median; and the last result."""
    result = function()
    times: list[float] = []
    while len(times) < repeats or (sum(times) < min_time_s and len(times) < MAX_RUNS):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return times, result


@dataclass
class Measures:
    """The figures an error is measured on, from one trajectory."""

    rebound_mps: float
    peak_force_n: float
    peak_pressure_pa: float
    imu: np.ndarray


def measure(trajectory: Trajectory, imu_rate_hz: float) -> Measures:
    """Rebound, peak contact force, peak pressure change and averaged IMU accelerometer."""
    problem = trajectory.problem
    window = problem.window_s
    grid = np.arange(0.0, window, 1.0 / HISTORY_RATE_HZ)
    steps = [seg.t_s for seg in trajectory.segments if hasattr(seg, "force_n")]
    times = np.unique(np.concatenate([grid, *[t[(t >= 0) & (t <= window)] for t in steps]]))
    state = trajectory.sample(times)
    structure = problem.structure
    pressure = structure.pressure_pa(state.q, state.qd) - structure.setting_pressure_pa
    stamps = sample_grid(1.0 / imu_rate_hz, window, imu_rate_hz)
    _, accel = imu_samples(trajectory, stamps, 1.0 / imu_rate_hz)
    return Measures(
        trajectory.rebound_velocity_mps,
        max(c.peak_force_n for c in trajectory.contacts),
        float(pressure.max()),
        accel[:, 2],
    )


def errors(measured: Measures, reference: Measures) -> dict[str, float]:
    """Relative errors of every metric against the reference."""

    def rel(a: float, b: float) -> float:
        return abs(a - b) / abs(b)

    imu = reference.imu - reference.imu.mean()
    return {
        "rebound": rel(measured.rebound_mps, reference.rebound_mps),
        "peak_force": rel(measured.peak_force_n, reference.peak_force_n),
        "peak_pressure": rel(measured.peak_pressure_pa, reference.peak_pressure_pa),
        "imu_l2": float(np.linalg.norm(measured.imu - reference.imu) / np.linalg.norm(imu)),
    }


def mark_pareto(rows: Sequence[Row], metric: Callable[[Row], float]) -> list[Row]:
    """Rows on the Pareto front of (median time, ``metric``): none faster is also as accurate."""
    front, best = [], float("inf")
    for row in sorted(rows, key=lambda r: r.median_s):
        value = metric(row)
        if value < best:
            front.append(row)
            best = value
    return front


def worst_target_error(row: Row) -> float:
    """The issue's target metrics: the worse of rebound and peak jack pressure change."""
    return max(row.errors["rebound"], row.errors["peak_pressure"])


def reference_solution(problem: ImpactProblem, imu_rate_hz: float) -> tuple[Measures, float]:
    """The Radau reference and its own error bound (against the same at 10 x the tolerance)."""
    reference = measure(solve(problem, "Radau", rtol=REFERENCE_RTOL), imu_rate_hz)
    coarser = measure(solve(problem, "Radau", rtol=10 * REFERENCE_RTOL), imu_rate_hz)
    return reference, max(errors(coarser, reference).values())


def solver_rows(
    problem: ImpactProblem,
    reference: Measures,
    imu_rate_hz: float,
    settings: Sequence[tuple[str, dict[str, Any]]],
    repeats: int,
    progress: Callable[[str], None] = lambda _: None,
    min_time_s: float = MIN_TIMED_S,
) -> list[Row]:
    """Every solver setting timed ``repeats`` times and measured against ``reference``."""
    rows = []
    for name, options in settings:
        progress(f"{name} {describe(options)}")
        times, trajectory = timed(lambda: solve(problem, name, **options), repeats, min_time_s)
        rows.append(
            Row(
                name, describe(options), times, errors(measure(trajectory, imu_rate_hz), reference)
            )
        )
    baseline = next(
        (r for r in rows if (r.name, r.setting) == (BASELINE[0], describe(BASELINE[1]))), None
    )
    for row in rows:
        row.ratio = row.median_s / baseline.median_s if baseline else float("nan")
    for row in mark_pareto(rows, worst_target_error):
        row.pareto = True
    return rows


def tier_rows(
    scene: Scene,
    settings: FidelitySettings,
    repeats: int,
    baseline_s: float,
    min_time_s: float = MIN_TIMED_S,
) -> tuple[list[Row], float]:
    """Each tier with its default solver against the richest model (modal) solved by Radau."""
    imu_rate = scene.sensors.imu_rate_hz
    modal = build_problem(
        scene.support,
        scene.impact,
        scene.contact_model,
        scene.window_s,
        structure=structure_for(TIERS["modal"], scene.support, settings.modes),
    )
    reference = measure(solve(modal, "Radau", rtol=1e-10), imu_rate)
    check = measure(solve(modal, "Radau", rtol=1e-9), imu_rate)
    rows = []
    for name in ("impulse", "rigid", "modal"):
        tier = TIERS[name]
        problem = build_problem(
            scene.support,
            scene.impact,
            scene.contact_model,
            scene.window_s,
            structure=structure_for(tier, scene.support, settings.modes),
        )
        times, trajectory = timed(lambda: solve(problem, tier.default_solver), repeats, min_time_s)
        row = Row(
            name, tier.default_solver, times, errors(measure(trajectory, imu_rate), reference)
        )
        row.ratio = row.median_s / baseline_s
        rows.append(row)
    for row in mark_pareto(rows, lambda r: max(r.errors.values())):
        row.pareto = True
    return rows, max(errors(check, reference).values())


def batch_throughput(
    scene: Scene,
    settings: FidelitySettings,
    impacts: int,
    repeats: int,
    seed: int = 0,
    min_time_s: float = MIN_TIMED_S,
) -> dict[str, float]:
    """Impacts per second of the batch path: summaries and full noisy streams, rigid and modal."""
    rng = np.random.default_rng(seed)
    names = [n for n, m in scene.materials.items() if m.material_class != "structure"]
    support = scene.support

    def draw(n: int) -> batch_path.ImpactBatch:
        return batch_path.ImpactBatch.from_arrays(
            support,
            scene.materials,
            rng.choice(names, n),
            rng.uniform(0.02, 0.1, n),
            np.sqrt(2 * support.gravity_mps2 * rng.uniform(1.5, 4.0, n)),
            rng.uniform(support.impact_zone_min_m, support.impact_zone_max_m, n),
        )

    out = {}
    summaries_batch, streams_batch = draw(impacts), draw(max(impacts // 10, 1))
    for name in ("rigid", "modal"):
        structure = structure_for(TIERS[name], support, settings.modes)
        times, _ = timed(
            lambda: batch_path.summaries(
                support, structure, summaries_batch, scene.contact_model, scene.window_s
            ),
            repeats,
            min_time_s,
        )
        out[f"{name}_summaries_per_s"] = summaries_batch.size / statistics.median(times)
        times, _ = timed(
            lambda: batch_path.streams(
                support,
                structure,
                streams_batch,
                scene.sensors,
                scene.contact_model,
                scene.window_s,
            ),
            repeats,
            min_time_s,
        )
        out[f"{name}_streams_per_s"] = streams_batch.size / statistics.median(times)
    return out


def real_time_factor(
    scene: Scene, settings: FidelitySettings, repeats: int, min_time_s: float = MIN_TIMED_S
) -> dict[str, float]:
    """Simulated seconds per wall second for one impact's window of sensor streams at the
    default rates (solve, then sample pressure, IMU and camera), per tier's default solver."""
    spec = scene.sensors
    out = {}
    for name in ("rigid", "modal"):
        tier = TIERS[name]
        structure = structure_for(tier, scene.support, settings.modes)

        def one_impact() -> None:
            problem = build_problem(
                scene.support,
                scene.impact,
                scene.contact_model,
                scene.window_s,
                structure=structure,
            )
            trajectory = solve(problem, tier.default_solver)
            suite = SensorSuite(spec)
            suite.pressure(
                trajectory, sample_grid(0.0, scene.window_s, spec.pressure_rate_hz), 0.0
            )
            suite.imu(trajectory, sample_grid(0.0, scene.window_s, spec.imu_rate_hz), 0.0)
            suite.rebound(trajectory, 0.0)

        times, _ = timed(one_impact, repeats, min_time_s)
        out[f"{name}_real_time_factor"] = scene.window_s / statistics.median(times)
    return out


def simulate_speed(
    scene: Scene,
    settings: FidelitySettings,
    repeats: int,
    min_time_s: float = MIN_TIMED_S,
    tier: str = DEFAULT_TIER,
) -> dict[str, float]:
    """``simulate(scene)`` at ``tier`` with every sensor of the scene's layout, and without the
    accelerometer, against scipy's Radau at rtol 1e-8 solving the same impact on the same
    structure: medians (s) and speed-ups (Radau's time over simulate's, timed in alternating
    rounds so that a busy machine slows both alike), each stage's median (plan, solve, sensors
    with and without the accelerometer, s) and simulate's rebound error against the converged
    Radau reference (relative)."""
    chosen = plan(scene, tier, settings.needs, settings)
    problem = build_problem(
        scene.support,
        scene.impact,
        scene.contact_model,
        scene.window_s,
        structure=structure_for(get_tier(tier), scene.support, settings.modes),
    )
    reference = solve(problem, "Radau", rtol=REFERENCE_RTOL)
    trajectory = solve(problem, chosen.solver, **chosen.solver_options)
    calls: dict[str, Callable[[], Any]] = {
        "radau": lambda: solve(problem, BASELINE[0], **BASELINE[1]),
        "simulate": lambda: simulate(scene, tier=tier, settings=settings),
        "simulate_no_vibration": lambda: simulate(
            scene, tier=tier, settings=settings, vibration=False
        ),
        "plan": lambda: plan(scene, tier, settings.needs, settings),
        "solve": lambda: solve(problem, chosen.solver, **chosen.solver_options),
        "sensors": lambda: sense(scene, trajectory, True),
        "sensors_no_vibration": lambda: sense(scene, trajectory, False),
    }
    times: dict[str, list[float]] = {name: [] for name in calls}
    result = simulate(scene, tier=tier, settings=settings)
    rounds = 0
    while rounds < repeats or (sum(times["radau"]) < min_time_s and rounds < MAX_RUNS):
        for name, call in calls.items():
            # the fast calls repeated within a round, so that each round weighs them alike
            for _ in range(1 if name == "radau" else 5):
                start = time.perf_counter()
                call()
                times[name].append(time.perf_counter() - start)
        rounds += 1
    medians = {name: statistics.median(values) for name, values in times.items()}
    rebound = abs(result.trajectory.rebound_velocity_mps - reference.rebound_velocity_mps)
    return {
        **{f"{name}_median_s": value for name, value in medians.items()},
        "speedup": medians["radau"] / medians["simulate"],
        "speedup_no_vibration": medians["radau"] / medians["simulate_no_vibration"],
        "rebound_error": rebound / abs(reference.rebound_velocity_mps),
        "rounds": rounds,
    }


def simulate_throughput(
    scene: Scene,
    settings: FidelitySettings,
    impacts: int,
    repeats: int,
    seed: int = 0,
    min_time_s: float = MIN_TIMED_S,
    sensor_settings: int = 3,
) -> dict[str, float]:
    """Impacts per second (one process) of ``simulate_many`` at the default tier, every sensor of
    the scene's layout on: ``impacts`` distinct impacts (coal and gangue, radii 25-100 mm, drop
    heights 0.5-4 m, positions over the impact zone) per wall second and per CPU second of
    this process (what one core gives on a shared machine), and the same impacts each at
    ``sensor_settings`` sensor settings (noise and seed varied, as a data set varies them;
    results per second)."""
    rng = np.random.default_rng(seed)
    names = [n for n, m in scene.materials.items() if m.material_class != "structure"]
    support = scene.support
    drawn = []
    for _ in range(impacts):
        height = float(rng.uniform(0.5, 4.0))
        material = scene.materials[str(rng.choice(names))]
        drawn.append(
            scene.with_impact(
                material=material,
                restitution=material.restitution,
                radius_m=float(rng.uniform(0.025, 0.1)),
                drop_height_m=height,
                impact_speed_mps=float(np.sqrt(2 * support.gravity_mps2 * height)),
                position_m=float(
                    rng.uniform(support.impact_zone_min_m, support.impact_zone_max_m)
                ),
            )
        )
    drawn = [replace(s, sensors=replace(s.sensors, seed=k)) for k, s in enumerate(drawn)]
    varied = [
        replace(s, sensors=replace(s.sensors.scaled_noise(1.0 + j), seed=s.sensors.seed + j))
        for s in drawn
        for j in range(sensor_settings)
    ]
    out = {}
    times, _ = timed(lambda: simulate_many(drawn, settings=settings), repeats, min_time_s)
    out["impacts_per_s"] = impacts / statistics.median(times)
    cpu = []
    # at least CPU_REPEATS runs: the median of three moves with one run another process slowed
    for _ in range(max(repeats, CPU_REPEATS)):
        start = time.process_time()
        simulate_many(drawn, settings=settings)
        cpu.append(time.process_time() - start)
    out["impacts_per_cpu_s"] = impacts / statistics.median(cpu)
    times, _ = timed(lambda: simulate_many(varied, settings=settings), repeats, min_time_s)
    out["results_per_s_at_settings"] = len(varied) / statistics.median(times)
    out["sensor_settings"] = sensor_settings
    out["impacts"] = impacts
    return out
