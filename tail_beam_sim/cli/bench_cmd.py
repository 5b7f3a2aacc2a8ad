"""``tail-beam bench``: speed against accuracy of every solver and tier, charted.

Prints a table (median time, spread, ratio to Radau at rtol 1e-8, relative errors against a
converged Radau reference, Pareto front marked ``*``), the tiers against the richest model,
the batch path's throughput, the real-time factor and ``simulate()`` as a whole (every sensor
on) against Radau, stage by stage; writes log-log PNG charts of time
against error with the Pareto front. The default run takes about a minute; ``--full`` adds
finer steps, looser and tighter tolerances and more repeats.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from tail_beam_sim.cli.common import add_impact_options, fidelity_from_args, scene_from_args
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics import benchmark as bench
from tail_beam_sim.physics.fidelity import TIERS, structure_for
from tail_beam_sim.physics.simulate import build_problem

TARGET_SPEEDUP = 1000.0
TARGET_ERROR = 0.01
TARGET_SIMULATE_SPEEDUP = 100.0  # the whole simulate(), every sensor on, over Radau rtol 1e-8
TARGET_MANY_PER_S = 5000.0  # simulate_many, full streams of distinct impacts, one core


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "bench",
        help="time and error of every solver and tier against a converged reference, charted",
    )
    add_impact_options(parser)
    parser.add_argument(
        "--full",
        action="store_true",
        help="more settings (finer steps, looser and tighter tolerances) and 5 repeats",
    )
    parser.add_argument(
        "--repeats",
        type=int,
        help=(
            "at least this many timed runs per setting after a warm-up, more for fast ones "
            "(default 3, 5 with --full)"
        ),
    )
    parser.add_argument(
        "--min-time-s",
        type=float,
        default=bench.MIN_TIMED_S,
        help="keep timing a fast setting until this much time is spent, s (default 0.3)",
    )
    parser.add_argument(
        "--structure",
        choices=("rigid", "modal"),
        default="rigid",
        help="structure of the solver comparison (default rigid)",
    )
    parser.add_argument(
        "--solvers",
        nargs="+",
        metavar="NAME",
        help="only these solvers (Radau at rtol 1e-8 is always kept as the baseline)",
    )
    parser.add_argument(
        "--batch-impacts",
        type=int,
        default=100_000,
        help="impacts in the batch summaries run (streams: a tenth); 0 skips the batch",
    )
    parser.add_argument(
        "--no-tiers",
        action="store_true",
        help="skip the tier comparison (it needs a modal Radau reference, ~10 s)",
    )
    parser.add_argument(
        "--out",
        default="out/bench",
        metavar="DIR",
        help="directory of the PNG charts (default out/bench)",
    )
    parser.add_argument(
        "--no-simulate",
        action="store_true",
        help="skip timing simulate() as a whole (every sensor) against Radau",
    )
    parser.add_argument(
        "--simulate-impacts",
        type=int,
        default=200,
        help=(
            "distinct impacts in the simulate_many throughput run (full streams, every sensor; "
            "one batch, as a data set gives them); 0 skips it"
        ),
    )
    parser.add_argument("--no-plot", action="store_true", help="do not write charts")
    parser.add_argument(
        "--json",
        action="store_true",
        help="print one JSON object with every figure instead of tables",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    repeats = args.repeats if args.repeats is not None else (5 if args.full else 3)
    if repeats < 1:
        raise InputError("--repeats", repeats, "must be >= 1")
    if args.batch_impacts < 0:
        raise InputError("--batch-impacts", args.batch_impacts, "must be >= 0")
    if args.simulate_impacts < 0:
        raise InputError("--simulate-impacts", args.simulate_impacts, "must be >= 0")
    scene = scene_from_args(args)
    _, _, settings = fidelity_from_args(
        argparse.Namespace(config=args.config, outputs=None, tolerance=None, tier=None)
    )
    settings_list = bench.QUICK_SETTINGS + (bench.FULL_EXTRA if args.full else [])
    if args.solvers:
        from tail_beam_sim.physics.solvers import SOLVERS

        unknown = sorted(set(args.solvers) - set(SOLVERS))
        if unknown:
            raise InputError(
                "--solvers", unknown[0], f"must be among {', '.join(sorted(SOLVERS))}"
            )
        settings_list = [
            s
            for s in settings_list
            if s[0] in args.solvers or s == (bench.BASELINE[0], bench.BASELINE[1])
        ]
    quiet = args.json

    def progress(message: str) -> None:
        if not quiet:
            print(f"  ... {message}", file=sys.stderr, flush=True)

    structure = structure_for(TIERS[args.structure], scene.support, settings.modes)
    problem = build_problem(
        scene.support, scene.impact, scene.contact_model, scene.window_s, structure=structure
    )
    imu_rate = scene.sensors.imu_rate_hz
    progress(f"reference: Radau rtol {bench.REFERENCE_RTOL:g} on the {args.structure} structure")
    reference, reference_error = bench.reference_solution(problem, imu_rate)
    rows = bench.solver_rows(
        problem, reference, imu_rate, settings_list, repeats, progress, args.min_time_s
    )
    baseline_s = next(
        r.median_s
        for r in rows
        if (r.name, r.setting) == (bench.BASELINE[0], bench.describe(bench.BASELINE[1]))
    )
    report: dict[str, Any] = {
        "scene": {
            k: scene.impact.__dict__[k]
            for k in ("radius_m", "impact_speed_mps", "position_m", "restitution")
        }
        | {"material": scene.impact.material.name},
        "structure": args.structure,
        "repeats": repeats,
        "min_time_s": args.min_time_s,
        "reference_rtol": bench.REFERENCE_RTOL,
        "reference_error_bound": reference_error,
        "radau_1e-8_median_s": baseline_s,
        "solvers": [r.as_dict() for r in rows],
    }
    tier_rows: list[bench.Row] = []
    if not args.no_tiers:
        progress("tiers against a modal Radau reference")
        tier_rows, tier_reference_error = bench.tier_rows(
            scene, settings, repeats, baseline_s, args.min_time_s
        )
        report["tiers"] = [r.as_dict() for r in tier_rows]
        report["tier_reference_error_bound"] = tier_reference_error
    if args.batch_impacts:
        progress(f"batch path, {args.batch_impacts} impacts")
        report["batch"] = bench.batch_throughput(
            scene, settings, args.batch_impacts, repeats, min_time_s=args.min_time_s
        )
    progress("real-time factor")
    report["real_time"] = bench.real_time_factor(scene, settings, repeats, args.min_time_s)
    if not args.no_simulate:
        progress("simulate() with every sensor against Radau rtol 1e-8")
        report["simulate"] = bench.simulate_speed(scene, settings, repeats, args.min_time_s)
        if args.simulate_impacts:
            progress(f"simulate_many, {args.simulate_impacts} impacts")
            report["simulate"]["many"] = bench.simulate_throughput(
                scene, settings, args.simulate_impacts, repeats, min_time_s=args.min_time_s
            )
    if not args.no_plot:
        report["charts"] = [str(p) for p in write_charts(Path(args.out), rows, tier_rows)]
    if args.json:
        print(json.dumps(report))
    else:
        print_report(report, rows, tier_rows)
    return 0


def print_report(
    report: dict[str, Any], rows: list[bench.Row], tier_rows: list[bench.Row]
) -> None:
    scene = report["scene"]
    print(
        f"{scene['material']} R = {scene['radius_m'] * 1e3:g} mm at "
        f"{scene['impact_speed_mps']:.3f} m/s, {scene['position_m']:g} m from the hinge; "
        f"{report['structure']} structure; median of >= {report['repeats']} runs (fast settings: "
        f"{report['min_time_s']:g} s of runs); errors against Radau rtol "
        f"{report['reference_rtol']:g} "
        f"(its own error bound {report['reference_error_bound']:.1e}); Radau rtol 1e-8 took "
        f"{report['radau_1e-8_median_s'] * 1e3:.1f} ms"
    )
    print(_table(rows))
    hybrid = next((r for r in rows if (r.name, r.setting) == ("hybrid", "default")), None)
    if hybrid is not None:
        speedup = 1.0 / hybrid.ratio
        ok = speedup >= TARGET_SPEEDUP and bench.worst_target_error(hybrid) <= TARGET_ERROR
        print(
            f"default solver (hybrid): {speedup:.0f} x faster than Radau rtol 1e-8, rebound error "
            f"{hybrid.errors['rebound']:.1e}, "
            f"peak jack pressure change error {hybrid.errors['peak_pressure']:.1e} (targets: >= "
            f"{TARGET_SPEEDUP:g} x, <= {TARGET_ERROR:g}): "
            f"{'met' if ok else 'NOT met'}"
        )
    if tier_rows:
        print(
            "\ntiers (default solver each) against the modal structure by Radau rtol 1e-10 "
            f"(bound {report['tier_reference_error_bound']:.1e}):"
        )
        print(_table(tier_rows))
    if "batch" in report:
        b = report["batch"]
        print(
            f"\nbatch path (one core): summaries {b['rigid_summaries_per_s']:,.0f} impacts/s "
            f"rigid, {b['modal_summaries_per_s']:,.0f} modal; "
            f"full 0.05 s noisy streams {b['rigid_streams_per_s']:,.0f} impacts/s rigid, "
            f"{b['modal_streams_per_s']:,.0f} modal"
        )
    rt = report["real_time"]
    print(
        "real-time factor, one impact's 0.05 s of sensor streams at the default rates: rigid "
        f"{rt['rigid_real_time_factor']:.0f} x, modal {rt['modal_real_time_factor']:.0f} x"
    )
    if "simulate" in report:
        print_simulate(report["simulate"])
    for chart in report.get("charts", []):
        print(f"wrote {chart}")


def print_simulate(figures: dict[str, Any]) -> None:
    """The simulate() section: speed-ups over Radau, rebound error, per-stage medians."""
    ok = figures["speedup"] >= TARGET_SIMULATE_SPEEDUP and figures["rebound_error"] <= TARGET_ERROR
    print(
        f"\nsimulate() (default tier, every sensor of the layout): {figures['speedup']:.0f} x "
        f"faster than Radau rtol 1e-8 on the same impact "
        f"({figures['speedup_no_vibration']:.0f} x without the accelerometer), rebound error "
        f"{figures['rebound_error']:.1e} (targets: >= {TARGET_SIMULATE_SPEEDUP:g} x with every "
        f"sensor, <= {TARGET_ERROR:g}): {'met' if ok else 'NOT met'}"
    )
    stages = ("plan", "solve", "sensors", "sensors_no_vibration", "simulate", "radau")
    print(
        "  medians, ms: "
        + ", ".join(f"{name} {figures[f'{name}_median_s'] * 1e3:.3f}" for name in stages)
    )
    if "many" in figures:
        many = figures["many"]
        met = many["impacts_per_cpu_s"] >= TARGET_MANY_PER_S
        print(
            f"simulate_many (one process, full streams, every sensor, {many['impacts']} "
            f"impacts at once): {many['impacts_per_s']:,.0f} distinct impacts/s, "
            f"{many['impacts_per_cpu_s']:,.0f} per CPU second (target >= "
            f"{TARGET_MANY_PER_S:,.0f} on one core): {'met' if met else 'NOT met'}; each impact "
            f"at {many['sensor_settings']} sensor settings (solved once): "
            f"{many['results_per_s_at_settings']:,.0f} results/s"
        )


def _table(rows: list[bench.Row]) -> str:
    header = (
        f"{'':1} {'solver':8} {'setting':28} {'median ms':>10} {'spread':>7} {'x Radau':>9} "
        + " ".join(f"{m:>13}" for m in bench.METRICS)
    )
    lines = [header]
    for r in sorted(rows, key=lambda r: r.median_s):
        lines.append(
            f"{'*' if r.pareto else ' '} {r.name:8} {r.setting:28} {r.median_s * 1e3:10.3f} "
            f"{r.spread:6.0%} {r.ratio:9.2e} "
            + " ".join(f"{r.errors[m]:13.2e}" for m in bench.METRICS)
        )
    return "\n".join(lines)


def write_charts(directory: Path, rows: list[bench.Row], tier_rows: list[bench.Row]) -> list[Path]:
    """Log-log time (ratio to Radau rtol 1e-8) against each error, Pareto front joined."""
    from tail_beam_sim.plotting import pyplot, save_figure

    plt = pyplot()
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for label, group, filename in (
        ("solvers", rows, "bench_solvers.png"),
        ("tiers", tier_rows, "bench_tiers.png"),
    ):
        if not group:
            continue
        figure, axes = plt.subplots(2, 2, figsize=(12, 9))
        for axis, metric in zip(axes.flat, bench.METRICS):
            floor = 1e-16
            for row in group:
                error = max(row.errors[metric], floor)
                axis.scatter(
                    row.ratio, error, s=30, color="tab:red" if row.name == "hybrid" else "tab:blue"
                )
                axis.annotate(
                    f"{row.name} {row.setting}" if row.setting != "default" else row.name,
                    (row.ratio, error),
                    fontsize=6,
                )
            front = bench.mark_pareto(group, lambda r, m=metric: max(r.errors[m], floor))
            axis.plot(
                [r.ratio for r in front],
                [max(r.errors[metric], floor) for r in front],
                "k--",
                lw=1,
                label="Pareto front",
            )
            axis.set_xscale("log")
            axis.set_yscale("log")
            axis.set_xlabel("time per impact / Radau rtol 1e-8 (same run)")
            axis.set_ylabel(f"relative error: {metric}")
            axis.grid(True, which="both", alpha=0.3)
            axis.legend(fontsize=7)
        figure.suptitle(f"tail_beam {label}: time against error")
        figure.tight_layout()
        written.append(save_figure(figure, directory / filename, 110, "--out"))
    return written
