"""How well the acceleration channel reads the onset and the contact duration of a lump that
strikes while the beam still rings from the lump before, against one that strikes a quiet beam.
The flow set's supports (``tail-beam evaluate --sets flow``: the nominal and foreign draws,
shipped layout, self-calibrated) each carry one flow of ``--flow-s`` seconds at each rate; every
label resting on the accelerometer is paired with its lump (the suite's matching rule), and per
time since the lump before (under 3 ms: the contacts overlap; 3-20 ms: in the ringing; 20 ms or
more) it prints the onset's error (the label's onset less the contact's start, ms: median, 10th
and 90th percentiles), the read contact duration over the true one and the read moment impulse
over the true one, m (v_in + v_out) x (each: median, and the robust spread of its logarithm,
IQR / 1.35), and the labels' accuracy (Wilson 95 %).

Each flow is read with ``identification.detection.onset_past_ringing`` on (the onset past the
ringing: tail_beam_id.signals.imu_detection.onset_after_ringing); ``--compare`` reads it a
second time with it off, as shipped (the onset at the first sample past the onset threshold in
the look-back whether the beam rings or not), the models and everything else the same. Asserts
nothing, ships nothing.

    python test/bench/bench_ringing_onset.py                       # nominal, 20 lumps/s, ~1 min
    python test/bench/bench_ringing_onset.py --rates 5,20 --foreign 2 --flow-s 60 --compare
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Sequence

import numpy as np

GAPS_S = ((0.0, 0.003, "< 3 ms"), (0.003, 0.02, "3-20 ms"), (0.02, math.inf, ">= 20 ms"))


def paired_rows(flow, labels: Sequence) -> list[tuple[float, float, float, float, bool]]:
    """(time since the lump before s, onset error s, log read/true duration, log read/true
    moment impulse, label right) for every label on the accelerometer paired with a lump."""
    from tail_beam_id.stream.label import match_stamps, match_tolerance_s
    from tail_beam_id.study.overlap_impulses import true_moment_nms

    stamps = flow.lump_stamps_s()
    order = np.sort(stamps)
    gangue = flow.gangue()
    tolerance = match_tolerance_s(flow.params["identification"])
    matching = match_stamps(list(stamps), [lab.impact_stamp_s for lab in labels], tolerance)
    rows = []
    for i, j in matching.pairs:
        label = labels[j]
        read = label.features.get("contact_duration_s")
        if "vibration" not in label.signals or not read:
            continue
        k = int(np.searchsorted(order, stamps[i]))
        since = stamps[i] - order[k - 1] if k > 0 else math.inf
        truth = flow.truths[i]
        moment = true_moment_nms(truth)
        read_moment = label.features.get("moment_impulse_nms", math.nan)
        rows.append(
            (
                float(since),
                float(label.impact_stamp_s - truth["contact_start_stamp"]),
                math.log(float(read) / float(truth["contact_duration_s"])),
                math.log(read_moment / moment) if read_moment > 0.0 else math.nan,
                (label.material == "gangue") == bool(gangue[i]),
            )
        )
    return rows


def log_summary(values: np.ndarray) -> str:
    """The median ratio and the robust spread (IQR / 1.35) of logs of ratios, finite ones."""
    values = values[np.isfinite(values)]
    if not values.size:
        return "   -  spread    -"
    spread = (np.percentile(values, 75) - np.percentile(values, 25)) / 1.35
    return f"{math.exp(np.median(values)):4.2f} spread {spread:4.2f}"


def describe(rows: list[tuple[float, float, float, float, bool]]) -> list[str]:
    """One line per gap class."""
    from tail_beam_id.study.evaluation import wilson

    out = []
    for low, high, name in GAPS_S:
        inside = [r for r in rows if low <= r[0] < high]
        if not inside:
            out.append(f"  {name:9s} no label on the accelerometer")
            continue
        onset_ms = 1e3 * np.array([r[1] for r in inside])
        right = sum(r[4] for r in inside)
        lo, hi = wilson(right, len(inside))
        out.append(
            f"  {name:9s} n {len(inside):4d}  onset error ms {np.median(onset_ms):+6.3f} "
            f"({np.percentile(onset_ms, 10):+6.3f} .. {np.percentile(onset_ms, 90):+6.3f})  "
            f"duration read/true {log_summary(np.array([r[2] for r in inside]))}  "
            f"moment read/true {log_summary(np.array([r[3] for r in inside]))}  "
            f"accuracy {100 * right / len(inside):5.1f} % ({100 * lo:4.1f}-{100 * hi:5.1f})"
        )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rates", default="20", help="lumps per second, comma separated")
    parser.add_argument("--foreign", type=int, default=0, help="foreign supports besides")
    parser.add_argument("--flow-s", type=float, default=30.0, help="each flow's length, s")
    parser.add_argument("--seed", type=int, default=46001)
    parser.add_argument("--compare", action="store_true", help="also the onset of before")
    args = parser.parse_args()

    from tail_beam_id.study.blas_threads import single_blas_thread
    from tail_beam_id.study.flow_evaluation import (
        FlowScene,
        flow_supports,
        identify_flow,
        reading_params,
        scene_flow,
    )
    from tail_beam_sim.config import load_parameters

    single_blas_thread()
    started = time.perf_counter()
    params = load_parameters([])
    scene = FlowScene(duration_s=args.flow_s, boundary_s=args.flow_s / 2, coal_s=0.0)
    rates = [float(r) for r in args.rates.split(",")]
    for s_index, (name, draw) in enumerate(flow_supports(params, args.foreign, args.seed)):
        for r_index, rate in enumerate(rates):
            flow = scene_flow(params, scene, rate, args.seed + 100 * s_index + r_index + 7, draw)
            readers = [("onset past the ringing", True)]
            if args.compare:
                readers.append(("first sample past the threshold", False))
            for reader, on in readers:
                # the recording's section and the reading profile's (merged over it) alike
                for section in (params, flow.params):
                    section["identification"]["detection"]["onset_past_ringing"] = on
                model = reading_params(params, flow, "self-calibrated", "shipped")
                labels, _ = identify_flow(flow, "shipped", None, model)
                print(f"{name}, {rate:g} lumps/s, {len(flow.truths)} lumps: {reader}")
                print("\n".join(describe(paired_rows(flow, labels))))
    print(f"({time.perf_counter() - started:.0f} s)")


if __name__ == "__main__":
    main()
