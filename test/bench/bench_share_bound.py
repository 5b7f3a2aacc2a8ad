"""What the physics allows the gangue share of a sparse flow: the flow set's supports (the
nominal and foreign draws of ``tail-beam evaluate --sets flow``), each lump labelled by a
near-Bayes classifier given its noise-free contact (what the sensors could at best read of it),
against the shipped identifier on the same recorded flow. Prints one table, asserts nothing,
ships nothing.

The classifier is k nearest neighbours (k = 25, standardised logarithms) fitted, per support, on
that support's own lumps of a long flow of another seed: the class-conditional distributions
known exactly, which no identifier has, so its figures bound what labels can do. Feature sets:

- ``J, v, tc``: the moment impulse about the hinge (N m s, m (v_in + v_out) x, what the jack and
  the beam's turning read), the rebound speed (m/s, the camera) and the contact duration (s);
- ``+ x``: also the impact position from the hinge (m), as the camera's impact point gives it.

Per support and rate it prints each reader's per-lump accuracy (Wilson 95 %) and the share's
mean absolute error over the flow's 1 s intervals (hop 0.5 s) against the true share by count,
as the flow set scores it; below them, each reader's accuracy by material and the identifier's
by the time since the lump before. The bound counts isolated lumps' features: at dense rates,
where responses overlap, no sensor reads them one by one, so there it is a bound for reading
lump by lump, not for the flow.

    python test/bench/bench_share_bound.py                      # about 3 minutes here
    python test/bench/bench_share_bound.py --rates 3.3,5 --flow-s 60 --foreign 2
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

NEIGHBOURS = 25
TRAINING_RATE_PER_S = 5.0
TRAINING_SHARE_BY_MASS = 0.5  # the long flow the classifier learns each support from
SEED_OFFSET = 900  # the training flow's seed past the flow set's case seeds


def contact_features(truths: list[dict], with_position: bool) -> np.ndarray:
    """Per lump: log of (moment impulse N m s, rebound speed m/s, contact duration s[, x m])."""
    mass = np.array([t["mass_kg"] for t in truths])
    v_in = np.array([t["impact_speed_mps"] for t in truths])
    v_out = np.array([t["rebound_speed_mps"] for t in truths])
    duration = np.array([t["contact_duration_s"] for t in truths])
    x = np.array([t["position_m"] for t in truths])
    columns = [mass * (v_in + v_out) * x, np.maximum(v_out, 1e-3), duration]
    if with_position:
        columns.append(x)
    return np.log(np.column_stack(columns))


def knn_labels(train_x: np.ndarray, train_g: np.ndarray, test_x: np.ndarray) -> np.ndarray:
    """True where the majority of a test lump's NEIGHBOURS nearest training lumps is gangue."""
    from scipy.spatial import cKDTree

    mean, scale = train_x.mean(axis=0), train_x.std(axis=0)
    tree = cKDTree((train_x - mean) / scale)
    _, near = tree.query((test_x - mean) / scale, NEIGHBOURS)
    return train_g[near].mean(axis=1) > 0.5


def share_mae(stamps_s: np.ndarray, gangue: np.ndarray, said: np.ndarray, intervals) -> float:
    """Mean |share labelled gangue - true share| by count over intervals holding a lump, points."""
    errors = []
    for start, end in intervals:
        inside = (stamps_s >= start) & (stamps_s < end)
        if inside.any():
            errors.append(abs(said[inside].mean() - gangue[inside].mean()))
    return 100.0 * float(np.mean(errors)) if errors else math.nan


def breakdown(said: np.ndarray, gangue: np.ndarray, groups: np.ndarray) -> str:
    """Accuracy per group, '<group> <percent> (n)', a lump without a label counted wrong."""
    parts = []
    for group in sorted(set(groups.tolist())):
        inside = groups == group
        right = int((said[inside] == gangue[inside]).sum())
        parts.append(f"{group} {100.0 * right / inside.sum():.1f} % ({int(inside.sum())})")
    return ", ".join(parts)


def main() -> int:
    from tail_beam_id.stream.label import match_stamps, match_tolerance_s
    from tail_beam_id.study.blas_threads import single_blas_thread
    from tail_beam_id.study.evaluation import wilson
    from tail_beam_id.study.flow import record_sim_flow, true_shares
    from tail_beam_id.study.flow_evaluation import (
        FLOW_SEED,
        FlowScene,
        flow_supports,
        identify_flow,
        reading_params,
        scene_flow,
    )
    from tail_beam_sim.config import load_parameters

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", default="3.3,5", help="lumps per s, comma-separated")
    parser.add_argument("--flow-s", type=float, default=40.0, help="each scored flow's length, s")
    parser.add_argument("--training-s", type=float, default=400.0, help="each support's "
                        "training flow, s of simulation at 5 lumps/s")
    parser.add_argument("--foreign", type=int, default=2, help="foreign supports (flow set's)")
    parser.add_argument("--seed", type=int, default=FLOW_SEED, help="the flow set's seed")
    args = parser.parse_args()
    try:
        rates = [float(r) for r in args.rates.split(",")]
    except ValueError:
        print(f"--rates = {args.rates!r}: must be comma-separated numbers", file=sys.stderr)
        return 2
    if not all(0.0 < r <= 200.0 for r in rates):
        print(f"--rates = {args.rates!r}: each must be in (0, 200] lumps/s", file=sys.stderr)
        return 2
    for name, value in (("--flow-s", args.flow_s), ("--training-s", args.training_s)):
        if not 1.0 <= value <= 3600.0:
            print(f"{name} = {value:g}: must be in [1, 3600] s", file=sys.stderr)
            return 2
    single_blas_thread()
    params = load_parameters([])
    # The flow set's scene stretched to --flow-s: pure coal for its first half, then the share by
    # mass rising to 0.7 over 2 s.
    scene = FlowScene(duration_s=args.flow_s, boundary_s=args.flow_s / 2.0, coal_s=0.0)
    started = time.perf_counter()
    header = (
        f"{'support':10s} {'lumps/s':>7s} {'lumps':>5s}  {'reader':22s} "
        f"{'per-lump accuracy (95 %)':>26s}  {'share MAE pts':>13s}"
    )
    print(header)
    for s_index, (name, draw) in enumerate(flow_supports(params, args.foreign, args.seed)):
        training = record_sim_flow(
            params,
            TRAINING_RATE_PER_S,
            args.training_s,
            0.0,
            0.1,
            TRAINING_SHARE_BY_MASS,
            args.seed + 100 * s_index + SEED_OFFSET,
            draw,
            vibration=False,
        )
        train_g = training.gangue()
        for r_index, rate in enumerate(rates):
            flow = scene_flow(params, scene, rate, args.seed + 100 * s_index + r_index, draw)
            model = reading_params(params, flow, "self-calibrated", "shipped")
            labels, shares = identify_flow(flow, "shipped", None, model)
            intervals = [(s.start_stamp_s, s.end_stamp_s) for s in shares]
            stamps, gangue = flow.lump_stamps_s(), flow.gangue()
            matching = match_stamps(
                list(stamps),
                [lab.impact_stamp_s for lab in labels],
                match_tolerance_s(flow.params["identification"]),
            )
            correct = sum((labels[j].material == "gangue") == gangue[i] for i, j in matching.pairs)
            count = len(stamps) + len(matching.extra)
            errors = [
                abs(s.share - true)
                for s, (true, n) in zip(shares, true_shares(flow, intervals))
                if s.share is not None and n
            ]
            rows = [("shipped identifier", correct, count, 100.0 * float(np.mean(errors)))]
            identified = np.full(len(stamps), -1.0)  # 1 gangue, 0 coal, -1 no label
            for i, j in matching.pairs:
                identified[i] = float(labels[j].material == "gangue")
            said_by = {"shipped identifier": identified}
            for reader, point in (("ideal on J, v, tc", False), ("ideal on J, v, tc + x", True)):
                said = knn_labels(
                    contact_features(training.truths, point),
                    train_g,
                    contact_features(flow.truths, point),
                )
                said_by[reader] = said.astype(float)
                rows.append(
                    (
                        reader,
                        int((said == gangue).sum()),
                        len(gangue),
                        share_mae(stamps, gangue, said.astype(float), intervals),
                    )
                )
            for reader, right, total, mae in rows:
                low, high = wilson(right, total)
                accuracy = f"{100 * right / total:5.1f} % ({100 * low:4.1f}-{100 * high:5.1f})"
                print(
                    f"{name:10s} {rate:7g} {len(stamps):5d}  {reader:22s} {accuracy:>26s}  "
                    f"{mae:13.1f}",
                    flush=True,
                )
            materials = np.array([t["material"] for t in flow.truths])
            for reader, said in said_by.items():
                print(f"{'':24s}{reader:22s} by material: {breakdown(said, gangue, materials)}")
            order = np.argsort(stamps)
            before = np.full(len(stamps), np.inf)
            before[order[1:]] = np.diff(stamps[order])
            gaps = np.select(
                [before < 0.02, before < 0.1, before < 0.3], ["<20 ms", "20-100 ms", "0.1-0.3 s"],
                ">=0.3 s",
            )
            print(f"{'':24s}{'shipped identifier':22s} by time since the lump before: "
                  f"{breakdown(identified, gangue, gaps)}", flush=True)
    print(f"({time.perf_counter() - started:.0f} s; training flows {args.training_s:g} s per "
          f"support at {TRAINING_RATE_PER_S:g} lumps/s, k = {NEIGHBOURS})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
