"""How fast the caving study's identified sources run against real time: a face drawn through
its sequence with the SPRT closing every window on the identifier's labels from a sensor
layout's simulated samples (the drawn flow through the physics core, the sensors and the
identifier), the simulated drawing time over the wall time and over the process's CPU time,
median of repeated runs. Prints a table, asserts nothing.

    python test/bench/bench_caving_pipeline.py                          # 3 supports, imu
    python test/bench/bench_caving_pipeline.py --supports 9 --layouts shipped,imu,pressure
    python test/bench/bench_caving_pipeline.py --supports 1 --lumps drawn --max-window-s 10

The issue's target is >= 20x real time for a group of 9 supports through one round. The CPU
ratio is the one to compare on a machine shared with other work.
"""

from __future__ import annotations

import argparse
import statistics
import time

from tail_beam_id.caving.rules import rule_factories
from tail_beam_id.study.caving import LabelModel, run_one
from tail_beam_id.study.caving_pipeline import Pipeline, pipeline_parameters
from tail_beam_sim.physics.face import FaceParams, load_face_parameters


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--supports", type=int, default=3)
    parser.add_argument("--layouts", default="imu")
    parser.add_argument("--lumps", default="struck", choices=("struck", "drawn"))
    parser.add_argument("--rule", default="sprt")
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--max-window-s", type=float, default=None)
    args = parser.parse_args()
    params = load_face_parameters()
    face = FaceParams.from_params(params, supports=args.supports)
    if args.max_window_s is not None:
        face = face.with_changes(max_window_s=args.max_window_s)
    caving = params["caving"]
    maker = rule_factories(caving)[args.rule]
    model = LabelModel.from_params(caving["labels"])
    physics = pipeline_parameters()
    print(
        f"{args.supports} supports, {face.sequence}, rule {args.rule}, {args.lumps} lumps "
        f"({caving['labels']['impacts_per_tonne']:g} per tonne when struck), "
        f"{face.mass_rate_kgps:g} kg/s"
    )
    print(
        f"{'layout':<13} {'drawing s':>9} {'lumps/s':>8} {'wall s':>8} {'x real time':>11} "
        f"{'CPU s':>8} {'x real time (CPU)':>17}"
    )
    for layout in args.layouts.split(","):
        pipeline = Pipeline(physics, layout, args.lumps, caving["labels"]["impacts_per_tonne"])
        walls, cpus, drawn, lumps = [], [], 0.0, 0
        for seed in range(args.repeats):
            counted: list[int] = []
            start, cpu = time.perf_counter(), time.process_time()
            run = run_one(
                face,
                maker,
                args.rule,
                f"identified:{layout}",
                model,
                seed,
                pipeline,
                lambda windows, clock_s: counted.append(windows),
            )
            walls.append(time.perf_counter() - start)
            cpus.append(time.process_time() - cpu)
            drawn = run.drawing_s
            lumps = run.lumps
        wall, cpu = statistics.median(walls), statistics.median(cpus)
        print(
            f"{layout:<13} {drawn:>9.0f} {lumps / drawn:>8.1f} {wall:>8.1f} {drawn / wall:>11.1f} "
            f"{cpu:>8.1f} {drawn / cpu:>17.1f}"
        )


if __name__ == "__main__":
    main()
