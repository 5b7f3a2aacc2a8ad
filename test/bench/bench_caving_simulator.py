"""How fast the flow simulator alone runs as the caving study's identified sources drive it: a
support's FlowSimulator (the pipeline's parameters, shipped layout) struck by Poisson lumps and
advanced cell by cell (the face's cells last about 0.06 s), no identifier. Prints the CPU time
(process time, median of repeated runs) and the stream time over it; asserts nothing.

    python test/bench/bench_caving_simulator.py                       # 15 and 200 lumps/s
    python test/bench/bench_caving_simulator.py --rates 15 --seconds 60 --repeats 5

The machine is shared: compare figures taken alternately, and say so when quoting them.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from tail_beam_id.study.caving_pipeline import LEAD_S, Pipeline, pipeline_parameters


def run(pipeline: Pipeline, rate: float, seconds: float, cell_s: float, seed: int) -> int:
    """One support's stream: Poisson lumps (rate per s, uniform in each cell), the simulator
    advanced to each cell's end; returns the lumps struck."""
    sim = pipeline.simulator(seed)
    rng = np.random.default_rng(seed)
    sim.advance(LEAD_S - 1e-9)
    t, lumps = LEAD_S, 0
    while t < seconds:
        for stamp in np.sort(rng.uniform(t, t + cell_s, rng.poisson(rate * cell_s))):
            lumps += 1
            command, _ = pipeline.command(bool(rng.random() < 0.4), rng.random(5), f"l{lumps}")
            sim.submit(command, contact_stamp_s=stamp)
        t += cell_s
        sim.advance(t)
    return lumps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", nargs="+", type=float, default=[15.0, 200.0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--cell-s", type=float, default=0.0583)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    pipeline = Pipeline(pipeline_parameters(), "shipped")
    run(pipeline, 15.0, 1.0, args.cell_s, 0)  # warm-up: the solver's tables
    print(f"{'lumps/s':>8} {'stream s':>9} {'lumps':>6} {'CPU s':>7} {'x real time (CPU)':>18}")
    for rate in args.rates:
        seconds = args.seconds if rate <= 50.0 else args.seconds / 4
        cpus, lumps = [], 0
        for _ in range(args.repeats):
            start = time.process_time()
            lumps = run(pipeline, rate, seconds, args.cell_s, 5)
            cpus.append(time.process_time() - start)
        cpu = statistics.median(cpus)
        print(f"{rate:8g} {seconds:9g} {lumps:6d} {cpu:7.2f} {seconds / cpu:18.1f}")


if __name__ == "__main__":
    main()
