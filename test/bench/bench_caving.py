"""How much faster than real time the caving study runs: a face (default the shipped group of 9
supports, one full round) drawn through its sequence with a rule closing every window, the
simulated drawing time over the wall time, median of repeated runs. Prints a table, asserts
nothing.

    python test/bench/bench_caving.py                       # 9 supports, 5 repeats
    python test/bench/bench_caving.py --supports 150 --repeats 1

Rules timed: the oracle on the truth (the drawing model and the truth only) and the SPRT on
the stand-in labels (the model plus a label per lump struck); the target is >= 20x.
"""

from __future__ import annotations

import argparse
import statistics
import time

from tail_beam_id.caving.rules import rule_factories
from tail_beam_id.study.caving import LabelModel, run_one
from tail_beam_sim.physics.face import FaceParams, load_face_parameters


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--supports", type=int, default=9)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    params = load_face_parameters()
    face = FaceParams.from_params(params, supports=args.supports)
    caving = params["caving"]
    makers = rule_factories(caving)
    model = LabelModel.from_params(caving["labels"])
    print(f"{args.supports} supports, {face.sequence}, {face.cell_size_m:g} m cells")
    print(
        f"{'rule':<8} {'source':<9} {'drawing s':>10} {'wall s (median)':>16} {'x real time':>12}"
    )
    for rule, source in (("oracle", "truth"), ("sprt", "stand-in")):
        walls, drawn = [], 0.0
        for seed in range(args.repeats):
            start = time.perf_counter()
            run = run_one(face, makers[rule], rule, source, model, seed)
            walls.append(time.perf_counter() - start)
            drawn = run.drawing_s
        wall = statistics.median(walls)
        print(f"{rule:<8} {source:<9} {drawn:>10.0f} {wall:>16.3f} {drawn / wall:>12.0f}")


if __name__ == "__main__":
    main()
