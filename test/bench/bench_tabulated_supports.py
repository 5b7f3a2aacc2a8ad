"""Identification on supports whose bending modes are given as a table (frequency, modal mass),
as a modal test reports them, spaced and weighted unlike the shipped support's: each support
recorded as one continuous stream of the stream scene's impacts and one of the paper scene's,
at the shipped layout (and with the IMU alone at 2, 5 and 20 kHz), then labelled by the
statistical method after self-calibration on the stream itself, as `tail-beam identify BAG`
does by default. Prints one table (accuracy with its Wilson interval, accuracy for R >= 50 mm,
wrong labels at confidence >= 0.9, extra labels, median compute per impact); asserts nothing.

    python test/bench/bench_tabulated_supports.py      # 80 + 60 impacts on 4 supports, ~6 min
    python test/bench/bench_tabulated_supports.py --shapes sine --imu-alone --paper-count 0
    python test/bench/bench_tabulated_supports.py --camera-hz 1e6   # stamps at the separation

Supports: modes 185 / 560 Hz with 600 kg modal masses each, and 300 / 1350 / 3100 Hz at 350 kg
(tail_beam_id.study.supports.tabulated_modes: no mass coupling with the rigid rotation, so each
mode rings at the frequency named), each with two families of mode shapes: the shipped ones
(small between the hinge and the jack pin, where most particles strike) and sin(k pi x / L), a
plate pinned at both ends, whose modes every strike drives hard: the case where the contact
lasts as long as a mode's half period and its half-sine read-out fails. Every other property
is the nominal support's. The particles follow the Gonthier contact law.
"""

from __future__ import annotations

import argparse
import copy
import sys

import numpy as np

TABLES = {
    "185/560 Hz, 600 kg": ((185.0, 600.0), (560.0, 600.0)),
    "300/1350/3100 Hz, 350 kg": ((300.0, 350.0), (1350.0, 350.0), (3100.0, 350.0)),
}
SHAPES = ("shipped", "sine")
LARGE_M = 0.05  # "large" particles: radius at least this, m
CONFIDENT = 0.9  # a wrong label at least this confident counts as a confident error


def sine_modes(modes: dict, table: tuple[tuple[float, float], ...]) -> dict:
    """tabulated_modes with the k-th shape sin(k pi x / L) over the beam (peak 1)."""
    from tail_beam_id.study.supports import tabulated_modes

    section = tabulated_modes(modes, table)
    x = np.array(section["stations_m"])
    length_m = float(x[-1])
    for k in range(len(table)):
        wave = (k + 1) * np.pi / length_m
        section[f"bending_{k + 1}"]["shape"] = [float(v) for v in np.sin(wave * x)]
        section[f"bending_{k + 1}"]["slope_radpm"] = [float(v) for v in wave * np.cos(wave * x)]
    return section


def layouts(params: dict, imu_alone: bool) -> dict[str, tuple[float, float]]:
    """Layout name -> (IMU rate Hz, accelerometer rate Hz; 0 = none)."""
    shipped = (
        float(params["sensors"]["imu_rate_hz"]),
        float(params["sensors"]["vibration_rate_hz"]),
    )
    chosen = {"shipped": shipped}
    if imu_alone:
        for rate in (2000.0, 5000.0, 20000.0):
            chosen[f"IMU alone {rate / 1e3:.0f} kHz"] = (rate, 0.0)
    return chosen


def main() -> int:
    from tail_beam_id.study.dataset import draw_commands, record_support
    from tail_beam_id.study.evaluation import wilson
    from tail_beam_id.study.runs import foreign_records
    from tail_beam_id.study.supports import SupportDraw, tabulated_modes
    from tail_beam_sim.cli.common import add_config_option
    from tail_beam_sim.config import load_parameters

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=80, help="stream-scene impacts per support")
    parser.add_argument(
        "--paper-count", type=int, default=60, help="paper-scene impacts per support"
    )
    parser.add_argument("--seed", type=int, default=61007, help="impacts' seed")
    parser.add_argument(
        "--imu-alone", action="store_true", help="also the IMU alone at 2, 5 and 20 kHz"
    )
    parser.add_argument(
        "--shapes",
        default=",".join(SHAPES),
        help=f"comma-separated mode shape families of {', '.join(SHAPES)}",
    )
    parser.add_argument(
        "--camera-hz",
        type=float,
        default=None,
        help="the recorded camera's frame rate, Hz (default config/'s; 1e6: stamps at the "
        "separation itself); the identifier is told config/'s, as `tail-beam identify` would be",
    )
    add_config_option(parser)
    args = parser.parse_args()
    params = load_parameters(args.config)
    print(
        "| support | layout | scene | right | R >= 50 mm | wrong at >= 0.9 | extra "
        "| compute ms/impact |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    shapes = [x for x in args.shapes.split(",") if x]
    if not shapes or any(x not in SHAPES for x in shapes):
        parser.error(f"--shapes: {args.shapes!r} must name some of {', '.join(SHAPES)}")
    if args.count < 1 or args.paper_count < 0:
        parser.error("--count must be >= 1 and --paper-count >= 0")
    shipped_vibration_hz = float(params["sensors"]["vibration_rate_hz"])
    supports = [
        (f"{n}, {shape} shapes", t, shape, k)
        for shape in shapes
        for k, (n, t) in enumerate(TABLES.items())
    ]
    for s, (name, table, shape, k) in enumerate(supports):
        for layout, (imu_hz, vibration_hz) in layouts(params, args.imu_alone).items():
            for scene, count in (("stream", args.count), ("paper", args.paper_count)):
                if count == 0:
                    continue
                varied = copy.deepcopy(dict(params))
                varied["modes"] = (
                    tabulated_modes(params["modes"], table)
                    if shape == "shipped"
                    else sine_modes(params["modes"], table)
                )
                varied["scene"]["contact_model"] = "gonthier"
                varied["sensors"]["imu_rate_hz"] = imu_hz
                if args.camera_hz is not None:
                    varied["sensors"]["camera_frame_rate_hz"] = args.camera_hz
                # no accelerometer: the draw says so; the rate stays a valid one
                varied["sensors"]["vibration_rate_hz"] = vibration_hz or shipped_vibration_hz
                draw = SupportDraw({"vibration_rate_hz": vibration_hz}, "gonthier")
                commands = [
                    c for c, _, _ in draw_commands(params, scene, count, args.seed + 100 * k)
                ]
                rng = np.random.default_rng([args.seed, k])
                recorded = record_support(params, draw, varied, commands, rng)
                records = list(
                    foreign_records(
                        params, recorded, s, count, ["statistical"], ["self-calibrated"], layout
                    )
                )
                right = sum(r.correct for r in records)
                low, high = wilson(right, len(records))
                large = [r for r in records if r.radius_m >= LARGE_M]
                confident = sum(
                    1
                    for r in records
                    if r.label is not None and not r.correct and r.label.confidence >= CONFIDENT
                )
                extra = sum(r.extra_labels for r in records)
                cost = np.median([1e3 * r.wall_s for r in records])
                print(
                    f"| {name} | {layout} | {scene} | {100 * right / len(records):.1f} % "
                    f"({100 * low:.1f}-{100 * high:.1f}, n {len(records)}) | "
                    + (
                        f"{100 * sum(r.correct for r in large) / len(large):.1f} % "
                        f"({sum(r.correct for r in large)}/{len(large)})"
                        if large and scene == "stream"
                        else "-"
                    )
                    + f" | {confident} | {extra} | {cost:.1f} |",
                    flush=True,
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
