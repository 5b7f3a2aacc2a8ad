"""How well the identifier reads each impact's moment impulse when other impacts overlap it:
flows of the suite's flow simulator on the nominal support, identified with the shipped
layout, every label paired with its lump (the suite's matching rule) and its read moment
impulses (the jack pressure's, the acceleration pulse's where there is one) compared with the
lump's true moment impulse about the hinge, m (v_in + v_out) x, by the distance from its
contact to the nearest other lump's. Run with a joint fit's neighbour columns on and off to see
what it does: the pressure fit's (``--fit pressure``, ``identification.neighbour_fit``) or the
acceleration's velocity step's (``--fit impulse``, ``identification.impulse_neighbour_fit``).
Seeds: the training flows' range (``TRAINING_SEED`` + 90 onwards), never the evaluation's.

What a better impulse can buy at most: on a sparse flow's labels that rest on a pulse, the
statistical method's score separates the materials (its AUC) with every signal, with the
jack pressure and the camera alone (the pulse's features removed: what a dense flow's labels
mostly rest on), and with those two and the true moment impulse in place of the read one.

    python -m tail_beam_id.study.overlap_impulses --rates 20,50,200 --duration-s 4 [--fit impulse]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from tail_beam_id.methods import build_method
from tail_beam_id.methods.statistical import JOINT_FEATURES, SIGNAL_FEATURES
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
# The identification parameter each --fit toggles.
FITS = {"pressure": "neighbour_fit", "impulse": "impulse_neighbour_fit"}


def read_impulses(
    recording: FlowRecording, neighbour_fit: bool, fit: str = "pressure"
) -> dict[str, Any]:
    """Per matched label: the true moment impulse (N m s), the pressure's and the pulse's read
    (nan where absent), the nearest other lump's distance (s), whether the label is right, and
    the flow's score AUC; with the ``fit``'s (FITS) neighbour columns on or off."""
    params = dict(recording.params)
    params["identification"] = {**params["identification"], FITS[fit]: neighbour_fit}
    recording = FlowRecording(**{**recording.__dict__, "params": params})
    labels, _ = identify_flow(recording, "shipped")
    stamps = recording.lump_stamps_s()
    gangue = recording.gangue()
    tolerance = match_tolerance_s(params["identification"])
    matching = match_stamps(list(stamps), [lab.impact_stamp_s for lab in labels], tolerance)
    rows = []
    for i, j in matching.pairs:
        truth = recording.truths[i]
        moment = true_moment_nms(truth)
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


def true_moment_nms(truth: Mapping[str, Any]) -> float:
    """A lump's moment impulse about the hinge, m (v_in + v_out) x, N m s."""
    return (
        truth["mass_kg"]
        * (truth["impact_speed_mps"] + truth["rebound_speed_mps"])
        * truth["position_m"]
    )


PULSE_FEATURES = {n for n, _ in SIGNAL_FEATURES["imu"]} | {
    n for names in JOINT_FEATURES.values() for n, _ in names
}


def pressure_camera_ceiling(recording: FlowRecording) -> dict[str, float]:
    """The score AUC of a sparse flow's labels that rest on a pulse: with every signal, without
    the pulse's features, and without them but with the true moment impulse."""
    params = recording.params
    labels, _ = identify_flow(recording, "shipped")
    stamps = recording.lump_stamps_s()
    gangue = recording.gangue()
    tolerance = match_tolerance_s(params["identification"])
    matching = match_stamps(list(stamps), [lab.impact_stamp_s for lab in labels], tolerance)
    method = build_method("statistical", params["identification"])
    scores: dict[str, list[float]] = {"all": [], "pressure+camera": [], "true impulse": []}
    truth = []
    for i, j in matching.pairs:
        features = dict(labels[j].features)
        if "contact_duration_s" not in features:
            continue
        truth.append(bool(gangue[i]))
        without = {k: v for k, v in features.items() if k not in PULSE_FEATURES}
        exact = {**without, "moment_impulse_pressure_nms": true_moment_nms(recording.truths[i])}
        for name, given in (
            ("all", features),
            ("pressure+camera", without),
            ("true impulse", exact),
        ):
            scores[name].append(-method.decide(given).estimates["logit"])
    return {"labels": len(truth), **{k: rank_auc(v, truth) for k, v in scores.items()}}


def _median(values: np.ndarray) -> float:
    values = values[np.isfinite(values)]
    return float(np.median(values)) if values.size else float("nan")


def format_table(rate: float, off: Mapping[str, Any], on: Mapping[str, Any]) -> str:
    """One rate's table: per nearest-neighbour bin the lumps, the pressure read's median
    absolute error (N m s) and median relative error above BIG_NMS, without and with the
    neighbour columns; the pulse read's median relative error where there is one, likewise."""
    lines = [
        f"{rate:g} lumps/s: {len(on['rows'])} labels matched; score AUC "
        f"{off['auc']:.3f} -> {on['auc']:.3f}; accuracy {off['rows'][:, 4].mean():.3f} -> "
        f"{on['rows'][:, 4].mean():.3f}",
        "nearest lump      n | pressure, abs. error N m s: single  joint | rel. error, true >"
        " 3 N m s: single  joint (   n) | pulse read: n  rel. error: single  joint",
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
        (n, a_off, r_off, big_n, pulses, p_off), (_, a_on, r_on, _, _, p_on) = cells
        lines.append(
            f"{lo * 1e3:4.0f}-{hi * 1e3:3.0f} ms {n:6d} | {a_off:33.2f} {a_on:6.2f} |"
            f" {r_off:32.3f} {r_on:6.3f} ({big_n:4d}) | {pulses:13d} {p_off:19.3f} {p_on:6.3f}"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rates", default="20,50,200", help="lumps/s, comma separated")
    parser.add_argument("--duration-s", type=float, default=4.0)
    parser.add_argument("--sparse-s", type=float, default=40.0, help="the sparse flow's length")
    parser.add_argument(
        "--fit",
        choices=sorted(FITS),
        default="pressure",
        help="whose neighbour columns are compared off and on: the jack pressure's fit or the "
        "acceleration's velocity step's",
    )
    args = parser.parse_args(argv)
    params = load_parameters([])
    for n, rate in enumerate(float(r) for r in args.rates.split(",")):
        duration = args.duration_s
        recording = record_sim_flow(
            params, rate, duration, 0.3 * duration, 0.2 * duration, 0.6, SEED + n
        )
        off = read_impulses(recording, False, args.fit)
        on = read_impulses(recording, True, args.fit)
        print(format_table(rate, off, on))
        print()
    sparse = record_sim_flow(
        params, 4.0, args.sparse_s, 0.3 * args.sparse_s, 0.2 * args.sparse_s, 0.6, SEED + 10
    )
    ceiling = pressure_camera_ceiling(sparse)
    print(
        f"4 lumps/s, {args.sparse_s:g} s: {ceiling['labels']} labels resting on a pulse; "
        "score AUC "
        f"with every signal {ceiling['all']:.3f}, pressure + camera alone "
        f"{ceiling['pressure+camera']:.3f}, pressure + camera with the true moment impulse "
        f"{ceiling['true impulse']:.3f}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
