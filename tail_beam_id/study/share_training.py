"""Training the gangue-share score model (``tail_beam_id/models/gangue_share.json``): flows of
the suite's flow simulator (:func:`tail_beam_id.study.flow.record_sim_flow`) at 5-200 lumps/s
with random share curves, every other one on the nominal support and the rest on supports drawn
from the training ranges, each identified with the shipped layout and with the IMU alone. Each
label paired with its lump (the suite's matching rule) gives one score
(:func:`tail_beam_id.stream.share.label_score`) of a coal or a gangue lump in its regime
(:func:`~tail_beam_id.stream.share.regime_of`); the model is their histogram densities.

Seeds: training flows use ``TRAINING_SEED`` + n; the evaluation's flow set uses its own
(``FLOW_SEED`` in :mod:`tail_beam_id.study.flow_evaluation`), which no training flow uses.

    python -m tail_beam_id.study.share_training --flows 24 --duration-s 6
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.label import Label, match_stamps, match_tolerance_s
from tail_beam_id.stream.replay import replay
from tail_beam_id.stream.share import (
    MODEL_PATH,
    SCORE_LIMIT,
    ShareConfig,
    label_score,
    regime_of,
)
from tail_beam_id.study.dataset import evaluation_params
from tail_beam_id.study.flow import FlowRecording, record_sim_flow
from tail_beam_id.study.supports import draw_support, support_ranges
from tail_beam_sim.config import load_parameters

TRAINING_SEED = 7700  # training flows: this + n (the evaluation's flows lie far apart)
RATES_PER_S = (5.0, 20.0, 50.0, 100.0, 200.0)  # lumps/s the training flows cycle through
SCORE_BINS = 24  # histogram bins over [-SCORE_LIMIT, SCORE_LIMIT]
PRIOR_COUNT = 0.5  # added to every bin: no score is impossible under either material
DEFAULT_INTERVAL_S = ShareConfig().interval_s  # the local label rate is counted over this, s
MIN_LABELS = 40  # a regime with fewer coal or gangue labels is left out (its labels counted)


def training_flows(
    params: Mapping[str, Any], flows: int, duration_s: float, seed: int = TRAINING_SEED
) -> list[FlowRecording]:
    """``flows`` flows: even ones on the nominal support, odd ones on supports drawn from the
    training ranges (with the shipped sensors); rates cycle through RATES_PER_S, share curves
    drawn per flow."""
    ranges = support_ranges(evaluation_params(params), "training")
    rng = np.random.default_rng(np.random.SeedSequence([seed, 11]))
    rates = {k: float(params["sensors"][k]) for k in SENSOR_RATES}
    out = []
    for n in range(flows):
        rate = float(RATES_PER_S[(n // 2) % len(RATES_PER_S)])
        boundary = float(rng.uniform(0.0, 0.5 * duration_s))
        ramp = float(rng.uniform(0.0, 0.3 * duration_s))
        final = float(rng.uniform(0.3, 1.0))
        support = None
        if n % 2:
            support = draw_support(ranges, rng, rng).with_sensors(
                rates, float(params["sensors"]["vibration_rate_hz"]), 1.0
            )
        out.append(
            record_sim_flow(params, rate, duration_s, boundary, ramp, final, seed + n, support)
        )
        print(f"share_training: flow {n + 1}/{flows} at {rate:g} lumps/s", file=sys.stderr)
    return out


SENSOR_RATES = ("pressure_rate_hz", "imu_rate_hz", "camera_frame_rate_hz")


def identify_flow(recording: FlowRecording, vibration: bool, method: str | None = None):
    """The labels of a flow recording, with the accelerometer or the IMU alone."""
    params = recording.params
    identifier = StreamIdentifier(method, params=params["identification"], model_params=params)
    return replay(
        identifier,
        recording.pressure,
        recording.imu,
        recording.rebounds,
        vibration=recording.vibration if vibration else None,
    )


def scored_labels(recording: FlowRecording, labels: Sequence[Label]) -> list[dict[str, Any]]:
    """Every label paired with a lump: its signals, overlap, score, the lump's material (is it
    gangue) and the labels per second around it (within half an interval either side)."""
    tolerance = match_tolerance_s(recording.params["identification"])
    stamps = np.array([lab.impact_stamp_s for lab in labels])
    matching = match_stamps(list(recording.lump_stamps_s()), list(stamps), tolerance)
    gangue = recording.gangue()
    half = 0.5 * DEFAULT_INTERVAL_S
    rows = []
    for i, j in matching.pairs:
        around = np.count_nonzero((stamps >= stamps[j] - half) & (stamps < stamps[j] + half))
        rows.append(
            {
                "signals": sorted(labels[j].signals),
                "overlap": bool(labels[j].overlap),
                "score": label_score(labels[j]),
                "gangue": bool(gangue[i]),
                "labels_per_s": around / DEFAULT_INTERVAL_S,
            }
        )
    return rows


def regime_rows(rows: Sequence[Mapping[str, Any]]) -> list[tuple[str, float, bool]]:
    """(regime, score, is gangue) of each scored label."""
    return [
        (
            regime_of(
                Label(0.0, "coal", 0.5, "", signals=tuple(r["signals"]), overlap=r["overlap"]),
                r["labels_per_s"],
            ),
            float(r["score"]),
            bool(r["gangue"]),
        )
        for r in rows
    ]


def fit_densities(rows: Sequence[tuple[str, float, bool]]) -> dict[str, Any]:
    """The models file's content: per regime the histogram densities (per unit score) of the
    coal and the gangue lumps' scores, and how many of each they rest on."""
    edges = np.linspace(-SCORE_LIMIT, SCORE_LIMIT, SCORE_BINS + 1)
    width = np.diff(edges)
    densities: dict[str, Any] = {}
    for regime in sorted({r for r, _, _ in rows}):
        if min(sum(r == regime and g == want for r, _, g in rows) for want in (False, True)) < (
            MIN_LABELS
        ):
            continue
        entry: dict[str, Any] = {}
        for name, is_gangue in (("coal", False), ("gangue", True)):
            scores = np.array([s for r, s, g in rows if r == regime and g == is_gangue])
            counts = np.histogram(scores, edges)[0] + PRIOR_COUNT
            entry[name] = (counts / counts.sum() / width).tolist()
            entry[f"{name}_labels"] = int(scores.size)
        densities[regime] = entry
    return {"basis": "count", "edges": edges.tolist(), "densities": densities}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--flows", type=int, default=24)
    parser.add_argument("--duration-s", type=float, default=6.0)
    parser.add_argument("--out", default=str(MODEL_PATH))
    parser.add_argument(
        "--cache", help="JSON file keeping the scored labels: read when it exists (a refit)"
    )
    args = parser.parse_args(argv)
    params = load_parameters([])
    if args.cache and Path(args.cache).exists():
        rows = json.loads(Path(args.cache).read_text())
    else:
        rows = []
        for recording in training_flows(params, args.flows, args.duration_s):
            for vibration in (True, False):
                rows += scored_labels(recording, identify_flow(recording, vibration))
        if args.cache:
            Path(args.cache).write_text(json.dumps(rows))
    model = fit_densities(regime_rows(rows))
    model["training"] = {
        "flows": args.flows,
        "duration_s": args.duration_s,
        "seed": TRAINING_SEED,
        "rates_per_s": list(RATES_PER_S),
    }
    with open(args.out, "w") as handle:
        json.dump(model, handle, indent=1)
        handle.write("\n")
    for regime, entry in model["densities"].items():
        print(f"{regime}: {entry['coal_labels']} coal, {entry['gangue_labels']} gangue labels")
    return 0


if __name__ == "__main__":
    sys.exit(main())
