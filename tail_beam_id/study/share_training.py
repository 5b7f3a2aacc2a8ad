"""Training the gangue-share vibration models (``tail_beam_id/models/gangue_share.json``):
simulated flows at 5-200 lumps/s with random share curves, on the nominal support and on
supports drawn from the training ranges, each interval's mean frame statistics against its true
share by count; one ridge regression per acceleration channel (the accelerometer, the IMU), its
residual standard deviation measured on flows left out of the fit.

Seeds: training flows use ``TRAINING_SEED`` + n; the evaluation's flow set uses its own
(``identification.evaluation.seeds.flow``), which no training flow uses.

    python -m tail_beam_id.study.share_training --flows 24 --duration-s 8
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from tail_beam_id.stream.share import (
    MODEL_PATH,
    FrameAccumulator,
    ShareConfig,
    interval_ends,
    interval_statistics,
)
from tail_beam_id.study.dataset import evaluation_params
from tail_beam_id.study.flow import FlowRecording, ShareCurve, record_flow, true_shares
from tail_beam_id.study.supports import draw_support, support_ranges
from tail_beam_sim.config import load_parameters

TRAINING_SEED = 7700  # training flows: this + n (the evaluation's flow seed lies far apart)
RATES_PER_S = (5.0, 10.0, 20.0, 50.0, 100.0, 200.0)  # lumps/s the training flows are drawn from
RIDGE = 1.0  # ridge penalty on the standardised statistics
MIN_LUMPS = 3  # intervals with fewer lumps carry too little share to learn from


def recording_frames(recording: FlowRecording, config: ShareConfig) -> dict[str, dict]:
    """Frame statistics of each acceleration channel of a recording (as the identifier takes
    them)."""
    out: dict[str, dict] = {}
    imu = FrameAccumulator(config.frame_s, config.min_frame_fill, "imu")
    imu.add(recording.imu.stamp_s, recording.imu.linear_acceleration_mps2[:, 2])
    imu.close()
    out["imu"] = imu.frames
    if recording.vibration is not None:
        vib = FrameAccumulator(config.frame_s, config.min_frame_fill, "vibration")
        vib.add(recording.vibration.sample_stamps_s(), recording.vibration.accel_mps2)
        vib.close()
        out["vibration"] = vib.frames
    return out


def interval_rows(
    recording: FlowRecording, config: ShareConfig
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(mean frame statistics, true share) of every interval with MIN_LUMPS lumps, by channel."""
    frames = recording_frames(recording, config)
    stamps = recording.imu.stamp_s
    ends = interval_ends(float(stamps[0]), float(stamps[-1]), config)
    intervals = [(end - config.interval_s, end) for end in ends]
    truth = true_shares(recording, intervals)
    rows: dict[str, tuple[list, list]] = {}
    count = round(config.interval_s / config.frame_s)
    for (start, _), (share, n) in zip(intervals, truth):
        if n < MIN_LUMPS:
            continue
        for channel, taken in frames.items():
            stats = interval_statistics(taken, round(start / config.frame_s), count)
            if stats.size:
                rows.setdefault(channel, ([], []))
                rows[channel][0].append(stats)
                rows[channel][1].append(share)
    return {c: (np.array(x), np.array(y)) for c, (x, y) in rows.items()}


def training_flows(
    params: Mapping[str, Any], flows: int, duration_s: float, seed: int = TRAINING_SEED
) -> list[FlowRecording]:
    """``flows`` flows: every other one on the nominal support, the rest on supports drawn from
    the training ranges; rates and share curves drawn per flow."""
    ev = evaluation_params(params)
    ranges = support_ranges(ev, "training")
    rng = np.random.default_rng(np.random.SeedSequence([seed, 11]))
    out = []
    for n in range(flows):
        rate = float(RATES_PER_S[n % len(RATES_PER_S)])
        curve = ShareCurve(
            float(rng.uniform(0.0, 0.6 * duration_s)),
            float(rng.uniform(0.0, 0.4 * duration_s)),
            float(rng.uniform(0.2, 1.0)),
        )
        support = None
        if n % 2:
            draw = draw_support(ranges, rng, rng)
            support = draw.with_sensors(
                {
                    k: float(params["sensors"][k])
                    for k in ("pressure_rate_hz", "imu_rate_hz", "camera_frame_rate_hz")
                },
                float(params["sensors"]["vibration_rate_hz"]),
                1.0,
            )
        out.append(record_flow(params, rate, duration_s, curve, seed + n, support=support))
        print(f"share_training: flow {n + 1}/{flows} at {rate:g} lumps/s", file=sys.stderr)
    return out


def fit_ridge(x: np.ndarray, y: np.ndarray, ridge: float = RIDGE) -> dict[str, Any]:
    """Ridge regression of y on standardised x: mean, scale, weights, bias."""
    mean = x.mean(axis=0)
    scale = x.std(axis=0)
    scale[scale < 1e-9] = 1.0
    z = (x - mean) / scale
    bias = float(y.mean())
    a = z.T @ z + ridge * np.eye(z.shape[1])
    weights = np.linalg.solve(a, z.T @ (y - bias))
    return {"mean": mean, "scale": scale, "weights": weights, "bias": bias}


def predict(fit: Mapping[str, Any], x: np.ndarray) -> np.ndarray:
    z = (x - fit["mean"]) / fit["scale"]
    return np.clip(z @ fit["weights"] + fit["bias"], 0.0, 1.0)


def train(
    recordings: Sequence[FlowRecording], config: ShareConfig, folds: int = 4
) -> dict[str, Any]:
    """The models file's content: per channel the ridge fit on every flow and the residual
    standard deviation of fits that left each fold of flows out."""
    per_flow = [interval_rows(r, config) for r in recordings]
    channels: dict[str, Any] = {}
    for channel in ("vibration", "imu"):
        data = [(n, rows[channel]) for n, rows in enumerate(per_flow) if channel in rows]
        if not data:
            continue
        residuals = []
        for fold in range(folds):
            train_x = [x for n, (x, _) in data if n % folds != fold and x.size]
            train_y = [y for n, (x, y) in data if n % folds != fold and x.size]
            test = [(x, y) for n, (x, y) in data if n % folds == fold and x.size]
            if not train_x or not test:
                continue
            fit = fit_ridge(np.vstack(train_x), np.concatenate(train_y))
            residuals += [predict(fit, x) - y for x, y in test]
        fit = fit_ridge(
            np.vstack([x for _, (x, _) in data if x.size]),
            np.concatenate([y for _, (x, y) in data if x.size]),
        )
        held_out = np.concatenate(residuals) if residuals else np.array([math.nan])
        channels[channel] = {
            "mean": fit["mean"].tolist(),
            "scale": fit["scale"].tolist(),
            "weights": fit["weights"].tolist(),
            "bias": fit["bias"],
            "residual_sd": float(np.sqrt(np.mean(held_out**2))),
            "held_out_mae": float(np.mean(np.abs(held_out))),
            "intervals": int(sum(x.shape[0] for _, (x, _) in data)),
        }
    return {
        "basis": "count",
        "frame_s": config.frame_s,
        "interval_s": config.interval_s,
        "channels": channels,
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--flows", type=int, default=24)
    parser.add_argument("--duration-s", type=float, default=8.0)
    parser.add_argument("--out", default=str(MODEL_PATH))
    args = parser.parse_args(argv)
    params = load_parameters([])
    config = ShareConfig.from_params(params["identification"].get("gangue_share"))
    recordings = training_flows(params, args.flows, args.duration_s)
    model = train(recordings, config)
    with open(args.out, "w") as handle:
        json.dump(model, handle, indent=1)
        handle.write("\n")
    for channel, entry in model["channels"].items():
        print(
            f"{channel}: {entry['intervals']} intervals, held-out MAE "
            f"{100 * entry['held_out_mae']:.1f} points, residual sd "
            f"{100 * entry['residual_sd']:.1f} points"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
