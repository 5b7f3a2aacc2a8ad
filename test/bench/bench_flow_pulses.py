"""How many of a dense flow's contacts the accelerometer's pulse detector finds, without and
with the second detector that scans what the ringing's predictor leaves, against what the
prediction errors hold. The flow set's flows (tail_beam_id.study.flow_evaluation: the nominal
support and foreign ones, shipped layout) are identified as ``tail-beam evaluate --sets flow``
reads them (self-calibrated), with ``identification.detection.vibration_innovations`` off and on;
for each, the share of the lumps whose contact start lies within 0.6 ms of a label resting on
the accelerometer. Beside them, the share found by the predictor alone (an autoregression of
order p fitted on the whole recording, refitted without the samples it predicts worst, as
calibration fits it): each run of samples whose prediction error exceeds k times its robust RMS
(runs 0.5 ms apart) taken for one contact, with no detector's rules. Prints a table (and events
a second against lumps a second: a detector finding more events than lumps would be finding
ringing), asserts nothing.

    python test/bench/bench_flow_pulses.py                          # 50, 200 lumps/s, ~1 min
    python test/bench/bench_flow_pulses.py --rates 20,50,100,200 --seed 47001
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from tail_beam_id.study.flow_evaluation import (
    FLOW_SEED,
    FlowScene,
    flow_supports,
    identify_flow,
    reading_params,
    scene_flow,
)
from tail_beam_sim.config import load_parameters

# The rates of the flow set's documented command (docs/results/gangue_share.md), whose order
# its case seeds follow: the flows here are that command's.
SET_RATES = (3.3, 5.0, 20.0, 50.0, 100.0, 200.0)
TOLERANCE_S = 0.0006  # a detection this close to a contact start finds it
RUN_GAP_S = 0.0005  # exceedances further apart start another event


def found_share(starts: np.ndarray, found: np.ndarray) -> float:
    """The share of ``starts`` (s) with a detection of ``found`` (s, sorted) within TOLERANCE_S."""
    if not found.size:
        return 0.0
    index = np.clip(np.searchsorted(found, starts), 1, found.size - 1)
    nearest = np.minimum(np.abs(found[index] - starts), np.abs(found[index - 1] - starts))
    return float(np.mean(nearest < TOLERANCE_S))


def innovation_events(stamp_s: np.ndarray, accel: np.ndarray, order: int, k: float) -> np.ndarray:
    """Stamps (s) of the runs of samples whose one-step prediction error by an autoregression of
    ``order`` (fitted on the samples, then refitted on those within 4 robust RMS) exceeds ``k``
    robust RMS."""
    x = np.asarray(accel, dtype=float)
    lagged = np.stack([x[order - j - 1 : x.size - j - 1] for j in range(order)], axis=1)
    target = x[order:]

    def errors(rows: np.ndarray) -> tuple[np.ndarray, float]:
        a, *_ = np.linalg.lstsq(lagged[rows], target[rows], rcond=None)
        e = target - lagged @ a
        return e, 1.4826 * float(np.median(np.abs(e - np.median(e))))

    e, sigma = errors(slice(None))
    e, sigma = errors(np.abs(e) < 4.0 * sigma)
    over = stamp_s[order:][np.abs(e) > k * sigma]
    if not over.size:
        return over
    return np.concatenate([over[:1], over[1:][np.diff(over) > RUN_GAP_S]])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rates", default="50,200", help="lumps/s, of the flow set's rates")
    parser.add_argument("--foreign", type=int, default=2, help="foreign supports")
    parser.add_argument("--seed", type=int, default=FLOW_SEED, help="the flow set's seed")
    parser.add_argument("--order", type=int, default=8, help="the autoregression's order")
    parser.add_argument("--duration-s", type=float, default=10.0, help="each flow's length, s")
    args = parser.parse_args()
    params = load_parameters([])
    off, on = (
        {
            **params,
            "identification": {
                **params["identification"],
                "detection": {
                    **params["identification"]["detection"],
                    "vibration_innovations": flag,
                },
            },
        }
        for flag in (False, True)
    )
    # as `tail-beam evaluate --sets flow --flow-duration-s 10` runs them: the boundary halfway
    scene = FlowScene(args.duration_s, args.duration_s / 2.0)
    rates = [float(r) for r in args.rates.split(",")]
    started = time.perf_counter()
    print(
        f"flows of {scene.duration_s:g} s, seed {args.seed}, shipped layout, self-calibrated; "
        f"AR({args.order})"
    )
    print(
        "support     lumps/s  lumps  identifier's pulses  with predictor  innovations > 6 sigma"
        " (events/s)  > 8 sigma"
    )
    for s_index, (name, draw) in enumerate(flow_supports(params, args.foreign, args.seed)):
        for rate in rates:
            case_seed = args.seed + 100 * s_index + SET_RATES.index(rate)
            flow = scene_flow(params, scene, rate, case_seed, draw)
            starts = np.sort([t["contact_start_stamp"] for t in flow.truths])
            shares = []
            for setting in (off, on):
                model = reading_params(setting, flow, "self-calibrated", "shipped")
                labels, _ = identify_flow(flow, "shipped", None, model)
                pulsed = np.sort(
                    [lab.impact_stamp_s for lab in labels if "vibration" in (lab.signals or ())]
                )
                shares.append(found_share(starts, pulsed))
            stamp_s = flow.vibration.sample_stamps_s()
            cells = []
            for k in (6.0, 8.0):
                events = innovation_events(stamp_s, flow.vibration.accel_mps2, args.order, k)
                cells.append(
                    f"{found_share(starts, events):5.0%} ({events.size / scene.duration_s:4.0f})"
                )
            print(
                f"{name:11s} {rate:7g} {starts.size:6d}  {shares[0]:19.0%}  {shares[1]:14.0%}"
                f"  {cells[0]:>32s}  {cells[1]:>9s}"
            )
    print(f"{time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
