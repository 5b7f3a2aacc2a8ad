"""``tail-beam caving``: a face drawn through its sequence once per closing rule, each rule fed
by the true lumps, by stand-in labels or by the identifier's labels on a sensor layout's
simulated samples (``identified:<layout>``); a table of top-coal recovery and gangue content with
95 % intervals over seeds, and the chart of one against the other (docs/caving.md)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from tail_beam_id.study.caving import (
    ALL_SOURCES,
    FIELD_TRIAL,
    SOURCES,
    Shortfall,
    Summary,
    run_study,
    shortfalls,
    summarise,
    write_chart,
)
from tail_beam_id.study.caving_latency import latency_study, parse_latencies, write_latency_chart
from tail_beam_id.study.caving_pipeline import LUMP_MODES, layout_of, pipeline_parameters
from tail_beam_sim.errors import InputError, require_int, require_output_file
from tail_beam_sim.physics.face import FaceParams, load_face_parameters
from tail_beam_sim.spec import DRAWING_SEQUENCES, MAX_FACE_SUPPORTS

__all__ = ["register", "run", "table"]

DEFAULT_CHART = "out/caving/recovery_vs_gangue.png"  # out/ is ignored by git
DEFAULT_LATENCY_CHART = "out/caving/recovery_vs_latency.png"


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "caving",
        help="top-coal recovery against gangue content of the caving windows' closing rules",
    )
    parser.add_argument(
        "--supports", type=int, help=f"supports drawn, 1-{MAX_FACE_SUPPORTS} (default: config, 9)"
    )
    parser.add_argument("--sequence", choices=DRAWING_SEQUENCES, help="drawing sequence")
    parser.add_argument("--group-size", type=int, help="supports per group (default: config)")
    parser.add_argument("--seeds", type=int, help="seeds run (default: caving.seeds)")
    parser.add_argument("--seed", type=int, help="first seed (default: face.seed)")
    parser.add_argument("--rules", help="rules, comma-separated (default: all)")
    parser.add_argument(
        "--sources",
        default=",".join(SOURCES),
        help="label sources, comma-separated: truth, stand-in, identified:<layout> with layout "
        "shipped, imu, pressure or impact_point (the drawn flow through that layout's simulated "
        f"sensors and the identifier; far slower) (default {','.join(SOURCES)})",
    )
    parser.add_argument(
        "--jobs", type=int, default=1, help="runs at once in worker processes (default 1)"
    )
    parser.add_argument(
        "--lumps",
        choices=LUMP_MODES,
        help="identified sources: the lumps of each drawn cell, struck (those striking the beam, "
        "caving.labels.impacts_per_tonne) or drawn (its whole mass) (default: "
        "caving.pipeline.lumps)",
    )
    parser.add_argument(
        "--oracle-curve",
        action="store_true",
        help="also run the oracle at each of caving.oracle_curve_levels on the same seeds, "
        "draw its curve and give each rule's recovery short of it at no more gangue content",
    )
    parser.add_argument(
        "--latencies",
        metavar="S,S,...",
        help="instead: the study on the stand-in labels at each of these label latencies (s), "
        "and the chart of recovery and gangue content against latency (--latency-chart)",
    )
    parser.add_argument(
        "--latency-chart",
        default=DEFAULT_LATENCY_CHART,
        help=f"with --latencies, the chart to write (default {DEFAULT_LATENCY_CHART}; '' none)",
    )
    parser.add_argument(
        "--chart", default=DEFAULT_CHART, help=f"chart to write (default {DEFAULT_CHART}; '' none)"
    )
    parser.add_argument(
        "--config",
        action="append",
        default=[],
        metavar="YAML",
        help="ROS 2 parameter file overriding config/face.yaml (repeatable; later wins)",
    )
    parser.set_defaults(func=run)


def _names(text: str | None, field: str, allowed: tuple[str, ...] | None = None) -> list[str]:
    names = [n.strip() for n in (text or "").split(",") if n.strip()]
    if not names:
        raise InputError(field, text, "must name at least one")
    for name in names:
        if allowed is not None and name not in allowed:
            raise InputError(field, name, f"must be among {', '.join(allowed)}")
    return names


class Progress:
    """``done of total runs`` rewritten in place on a terminal; nothing otherwise."""

    def __init__(self, stream: Any) -> None:
        self.stream = stream
        self.enabled = bool(getattr(stream, "isatty", lambda: False)())
        self.shown = False
        self.start = time.perf_counter()
        self.runs = ""
        self.lines = False  # a line per run where no terminal shows the bar (long runs)

    def update(self, done: int, total: int) -> None:
        self.runs = f"{done} of {total} runs ({100 * done / total:.0f} %)"
        if self.enabled:
            self.stream.write(f"\rcaving: {self.runs}\033[K")
            self.stream.flush()
            self.shown = True
        elif self.lines:
            wall = time.perf_counter() - self.start
            self.stream.write(f"caving: {self.runs}, {wall:.0f} s wall\n")
            self.stream.flush()

    def window(self, run: str, windows: int, clock_s: float) -> None:
        """After each window of an identified run: rewritten in place on a terminal, one line
        otherwise (these runs take minutes)."""
        wall = time.perf_counter() - self.start
        text = f"caving: run {run}: {windows} window(s), {clock_s:.0f} s drawn, {wall:.0f} s wall"
        if self.enabled:
            self.stream.write(f"\r{text}\033[K")
            self.shown = True
        else:
            self.stream.write(text + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.shown:
            self.stream.write("\n")
            self.stream.flush()


def _pct(value: float) -> str:
    return f"{100 * max(value, 0.0):5.1f}"  # above 100: coal of the undrawn margins drawn too


def _ranges(s: Summary) -> tuple[str, str]:
    """Recovery and gangue content (%) of ``s``, each with its interval: ``mean [low, high]``."""
    rec, gan = s.recovery_interval, s.gangue_interval
    return (
        f"{_pct(s.recovery)} [{_pct(rec[0])}, {_pct(rec[1])}]",
        f"{_pct(s.gangue_content)} [{_pct(gan[0])}, {_pct(gan[1])}]",
    )


def _points(value: float) -> str:
    return f"{100 * value:5.1f}" if value == value else "    -"


def table(summaries: list[Summary], short: dict[tuple[str, str], Shortfall] | None = None) -> str:
    """The study's table: per rule and source, recovery and gangue content (%) with their 95 %
    intervals over seeds, the mean drawing time (s), and with ``short`` the recovery short of
    the oracle's curve (points); the field trial last."""
    w = max([9] + [len(s.source) for s in summaries])
    lines = [
        f"{'rule':<15} {'source':<{w}} {'seeds':>5}  {'recovery %':<22} {'gangue content %':<22}"
        f" {'drawing s':>9}" + ("  short of oracle curve, pts" if short else ""),
    ]
    for s in summaries:
        gap = (short or {}).get((s.rule, s.source))
        tail = ""
        if gap is not None:
            low, high = gap.interval
            tail = f"  {_points(gap.mean)} [{_points(low)}, {_points(high)}]"
            if gap.seeds < s.seeds:
                tail += f" ({gap.seeds} of {s.seeds} seeds: less gangue than the curve's least)"
        rec, gan = _ranges(s)
        lines.append(
            f"{s.rule:<15} {s.source:<{w}} {s.seeds:>5}  {rec:<22} {gan:<22} {s.drawing_s:>9.0f}"
            + tail
        )
    name, recovery, gangue = FIELD_TRIAL
    lines.append(f"{name}: recovery {100 * recovery:.2f} %, gangue content {100 * gangue:.2f} %")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    params = load_face_parameters(tuple(args.config))
    face = FaceParams.from_params(
        params, supports=args.supports, sequence=args.sequence, group_size=args.group_size
    )
    caving = params.get("caving") or {}
    seeds = require_int(
        "--seeds", caving.get("seeds") if args.seeds is None else args.seeds, 1, 1000
    )
    first = face.seed if args.seed is None else require_int("--seed", args.seed, 0)
    rules = None if args.rules is None else _names(args.rules, "--rules")
    if args.latencies is not None:
        return _run_latencies(args, face, caving, range(first, first + seeds), rules)
    sources = _names(args.sources, "--sources")
    for source in sources:
        layout_of(source)  # a bad layout refused by name
        if source not in ALL_SOURCES:
            raise InputError("--sources", source, f"must be among {', '.join(ALL_SOURCES)}")
    physics = None
    if any(layout_of(s) for s in sources):
        physics = pipeline_parameters(tuple(args.config))
        if args.lumps is not None:
            caving = {
                **caving,
                "pipeline": {**(caving.get("pipeline") or {}), "lumps": args.lumps},
            }
    chart = _chart_path(args.chart) if args.chart else None  # refused before the runs
    progress = Progress(sys.stderr)
    progress.lines = physics is not None
    start = time.perf_counter()
    try:
        runs = run_study(
            face,
            caving,
            range(first, first + seeds),
            rules,
            sources,
            progress.update,
            physics,
            progress.window,
            require_int("--jobs", args.jobs, 1, 64),
            args.oracle_curve,
        )
    finally:
        progress.close()
    wall_s = time.perf_counter() - start
    summaries = summarise(runs)
    print(
        f"caving: {face.supports} supports, {face.sequence} in groups of {face.group_size}, "
        f"{face.top_coal_height_m:g} m top coal; {seeds} seed(s) from {first}"
    )
    print(table(summaries, shortfalls(runs)))
    drawn_s = sum(r.drawing_s for r in runs)
    print(
        f"simulated {drawn_s:.0f} s of drawing in {wall_s:.1f} s of wall time "
        f"({drawn_s / wall_s:.0f}x real time)"
    )
    for source in sources:
        mine = [r for r in runs if r.source == source and layout_of(source) is not None]
        if mine:
            drawn, wall = sum(r.drawing_s for r in mine), sum(r.wall_s for r in mine)
            lumps = (caving.get("pipeline") or {}).get("lumps", "struck")
            print(
                f"{source} ({lumps} lumps): {drawn:.0f} s of drawing in {wall:.1f} s of wall "
                f"time ({drawn / wall:.1f}x real time)"
            )
    timed_out = sum(s.timed_out for s in summaries)
    if timed_out:
        print(
            f"caving: {timed_out} window(s) ran to face.max_window_s without closing",
            file=sys.stderr,
        )
    if chart is not None:
        path = write_chart(summaries, chart)
        print(f"chart: {path}")
    return 0


def _run_latencies(
    args: argparse.Namespace,
    face: FaceParams,
    caving: dict[str, Any],
    seeds: range,
    rules: list[str] | None,
) -> int:
    """``--latencies``: each rule on the stand-in labels at each latency; a table and chart."""
    if args.sources != ",".join(SOURCES) or args.oracle_curve or args.lumps is not None:
        raise InputError(
            "--latencies",
            args.latencies,
            "runs on the stand-in labels alone: without --sources, --oracle-curve and --lumps",
        )
    latencies = parse_latencies(args.latencies)
    chart = _chart_path(args.latency_chart) if args.latency_chart else None
    progress = Progress(sys.stderr)
    try:
        rows = latency_study(
            face,
            caving,
            seeds,
            latencies,
            rules,
            require_int("--jobs", args.jobs, 1, 64),
            progress.update,
        )
    finally:
        progress.close()
    print(
        f"caving: {face.supports} supports, {face.sequence}; stand-in labels at each latency; "
        f"{len(seeds)} seed(s) from {seeds.start}"
    )
    print(f"{'latency s':>9}  {'rule':<15} {'recovery %':<22} {'gangue content %'}")
    for row in rows:
        s = row.summary
        rec, gan = _ranges(s)
        print(f"{row.latency_s:>9g}  {s.rule:<15} {rec:<22} {gan}")
    if chart is not None:
        print(f"chart: {write_latency_chart(rows, chart)}")
    return 0


def _chart_path(text: str) -> str:
    path = Path(text)
    if path.parent != Path(".") and not path.parent.exists():
        try:
            path.parent.mkdir(parents=True)
        except OSError as exc:
            raise InputError(
                "--chart", text, f"its folder cannot be made ({exc.strerror})"
            ) from None
    require_output_file("--chart", path)
    return text


def main(argv: list[str] | None = None) -> int:
    """Run the verb alone (``python -m tail_beam_id.cli.caving_cmd``), as ``tail-beam caving``
    does once the package's entry points are installed."""
    parser = argparse.ArgumentParser(prog="tail-beam")
    sub = parser.add_subparsers(dest="command", required=True)
    register(sub)
    args = parser.parse_args(["caving", *(sys.argv[1:] if argv is None else argv)])
    try:
        return run(args)
    except InputError as exc:
        print(f"tail-beam caving: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
