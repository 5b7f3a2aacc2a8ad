"""Train the trained methods on the project's own simulations, with a seed no evaluation uses,
and write their parameters as small JSON files in tail_beam_id/models/.

    python -m tail_beam_id.training [--count 400] [--tier modal]

Regenerates threshold.json, statistical.json and physics.json deterministically (same seed,
same files). The training impacts are the ``stream`` scene (nominal support, calibrated
contact law) at every configured noise factor and sensor rate.
"""

from __future__ import annotations

import argparse
import json
import math
import pickle
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import minimize, minimize_scalar

from tail_beam_id.dataset import evaluation_params, settings
from tail_beam_id.methods import MODELS_DIR
from tail_beam_id.methods.statistical import SIGNAL_ORDER, base_vector, expand, feature_list, signals_of, subset_key
from tail_beam_id.runs import Record, run_set
from tail_beam_sim.config import load_parameters
from tail_beam_sim.contact import hertz_elastic_impact, hertz_stiffness
from tail_beam_sim.scene import Impact
from tail_beam_sim.simulate import build_problem
from tail_beam_sim.solvers import solve
from tail_beam_sim.materials import material_table
from tail_beam_sim.support import Support

MATCH_TOLERANCE_S = 0.002  # a label within this of the true contact is that impact's
L2_PENALTY = 1e-3  # ridge penalty on the standardised logistic weights
HOLDOUT_FRACTION = 0.25  # share of training impacts kept aside to fit the temperature
THRESHOLD_FEATURES = ("rebound_speed_mps", "moment_impulse_nms", "pressure_swing_pa")


def collect(params: Mapping[str, Any], scene_set: str, count: int, seed: int, tier: str | None) -> list[Record]:
    """Feature records of ``count`` training impacts at every setting (detected ones only)."""
    records = run_set(params, scene_set, count, seed, settings(params, every_rate=True), ["threshold"], MATCH_TOLERANCE_S, tier)
    return [r for r in records if r.label is not None]


def _nll(w: np.ndarray, x: np.ndarray, y: np.ndarray, l2: float) -> tuple[float, np.ndarray]:
    """Mean logistic loss plus ridge penalty, and its gradient (bias is w[-1], unpenalised)."""
    z = x @ w[:-1] + w[-1]
    loss = np.mean(np.logaddexp(0.0, z) - y * z) + l2 * np.sum(w[:-1] ** 2)
    p = 1.0 / (1.0 + np.exp(-z))
    grad = np.append(x.T @ (p - y) / y.size + 2.0 * l2 * w[:-1], np.mean(p - y))
    return float(loss), grad


def fit_logistic(x: np.ndarray, y: np.ndarray, l2: float = L2_PENALTY) -> np.ndarray:
    """Weights (then bias) of a ridge logistic regression."""
    result = minimize(_nll, np.zeros(x.shape[1] + 1), args=(x, y, l2), jac=True, method="L-BFGS-B", options={"maxiter": 2000})
    return result.x


def fit_temperature(logits: np.ndarray, y: np.ndarray) -> float:
    """The temperature T that makes sigmoid(logit / T) best calibrated on held-out impacts."""
    def loss(log_t: float) -> float:
        z = logits / math.exp(log_t)
        return float(np.mean(np.logaddexp(0.0, z) - y * z))

    return float(math.exp(minimize_scalar(loss, bounds=(-3.0, 3.0), method="bounded").x))


def train_statistical(records: Sequence[Record], seed: int) -> dict[str, Any]:
    """One calibrated logistic model per subset of signals (every non-empty subset) and, for
    subsets with the IMU, per IMU sample period."""
    rng = np.random.default_rng(seed)
    impacts = sorted({(r.scene_set, r.index) for r in records})
    chosen = rng.choice(len(impacts), size=max(1, int(len(impacts) * HOLDOUT_FRACTION)), replace=False)
    held = {impacts[i] for i in chosen}
    subsets: dict[str, Any] = {}
    for mask in range(1, 2 ** len(SIGNAL_ORDER)):
        signals = tuple(s for i, s in enumerate(SIGNAL_ORDER) if mask >> i & 1)
        usable = [r for r in records if set(signals) <= set(signals_of(r.label["features"]))]
        groups: dict[str, list[Record]] = {subset_key(signals): usable}
        if "imu" in signals:
            groups = {}
            for r in usable:
                groups.setdefault(f"{subset_key(signals)}@{round(r.label['features']['imu_period_s'], 7):g}", []).append(r)
        for key, group in groups.items():
            if len(group) >= 50:
                subsets[key] = fit_subset(group, feature_list(signals), held)
    return {"subsets": subsets}


def fit_subset(records: Sequence[Record], names: Sequence[tuple[str, float | None]], held: set[tuple[str, int]]) -> dict[str, Any]:
    """Standardise, fit the logistic weights on the training impacts, the temperature on the
    held-out ones."""
    x = expand(np.array([base_vector(r.label["features"], names) for r in records]))
    y = np.array([1.0 if r.is_coal else 0.0 for r in records])
    train = np.array([(r.scene_set, r.index) not in held for r in records])
    mean, scale = x[train].mean(axis=0), x[train].std(axis=0) + 1e-9
    z = (x - mean) / scale
    w = fit_logistic(z[train], y[train])
    temperature = fit_temperature(z[~train] @ w[:-1] + w[-1], y[~train])
    return {
        "features": [[n, f] for n, f in names], "mean": mean.tolist(), "scale": scale.tolist(),
        "weights": w[:-1].tolist(), "bias": float(w[-1]), "temperature": temperature,
        "trained_on": int(train.sum()), "calibrated_on": int((~train).sum()),
    }


def train_threshold(records: Sequence[Record]) -> dict[str, Any]:
    """One rule per candidate feature (a 1-D logistic on its log), best balanced accuracy first,
    fitted at the nominal noise (the study's conditions)."""
    rules = []
    for name in THRESHOLD_FEATURES:
        usable = [r for r in records if name in r.label["features"] and r.setting.endswith("/x1")]
        if len(usable) < 50:
            continue
        x = np.log(np.maximum([r.label["features"][name] for r in usable], 1e-9))[:, None]
        y = np.array([1.0 if r.is_coal else 0.0 for r in usable])
        w = fit_logistic(x, y, l2=0.0)
        slope, threshold = float(w[0]), float(math.exp(-w[1] / w[0]))
        predicted = (slope * (x[:, 0] - math.log(threshold))) > 0
        balanced = 0.5 * (np.mean(predicted[y == 1]) + np.mean(~predicted[y == 0]))
        values = [r.label["features"][name] for r in usable]
        rules.append({
            "feature": name, "threshold": threshold, "slope": slope, "seen": [float(min(values)), float(max(values))],
            "training_balanced_accuracy": float(balanced),
        })
    rules.sort(key=lambda r: -r["training_balanced_accuracy"])
    return {"rules": rules}


def duration_ratio_table(params: Mapping[str, Any]) -> dict[str, list[float]]:
    """Contact duration under the calibrated hysteresis law over the elastic Hertz duration, as
    a function of restitution, from the project's solver (a 25 mm coal sphere at 5 m/s)."""
    materials = material_table(params)
    support = Support.from_params(params["support"], materials)
    grid = np.round(np.linspace(0.2, 0.8, 13), 3)
    ratios = []
    for e in grid:
        impact = Impact.from_mapping(
            {"material": "coal", "radius_m": 0.025, "impact_speed_mps": 5.0, "position_m": 1.0, "restitution": float(e)},
            materials, support,
        )
        trajectory = solve(build_problem(support, impact, "calibrated", 0.01))
        elastic = hertz_elastic_impact(hertz_stiffness(impact.material, support.plate, 0.025), impact.mass_kg, 5.0)
        ratios.append(trajectory.contacts[0].duration_s / elastic["duration_s"])
    return {"restitution": grid.tolist(), "ratio": [float(r) for r in ratios]}


def timing_table(records: Sequence[Record]) -> list[dict[str, float]]:
    """Per IMU period: median and robust spread of (camera stamp - IMU onset) - true duration."""
    by_period: dict[float, list[float]] = {}
    for r in records:
        f = r.label["features"]
        if "rebound_delay_s" in f:
            by_period.setdefault(round(f["imu_period_s"], 7), []).append(f["rebound_delay_s"] - r.duration_s)
    table = []
    for period, lags in sorted(by_period.items()):
        lag = np.array(lags)
        median = float(np.median(lag))
        table.append({"imu_period_s": period, "mean_s": median, "std_s": float(1.4826 * np.median(np.abs(lag - median))), "count": len(lags)})
    return table


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="train the identification methods (writes tail_beam_id/models/*.json)")
    parser.add_argument("--count", type=int, default=400, help="training impacts (each at every setting)")
    parser.add_argument("--tier", default=None, help="simulation tier (default: the evaluation's)")
    parser.add_argument("--cache", default=None, help="pickle file keeping the simulated training records (reused if present)")
    args = parser.parse_args(argv)
    params = load_parameters()
    seed = int(evaluation_params(params)["training_seed"])
    if {seed, seed + 1} & set(evaluation_params(params)["seeds"].values()):
        raise SystemExit("training_seed must differ from every evaluation seed")
    paper_count = max(args.count // 4, 60)
    cache = Path(args.cache) if args.cache else None
    if cache is not None and cache.is_file():
        records, paper = pickle.loads(cache.read_bytes())
    else:
        records = collect(params, "stream", args.count, seed, args.tier)
        # The threshold is the study's idea for the study's scene: tuned on paper-scene impacts.
        paper = collect(params, "paper", paper_count, seed + 1, args.tier)
        if cache is not None:
            cache.write_bytes(pickle.dumps((records, paper)))
    provenance = {"training_seed": seed, "impacts": args.count, "records": len(records), "scene_set": "stream"}
    paper_provenance = {"training_seed": seed + 1, "impacts": paper_count, "records": len(paper), "scene_set": "paper"}
    outputs = {
        "threshold": {**train_threshold(paper), "provenance": paper_provenance},
        "statistical": {**train_statistical(records + paper, seed), "provenance": [provenance, paper_provenance]},
        "physics": {"duration_ratio": duration_ratio_table(params), "timing": timing_table(records), "provenance": provenance},
    }
    for name, model in outputs.items():
        path = MODELS_DIR / f"{name}.json"
        path.write_text(json.dumps(model, indent=1) + "\n", encoding="utf-8")
        print(f"wrote {path} ({path.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
