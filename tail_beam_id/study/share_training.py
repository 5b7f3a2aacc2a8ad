"""Training the gangue-share score model (``tail_beam_id/models/gangue_share.json``): flows of
the suite's flow simulator (:func:`tail_beam_id.study.flow.record_sim_flow`) at 5-200 lumps/s
with random share curves, every other one on the nominal support and the rest on supports drawn
from the training ranges, each identified with the shipped layout and with the IMU alone. Each
label paired with its lump (the suite's matching rule) gives one score
(:func:`tail_beam_id.stream.share.label_score`) of a coal or a gangue lump in its regime
(:func:`~tail_beam_id.stream.share.regime_of`); the model is their histogram densities. Its
systematic error per flow-density class is measured on flows held out of the fit: the
densities read the 1 s intervals of ``--held-out-flows`` more flows (other seeds, other drawn
supports), and what their errors exceed their statistical standard errors by (in quadrature) is
the systematic standard error (with none held out, by two-fold cross-validation over the
training flows).

Seeds: training flows use ``TRAINING_SEED`` + n; the evaluation's flow set uses its own
(``FLOW_SEED`` in :mod:`tail_beam_id.study.flow_evaluation`), which no training flow uses.

    python -m tail_beam_id.study.share_training --flows 20 --held-out-flows 40 --duration-s 10

Each training flow is read with its support's own parameters; ``--profile`` reads them as the
flow set reads its supports instead (``self-calibrated``: calibrated on the flow itself, as
``tail-beam identify`` reads a bag). Trained self-calibrated, the model read the flow set worse
(docs/results/gangue_share.md), so the shipped one is not.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tail_beam_id.calibration.offline import ringing_predictor
from tail_beam_id.stream.label import Label, match_stamps, match_tolerance_s
from tail_beam_id.stream.share import (
    MODEL_PATH,
    RATE_CLASS_EDGES_PER_S,
    SCORE_LIMIT,
    ScoreModel,
    ShareConfig,
    estimate_share,
    interval_ends,
    label_score,
    regime_of,
)
from tail_beam_id.study.dataset import evaluation_params
from tail_beam_id.study.flow import FlowRecording, record_sim_flow
from tail_beam_id.study.flow_evaluation import FLOW_PROFILES, identify_flow, reading_params
from tail_beam_id.study.provenance import source_revision
from tail_beam_id.study.supports import draw_support, support_ranges
from tail_beam_sim.config import load_parameters

TRAINING_SEED = 7700  # training flows: this + n (the evaluation's flows lie far apart)
RATES_PER_S = (5.0, 20.0, 50.0, 100.0, 200.0)  # lumps/s the training flows cycle through
SCORE_BINS = 24  # histogram bins over [-SCORE_LIMIT, SCORE_LIMIT]
PRIOR_COUNT = 0.5  # added to every bin: no score is impossible under either material
DEFAULT_INTERVAL_S = ShareConfig().interval_s  # the local label rate is counted over this, s
MIN_LABELS = 40  # a regime with fewer coal or gangue labels is left out (its labels counted)
# Flows after the training ones on which the systematic error is measured (half of them on
# drawn supports): cross-validation over the training flows' 10 drawn supports stated too
# little of it (docs/results/gangue_share.md).
HELD_OUT_FLOWS = 40
MAX_DURATION_S = 600.0  # a training flow longer than this, s, is surely a mistake


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
            support = draw_support(ranges, rng, rng, params["modes"]).with_sensors(
                rates, float(params["sensors"]["vibration_rate_hz"]), 1.0
            )
        out.append(
            record_sim_flow(params, rate, duration_s, boundary, ramp, final, seed + n, support)
        )
        print(f"share_training: flow {n + 1}/{flows} at {rate:g} lumps/s", file=sys.stderr)
    return out


SENSOR_RATES = ("pressure_rate_hz", "imu_rate_hz", "camera_frame_rate_hz")


def identified(
    recording: FlowRecording,
    layout: str,
    params: Mapping[str, Any] | None = None,
    profile: str = "true",
) -> dict[str, Any]:
    """A flow read with one layout (``shipped``, or ``imu``: without the accelerometer), the
    support known by ``profile`` on ``params`` (config/; :func:`~tail_beam_id.study.
    flow_evaluation.reading_params`), as the training keeps it: its rate, its labels (JSON),
    the lumps' stamps and materials."""
    model = None if params is None else reading_params(params, recording, profile, layout)
    if model is None and layout == "shipped" and recording.vibration is not None:
        # the recorded support's own parameters, with the ringing's predictor a calibration
        # would read from the recording (tail_beam_id.signals.innovations)
        predictor = ringing_predictor(
            recording.params,
            (recording.vibration.sample_stamps_s(), recording.vibration.accel_mps2),
        )
        model = {**recording.params, "calibration": predictor} if predictor else None
    labels, _ = identify_flow(recording, layout, None, model)
    return {
        "rate_per_s": recording.rate_per_s,
        "layout": layout,
        "tolerance_s": match_tolerance_s(recording.params["identification"]),
        "labels": [lab.to_json() for lab in labels],
        "lump_stamps_s": [float(t) for t in recording.lump_stamps_s()],
        "gangue": [bool(g) for g in recording.gangue()],
    }


def flow_labels(flow: Mapping[str, Any]) -> list[Label]:
    return [Label.from_json(text) for text in flow["labels"]]


def scored_labels(flow: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Every label of an :func:`identified` flow paired with a lump: its signals, overlap,
    score, the lump's material (is it gangue) and the labels per second around it (within
    half an interval either side)."""
    labels = flow_labels(flow)
    stamps = np.array([lab.impact_stamp_s for lab in labels])
    matching = match_stamps(list(flow["lump_stamps_s"]), list(stamps), flow["tolerance_s"])
    gangue = flow["gangue"]
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


def interval_errors(
    flow: Mapping[str, Any], model: ScoreModel, config: ShareConfig = ShareConfig()
) -> list[tuple[float, float, float]]:
    """(labels per second, estimate - true share by count, statistical standard error) of
    every interval of an :func:`identified` flow that the mixture estimate read."""
    labels = flow_labels(flow)
    lumps = np.array(flow["lump_stamps_s"])
    gangue = np.array(flow["gangue"], dtype=bool)
    if not labels or not lumps.size:
        return []
    out = []
    for end in interval_ends(float(lumps.min()), float(lumps.max()), config):
        start = end - config.interval_s
        inside = (lumps >= start) & (lumps < end)
        share = estimate_share(labels, start, end, config, model)
        if share.basis_method != "mixture" or share.share is None or not inside.any():
            continue
        out.append(
            (
                share.lumps / config.interval_s,
                share.share - float(gangue[inside].mean()),
                float(share.standard_error or 0.0),
            )
        )
    return out


def systematic_se(flows: Sequence[Mapping[str, Any]], folds: Sequence[int]) -> list[float]:
    """Per flow-density class, the systematic standard error of the mixture share by
    cross-validation: the flows of each fold read by densities fitted on the others
    (:func:`excess_se`)."""
    errors: list[tuple[float, float, float]] = []
    for fold in sorted(set(folds)):
        rows = [r for f, k in zip(flows, folds) if k != fold for r in scored_labels(f)]
        model = ScoreModel.from_dict(fit_densities(regime_rows(rows)))
        for flow, k in zip(flows, folds):
            if k == fold:
                errors += interval_errors(flow, model)
    return excess_se(errors)


def held_out_se(model: ScoreModel, flows: Sequence[Mapping[str, Any]]) -> list[float]:
    """Per flow-density class, the systematic standard error of ``model``'s mixture share on
    ``flows`` it was not fitted on (:func:`excess_se`): the error of the densities themselves,
    with as many other supports as the flows bring."""
    return excess_se([e for flow in flows for e in interval_errors(flow, model)])


def excess_se(errors: Sequence[tuple[float, float, float]]) -> list[float]:
    """Per flow-density class of (labels per second, error, statistical standard error) rows:
    sqrt(mean error^2 - mean statistical variance), 0 when the errors are no larger than the
    statistical ones or the class has none."""
    classes = np.searchsorted(RATE_CLASS_EDGES_PER_S, [e[0] for e in errors], side="right")
    out = []
    for c in range(len(RATE_CLASS_EDGES_PER_S) + 1):
        picked = [e for e, k in zip(errors, classes) if k == c]
        if not picked:
            out.append(0.0)
            continue
        excess = np.mean([d * d for _, d, _ in picked]) - np.mean([se * se for _, _, se in picked])
        out.append(round(math.sqrt(max(0.0, float(excess))), 4))
    return out


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
    parser.add_argument("--flows", type=int, default=20, help="flows the densities learn from")
    parser.add_argument(
        "--held-out-flows",
        type=int,
        default=HELD_OUT_FLOWS,
        help="flows after those (other seeds, other drawn supports) on which the systematic "
        "error is measured; 0: by two-fold cross-validation over the training flows",
    )
    parser.add_argument(
        "--duration-s", type=float, default=10.0, help="each flow's length, s of simulation"
    )
    parser.add_argument("--out", default=str(MODEL_PATH))
    parser.add_argument(
        "--cache", help="JSON file keeping the flows' labels: read when it exists (a refit)"
    )
    parser.add_argument(
        "--profile",
        default=None,
        choices=FLOW_PROFILES,
        help="read each training flow as the flow set reads its supports with this profile "
        "(default: with the recorded support's own parameters, as the shipped model)",
    )
    args = parser.parse_args(argv)
    for option, value, least in (
        ("--flows", args.flows, 1),
        ("--held-out-flows", args.held_out_flows, 0),
    ):
        if value < least:
            raise SystemExit(f"share_training: {option} must be >= {least}, not {value}")
    if not 0.0 < args.duration_s <= MAX_DURATION_S:  # NaN fails too
        raise SystemExit(
            f"share_training: --duration-s must be in (0, {MAX_DURATION_S:g}] s, "
            f"not {args.duration_s:g}"
        )
    params = load_parameters([])
    wanted = args.flows + args.held_out_flows
    if args.cache and Path(args.cache).exists():
        try:
            flows = json.loads(Path(args.cache).read_text())
            cached = len({int(f["flow"]) for f in flows})
        except (OSError, ValueError, TypeError, KeyError) as exc:
            raise SystemExit(
                f"share_training: the cache {args.cache} is no list of identified flows "
                f"({type(exc).__name__}: {exc})"
            ) from None
        if cached < wanted:
            raise SystemExit(
                f"share_training: the cache {args.cache} holds {cached}"
                f" flows, fewer than --flows + --held-out-flows = {wanted}: give another --cache"
                " (or --held-out-flows 0: the systematic error by cross-validation)"
            )
    else:
        # One sequence of flows: the held-out ones continue the training ones' seeds and draws.
        flows = [
            dict(
                identified(recording, layout, params if args.profile else None, args.profile),
                flow=n,
            )
            for n, recording in enumerate(training_flows(params, wanted, args.duration_s))
            for layout in ("shipped", "imu")
        ]
        if args.cache:
            try:
                Path(args.cache).write_text(json.dumps(flows))
            except OSError as exc:
                raise SystemExit(
                    f"share_training: --cache {args.cache}: cannot be written ({exc})"
                ) from None
    held_out = [f for f in flows if args.flows <= f["flow"] < wanted]
    flows = [f for f in flows if f["flow"] < args.flows]
    rows = [r for flow in flows for r in scored_labels(flow)]
    model = fit_densities(regime_rows(rows))
    if held_out:
        model["systematic_se"] = held_out_se(ScoreModel.from_dict(model), held_out)
    else:
        # Two folds of whole flows (both layouts together), each holding every rate and kind.
        model["systematic_se"] = systematic_se(flows, [(f["flow"] // 2) % 2 for f in flows])
    model["training"] = {
        "flows": args.flows,
        "held_out_flows": args.held_out_flows,
        "duration_s": args.duration_s,
        "seed": TRAINING_SEED,
        "rates_per_s": list(RATES_PER_S),
        "profile": args.profile or "recorded",
        "source_revision": source_revision(),
    }
    try:
        Path(args.out).write_text(json.dumps(model, indent=1) + "\n", encoding="utf-8")
    except OSError as exc:
        raise SystemExit(f"share_training: --out {args.out}: cannot be written ({exc})") from None
    for regime, entry in model["densities"].items():
        print(f"{regime}: {entry['coal_labels']} coal, {entry['gangue_labels']} gangue labels")
    print(f"systematic standard error per flow-density class: {model['systematic_se']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
