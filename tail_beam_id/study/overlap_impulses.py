"""How well the identifier reads each impact's moment impulse when other impacts overlap it:
flows of the suite's flow simulator on the nominal support, identified with the shipped
layout, every label paired with its lump (the suite's matching rule) and its read moment
impulses (the jack pressure's, the acceleration pulse's where there is one) compared with the
lump's true moment impulse about the hinge, m (v_in + v_out) x, by the distance from its
contact to the nearest other lump's. Run with the pressure fit's neighbour columns on and off
(``identification.neighbour_fit``) to see what the joint fit does. Seeds: the training flows'
range (``TRAINING_SEED`` + 90 onwards), never the evaluation's.

    python -m tail_beam_id.study.overlap_impulses --rates 20,50,200 --duration-s 4
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from tail_beam_id.stream.label import match_stamps, match_tolerance_s
from tail_beam_id.stream.share import label_score
from tail_beam_id.study.flow import FlowRecording, record_sim_flow
from tail_beam_id.study.flow_evaluation import identify_flow, rank_auc
from tail_beam_id.study.share_training import TRAINING_SEED
from tail_beam_sim.config import load_parameters

SEED = TRAINING_SEED + 90  # these flows' seeds: this + n
# Nearest-neighbour distance bins, s.
BINS_S = ((0.0, 0.001), (0.001, 0.002), (0.002, 0.005), (0.005, 0.01), (0.01, 0.02), (0.02, 0.032))
BIG_NMS = 3.0  # relative errors are taken over lumps above this true moment impulse, N m s


def read_impulses(recording: FlowRecording, neighbour_fit: bool) -> dict[str, Any]:
    """Per matched label: the true moment impulse (N m s), the pressure's and the pulse's read
    (nan where absent), the nearest other lump's distance (s), whether the label is right, and
    the flow's score AUC."""
    params = dict(recording.params)
    params["identification"] = {**params["identification"], "neighbour_fit": neighbour_fit}
    recording = FlowRecording(**{**recording.__dict__, "params": params})
    labels, _ = identify_flow(recording, "shipped")
    stamps = recording.lump_stamps_s()
    gangue = recording.gangue()
    tolerance = match_tolerance_s(params["identification"])
    matching = match_stamps(list(stamps), [lab.impact_stamp_s for lab in labels], tolerance)
    rows = []
    for i, j in matching.pairs:
        truth = recording.truths[i]
        moment = (
            truth["mass_kg"]
            * (truth["impact_speed_mps"] + truth["rebound_speed_mps"])
            * truth["position_m"]
        )
        gaps = np.abs(stamps - stamps[i])
        gaps[i] = np.inf
        features = labels[j].features
        rows.append(
            (
                moment,
                features.get("moment_impulse_pressure_nms", np.nan),
                features.get("moment_impulse_imu_nms", np.nan),
                float(gaps.min()),
                float((labels[j].material == "gangue") == gangue[i]),
            )
        )
    scores = [label_score(labels[j]) for _, j in matching.pairs]
    auc = rank_auc(scores, [bool(gangue[i]) for i, _ in matching.pairs])
    return {"rows": np.array(rows, dtype=float).reshape(-1, 5), "auc": auc}


def _median(values: np.ndarray) -> float:
    values = values[np.isfinite(values)]
    return float(np.median(values)) if values.size else float("nan")


def format_table(rate: float, off: Mapping[str, Any], on: Mapping[str, Any]) -> str:
    """One rate's table: per nearest-neighbour bin the lumps, the pressure read's median
    absolute error (N m s) and median relative error above BIG_NMS, without and with the
    neighbour columns; the pulse read's where there is one."""
    lines = [
        f"{rate:g} lumps/s: {len(on['rows'])} labels matched; score AUC "
        f"{off['auc']:.3f} -> {on['auc']:.3f}; accuracy {off['rows'][:, 4].mean():.3f} -> "
        f"{on['rows'][:, 4].mean():.3f}",
        "nearest lump   n  | pressure |err| N m s: single, joint | rel. err (true > 3 N m s, n):"
        " single, joint | pulse read: n, rel. err",
    ]
    for lo, hi in BINS_S:
        cells = []
        for result in (off, on):
            true, pressure, pulse, gap, _ = result["rows"].T
            inside = (gap >= lo) & (gap < hi)
            big = inside & (true > BIG_NMS)
            cells.append(
                (
                    inside.sum(),
                    _median(np.abs(pressure[inside] - true[inside])),
                    _median(np.abs(pressure[big] / true[big] - 1.0)),
                    big.sum(),
                    np.isfinite(pulse[inside]).sum(),
                    _median(np.abs(pulse[inside] / true[inside] - 1.0)),
                )
            )
        (n, a_off, r_off, big_n, pulses, pulse_err), (_, a_on, r_on, *_rest) = cells
        lines.append(
            f"{lo * 1e3:4.0f}-{hi * 1e3:3.0f} ms {n:4d}  | {a_off:6.2f} {a_on:6.2f}"
            f"                    | {r_off:6.3f} {r_on:6.3f} ({big_n:3d})"
            f"                     | {pulses:4d} {pulse_err:6.3f}"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rates", default="20,50,200", help="lumps/s, comma separated")
    parser.add_argument("--duration-s", type=float, default=4.0)
    args = parser.parse_args(argv)
    params = load_parameters([])
    for n, rate in enumerate(float(r) for r in args.rates.split(",")):
        duration = args.duration_s
        recording = record_sim_flow(
            params, rate, duration, 0.3 * duration, 0.2 * duration, 0.6, SEED + n
        )
        off = read_impulses(recording, False)
        on = read_impulses(recording, True)
        print(format_table(rate, off, on))
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
