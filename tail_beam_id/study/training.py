"""Train the trained methods on the project's own simulations, with a seed no evaluation uses,
and write their parameters as small JSON files in tail_beam_id/models/.

    python -m tail_beam_id.study.training [--count 400] [--tier modal]

Regenerates threshold.json, statistical.json and physics.json deterministically (same seed,
same files). The training impacts are the ``stream`` scene (nominal support, calibrated
contact law) at every configured noise factor and sensor setting (the shipped one with the
tail-beam accelerometer fed, as id_node feeds it, and the IMU-only ones), and ``varied``
impacts on drawn supports, half of them with an accelerometer (each of those identified with
it and again without it, so the IMU-only models see every support), and ``varied_paper``:
the paper scene's impacts on drawn supports, which the stream's drawn restitutions never show.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import minimize, minimize_scalar

from tail_beam_id.methods import MODELS_DIR
from tail_beam_id.methods.hysteresis import (
    bin_logits,
    hysteresis_latent,
    joint_probabilities,
    latent_bin,
)
from tail_beam_id.methods.inputs import IMPACT_X
from tail_beam_id.methods.statistical import (
    CALIBRATED_POINT_FEATURES,
    HYSTERESIS,
    POINT_FEATURES,
    SIGNAL_ORDER,
    WITH_POINT,
    WITHOUT_DELAY,
    base_vector,
    delay_design,
    feature_list,
    network_logit,
    signals_of,
    size_feature,
    subset_key,
)
from tail_beam_id.signals.camera import MIN_PERIOD_S
from tail_beam_id.signals.features import VIBRATION_CHANNEL
from tail_beam_id.stream.label import Label
from tail_beam_id.study.blas_threads import single_blas_thread
from tail_beam_id.study.dataset import DRAWN_SETS, evaluation_params, settings
from tail_beam_id.study.provenance import source_revision
from tail_beam_id.study.runs import WHOLE_STREAM_CHUNK_S, Record, run_set
from tail_beam_sim.config import load_parameters
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.contact import hertz_elastic_impact, hertz_stiffness
from tail_beam_sim.physics.materials import material_table
from tail_beam_sim.physics.scene import Impact
from tail_beam_sim.physics.simulate import build_problem
from tail_beam_sim.physics.solvers import solve
from tail_beam_sim.physics.support import Support

L2_PENALTY = 1e-3  # ridge penalty on the standardised logistic weights
HOLDOUT_FRACTION = 0.25  # share of training impacts kept aside to fit the temperature
MIN_UNSEEN_IMPACTS = (
    50  # held-out drawn-support impacts needed to fit the temperature on them alone
)
MAX_TRAINING_IMPACTS = 1_000_000  # per --count option: more would not fit in memory here
ENVELOPE_PERCENTILES = (0.1, 99.9)  # a model's training envelope: these percentiles of each input
THRESHOLD_FEATURES = ("rebound_speed_mps", "moment_impulse_nms", "pressure_swing_pa")


def collect(
    params: Mapping[str, Any],
    scene_set: str,
    count: int,
    seed: int,
    tier: str | None,
    true_profile: bool = False,
) -> list[Record]:
    """Feature records of ``count`` training impacts at every setting (detected ones only); an
    impact with the accelerometer on a drawn support is identified with and without it."""
    records = run_set(
        params,
        scene_set,
        count,
        seed,
        settings(params, every_rate=True),
        ["threshold"],
        tier,
        true_profile=true_profile,
        without_vibration_too=scene_set in DRAWN_SETS,
        # the streams in one delivery: the same labels as id_node's chunks give (the detectors
        # and the decision do not depend on the chunking), without the per-chunk work
        chunk_s=WHOLE_STREAM_CHUNK_S,
    )
    return [r for r in records if r.label is not None]


# One collect() call: (params, scene set, count, seed, tier, true_profile).
CollectJob = tuple[Mapping[str, Any], str, int, int, str | None, bool]


def _collect_job(job: CollectJob) -> list[Record]:
    return collect(*job)


def collect_all(jobs: Sequence[CollectJob], workers: int) -> list[list[Record]]:
    """collect() of each job, in the jobs' order, over ``workers`` processes (each job seeds
    its own impacts, so the records are the same for any number of workers); the largest jobs
    (by impacts) start first, so that the workers finish together."""
    if workers <= 1 or len(jobs) <= 1:
        return [_collect_job(job) for job in jobs]
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    order = sorted(range(len(jobs)), key=lambda k: -jobs[k][2])
    context = multiprocessing.get_context("fork")
    with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
        futures = {k: pool.submit(_collect_job, jobs[k]) for k in order}
        return [futures[k].result() for k in range(len(jobs))]


def default_workers() -> int:
    """Processes the training simulates in: every core this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def _nll(w: np.ndarray, x: np.ndarray, y: np.ndarray, l2: float) -> tuple[float, np.ndarray]:
    """Mean logistic loss plus ridge penalty, and its gradient (bias is w[-1], unpenalised)."""
    z = x @ w[:-1] + w[-1]
    loss = np.mean(np.logaddexp(0.0, z) - y * z) + l2 * np.sum(w[:-1] ** 2)
    p = 1.0 / (1.0 + np.exp(-z))
    grad = np.append(x.T @ (p - y) / y.size + 2.0 * l2 * w[:-1], np.mean(p - y))
    return float(loss), grad


def fit_logistic(x: np.ndarray, y: np.ndarray, l2: float = L2_PENALTY) -> np.ndarray:
    """Weights (then bias) of a ridge logistic regression."""
    result = minimize(
        _nll,
        np.zeros(x.shape[1] + 1),
        args=(x, y, l2),
        jac=True,
        method="L-BFGS-B",
        options={"maxiter": 2000},
    )
    return result.x


HIDDEN_UNITS = 16  # the statistical method's hidden layer


def _mlp_unpack(
    theta: np.ndarray, d: int, h: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    w1 = theta[: h * d].reshape(h, d)
    b1 = theta[h * d : h * d + h]
    w2 = theta[h * d + h : h * d + 2 * h]
    return w1, b1, w2, float(theta[-1])


def _mlp_loss(
    theta: np.ndarray, z: np.ndarray, y: np.ndarray, h: int, l2: float
) -> tuple[float, np.ndarray]:
    """Mean logistic loss of a one-hidden-layer tanh network plus ridge penalty, and its
    gradient."""
    n, d = z.shape
    w1, b1, w2, b2 = _mlp_unpack(theta, d, h)
    hidden = np.tanh(z @ w1.T + b1)
    s = hidden @ w2 + b2
    loss = float(np.mean(np.logaddexp(0.0, s) - y * s) + l2 * (np.sum(w1**2) + np.sum(w2**2)))
    ds = (1.0 / (1.0 + np.exp(-s)) - y) / n
    dhidden = np.outer(ds, w2) * (1.0 - hidden**2)
    grad = np.concatenate(
        [
            (dhidden.T @ z + 2 * l2 * w1).ravel(),
            dhidden.sum(axis=0),
            hidden.T @ ds + 2 * l2 * w2,
            [ds.sum()],
        ]
    )
    return loss, grad


def fit_network(
    z: np.ndarray, y: np.ndarray, seed: int, hidden: int = HIDDEN_UNITS, l2: float = L2_PENALTY
) -> dict[str, Any]:
    """Weights of the statistical method's network (L-BFGS from a seeded small start)."""
    d = z.shape[1]
    rng = np.random.default_rng(seed)
    theta = np.concatenate(
        [
            rng.normal(0.0, 1.0 / math.sqrt(d), hidden * d),
            np.zeros(hidden),
            rng.normal(0.0, 0.1, hidden),
            [0.0],
        ]
    )
    result = minimize(
        _mlp_loss,
        theta,
        args=(z, y, hidden, l2),
        jac=True,
        method="L-BFGS-B",
        options={"maxiter": 3000},
    )
    w1, b1, w2, b2 = _mlp_unpack(result.x, d, hidden)
    return {"w1": w1.tolist(), "b1": b1.tolist(), "w2": w2.tolist(), "b2": b2}


def _softmax_unpack(
    theta: np.ndarray, d: int, h: int, m: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(w1 h x d, b1 h, w2 m x h, b2 m) of a softmax network's flat parameters."""
    return (
        theta[: h * d].reshape(h, d),
        theta[h * d : h * d + h],
        theta[h * d + h : h * d + h + h * m].reshape(m, h),
        theta[h * d + h + h * m :],
    )


def _softmax_loss(
    theta: np.ndarray, z: np.ndarray, c: np.ndarray, h: int, m: int, l2: float
) -> tuple[float, np.ndarray]:
    """Mean cross-entropy of a one-hidden-layer tanh network with ``m`` softmax outputs (class
    indices ``c``) plus ridge penalty, and its gradient."""
    n, d = z.shape
    w1, b1, w2, b2 = _softmax_unpack(theta, d, h, m)
    hidden = np.tanh(z @ w1.T + b1)
    scores = hidden @ w2.T + b2
    scores -= scores.max(axis=1, keepdims=True)
    p = np.exp(scores)
    p /= p.sum(axis=1, keepdims=True)
    rows = np.arange(n)
    loss = float(-np.mean(np.log(p[rows, c] + 1e-300)) + l2 * (np.sum(w1**2) + np.sum(w2**2)))
    ds = p
    ds[rows, c] -= 1.0
    ds /= n
    dhidden = (ds @ w2) * (1.0 - hidden**2)
    grad = np.concatenate(
        [
            (dhidden.T @ z + 2 * l2 * w1).ravel(),
            dhidden.sum(axis=0),
            (ds.T @ hidden + 2 * l2 * w2).ravel(),
            ds.sum(axis=0),
        ]
    )
    return loss, grad


HYSTERESIS_HIDDEN_UNITS = 24  # the hysteresis network's hidden layer (it has 2 x bins outputs)


def hysteresis_section(section: Mapping[str, Any]) -> tuple[list[float], float]:
    """(bin_edges, reference_restitution) of ``identification.statistical.hysteresis``, checked:
    edges finite and strictly increasing, the restitution in (0, 0.999]."""
    field = "identification.statistical.hysteresis"
    edges = section.get("bin_edges")
    if (
        not isinstance(edges, (list, tuple))
        or not edges
        or not all(
            isinstance(e, (int, float)) and not isinstance(e, bool) and math.isfinite(e)
            for e in edges
        )
        or any(b <= a for a, b in zip(edges, edges[1:]))
    ):
        raise InputError(
            f"{field}.bin_edges",
            edges,
            "must be a non-empty list of finite numbers, strictly increasing",
        )
    # A restitution of 1 has no hysteresis (chi 0), so the latent's log needs it below 1.
    reference = HYSTERESIS.check(section, only=("reference_restitution",))["reference_restitution"]
    return [float(e) for e in edges], float(reference)


def fit_hysteresis(
    records: Sequence[Record], section: Mapping[str, Any], seed: int
) -> dict[str, Any]:
    """The network that reads an impact's class and its support's hysteresis bin together
    (tail_beam_id.methods.hysteresis), on the drawn supports' impacts identified knowing their
    support (what a self-calibrated identifier sees) with every signal: standardised like the
    statistical models, its temperature fitted on held-out impacts (each on a support no
    training impact struck) with their support's true bin."""
    edges, reference = hysteresis_section(section)
    # the inputs of the full model of a support with a profile, the camera's frame among them
    names = feature_list(SIGNAL_ORDER, frame=True)
    usable = [
        r
        for r in records
        if r.calibrated
        and r.scene_set in DRAWN_SETS
        and r.contact_model is not None
        and set(SIGNAL_ORDER) <= set(signals_of(r.label.features))
        and all(name in r.label.features for name, _ in names)
    ]
    if len(usable) < 200:
        raise SystemExit(
            f"training: {len(usable)} drawn-support records carry their contact law (200 needed): "
            "simulate afresh (delete the --cache file)"
        )
    base = np.array([base_vector(r.label.features, names) for r in usable])
    k = len(edges) + 1
    bins = np.array(
        [
            latent_bin(
                hysteresis_latent(r.contact_model, r.contact_damping_scale, reference), edges
            )
            for r in usable
        ]
    )
    classes = np.array([int(r.is_coal) for r in usable]) * k + bins
    held = np.array([r.index % 4 == 0 for r in usable])  # a quarter of the supports, kept aside
    envelope = np.percentile(base[~held], ENVELOPE_PERCENTILES, axis=0)
    x = np.clip(base, envelope[0], envelope[1])
    mean, scale = x[~held].mean(axis=0), x[~held].std(axis=0) + 1e-9
    z = (x - mean) / scale
    h, m, d = HYSTERESIS_HIDDEN_UNITS, 2 * k, z.shape[1]
    rng = np.random.default_rng(seed)
    theta = np.concatenate(
        [
            rng.normal(0.0, 1.0 / math.sqrt(d), h * d),
            np.zeros(h),
            rng.normal(0.0, 0.1, h * m),
            np.zeros(m),
        ]
    )
    result = minimize(
        _softmax_loss,
        theta,
        args=(z[~held], classes[~held], h, m, L2_PENALTY),
        jac=True,
        method="L-BFGS-B",
        options={"maxiter": 3000},
    )
    w1, b1, w2, b2 = _softmax_unpack(result.x, d, h, m)
    model = {
        "features": [[n, f] for n, f in names],
        "mean": mean.tolist(),
        "scale": scale.tolist(),
        "envelope": envelope.tolist(),
        "w1": w1.tolist(),
        "b1": b1.tolist(),
        "w2": w2.tolist(),
        "b2": b2.tolist(),
        "prior": (np.bincount(classes[~held], minlength=m) / int((~held).sum())).tolist(),
        "bin_edges": edges,
        "reference_restitution": reference,
        "trained_on": int((~held).sum()),
        "calibrated_on": int(held.sum()),
    }
    joint = joint_probabilities(model, z[held])
    logits = np.array([bin_logits(row)[b] for row, b in zip(joint, bins[held])])
    model["temperature"] = fit_temperature(logits, (classes[held] >= k).astype(float))
    return model


def fit_temperature(logits: np.ndarray, y: np.ndarray) -> float:
    """The temperature T that makes sigmoid(logit / T) best calibrated on held-out impacts."""

    def loss(log_t: float) -> float:
        z = logits / math.exp(log_t)
        return float(np.mean(np.logaddexp(0.0, z) - y * z))

    return float(math.exp(minimize_scalar(loss, bounds=(-3.0, 3.0), method="bounded").x))


def fit_size_temperature(
    logits: np.ndarray, y: np.ndarray, log_size: np.ndarray, reference: float
) -> tuple[float, float]:
    """(T, slope) that make sigmoid(logit / (T exp(slope (reference - log_size)))) best calibrated
    on held-out impacts: a temperature that grows as the impact gets smaller (``log_size``: the
    log of its moment impulse; ``reference``: the training median of it). A small particle's
    contact is shorter than what the camera's frame resolves, so the features that tell coal
    from gangue are least sure there; one temperature for all would make the small ones
    overconfident on supports no training saw."""
    du = reference - log_size

    def loss(p: np.ndarray) -> float:
        z = logits / np.exp(p[0] + p[1] * du)
        return float(np.mean(np.logaddexp(0.0, z) - y * z))

    start = math.log(fit_temperature(logits, y))
    result = minimize(
        loss,
        np.array([start, 0.0]),
        method="Nelder-Mead",
        options={"xatol": 1e-4, "fatol": 1e-7, "maxiter": 2000},
    )
    log_t, slope = (float(v) for v in result.x)
    return math.exp(log_t), slope


def train_statistical(
    records: Sequence[Record], seed: int, hysteresis: Mapping[str, Any]
) -> dict[str, Any]:
    """The statistical method's two families of models: ``subsets`` from the records identified
    with the nominal config/, ``calibrated_subsets`` from those identified on a known profile:
    the drawn supports' records identified knowing their support, and the nominal support's
    own records (its profile is config/, so they are what a perfect calibration gives there).
    Without the latter the calibrated models would know only drawn supports, and label streams
    of the nominal support less well at the shipped layout."""
    return {
        "subsets": train_family(
            [r for r in records if not r.calibrated and not stamps_separation(r)], seed
        ),
        "calibrated_subsets": train_family(
            [r for r in records if r.calibrated or r.scene_set not in DRAWN_SETS],
            seed,
            frame=True,
        ),
        "hysteresis": fit_hysteresis(records, hysteresis, seed),
    }


def stamps_separation(record: Record) -> bool:
    """Whether the record's camera stamps the separation itself (faster than any frame grid the
    identifier reads, tail_beam_id.signals.camera.MIN_PERIOD_S). The models for config/ alone
    take every delay as the training's reference camera's (lag about half its frame) and are
    fitted without such records; the models of a support with a profile read the frame."""
    rate = record.camera_frame_rate_hz
    return rate is not None and rate * MIN_PERIOD_S > 1.0


def train_family(records: Sequence[Record], seed: int, frame: bool = False) -> dict[str, Any]:
    """One temperature-calibrated network per subset of signals (every non-empty subset), across
    every support and sensor rate in ``records`` (the IMU period is a continuous feature).
    ``frame``: the models with the rebound delay read the camera's frame period as well (the
    family of supports with a profile, whose frame is measured or configured per support: the
    drawn supports' cameras, from 2 kHz to stamps at the separation itself).

    Impacts whose acceleration features came from the accelerometer are fitted too: its
    anti-alias filter shapes the pulse that ``contact_duration_s`` is read from
    (tail_beam_id.signals.contact_fit) otherwise than an IMU's sample-period mean does.
    """
    every = list(records)
    held = held_out(records, seed)
    subsets: dict[str, Any] = {}
    for mask in range(1, 2 ** len(SIGNAL_ORDER)):
        signals = tuple(s for i, s in enumerate(SIGNAL_ORDER) if mask >> i & 1)
        names = feature_list(signals, frame=frame)
        usable = [
            r
            for r in records
            if set(signals) <= set(signals_of(r.label.features))
            and all(name in r.label.features for name, _ in names)
        ]
        if len(usable) >= 50:
            subsets[subset_key(signals)] = fit_subset(usable, names, held)
            if "rebound_delay_s" in dict(names):
                # The check of the delay is fitted on the accelerometer's impacts too: its
                # delays are the tight ones an offset clock shows in (tail_beam_id.signals.timing).
                subsets[subset_key(signals)]["delay_check"] = fit_delay_check(
                    [
                        r
                        for r in every
                        if set(signals) <= set(signals_of(r.label.features))
                        and all(name in r.label.features for name, _ in names)
                    ],
                    names,
                    subsets[subset_key(signals)],
                )
                # And a model without the delay, for cameras slower than any drawn here
                # (methods.statistical.WITHOUT_DELAY).
                subsets[subset_key(signals) + WITHOUT_DELAY] = fit_subset(
                    usable, feature_list(signals, delay=False), held
                )
    return subsets


def held_out(records: Sequence[Record], seed: int) -> set[tuple[str, int]]:
    """The impacts (scene set, index) kept aside to fit the temperature: HOLDOUT_FRACTION of
    them, drawn by ``seed``."""
    rng = np.random.default_rng(seed)
    impacts = sorted({(r.scene_set, r.index) for r in records})
    chosen = rng.choice(
        len(impacts), size=max(1, int(len(impacts) * HOLDOUT_FRACTION)), replace=False
    )
    return {impacts[i] for i in chosen}


def train_point_models(records: Sequence[Record], seed: int) -> dict[str, dict[str, Any]]:
    """The statistical method's models fitted with the impact point as well (``WITH_POINT``),
    for both families (as :func:`train_statistical` splits the records): one per subset of
    signals with the camera's rebound (a point comes with it), from the records whose labels
    carry ``impact_x_m``. They join the shipped models without changing any of them: an impact
    without a point is decided exactly as before."""
    return {
        "subsets": point_family(
            [r for r in records if not r.calibrated and not stamps_separation(r)],
            seed,
            POINT_FEATURES,
        ),
        "calibrated_subsets": point_family(
            [r for r in records if r.calibrated or r.scene_set not in DRAWN_SETS],
            seed,
            CALIBRATED_POINT_FEATURES,
        ),
    }


def point_family(
    records: Sequence[Record], seed: int, point_features: Sequence[tuple[str, float | None]]
) -> dict[str, Any]:
    """One ``WITH_POINT`` network per subset of signals holding the rebound, on the inputs of
    the subset's model plus ``point_features``, held out and calibrated as
    :func:`train_family` does."""
    held = held_out(records, seed)
    subsets: dict[str, Any] = {}
    for mask in range(1, 2 ** len(SIGNAL_ORDER)):
        signals = tuple(s for i, s in enumerate(SIGNAL_ORDER) if mask >> i & 1)
        if "rebound_velocity" not in signals:
            continue
        usable = [
            r
            for r in records
            if set(signals) <= set(signals_of(r.label.features))
            and all(name in r.label.features for name, _ in point_features)
        ]
        if len(usable) >= 50:
            names = feature_list(signals) + list(point_features)
            subsets[subset_key(signals) + WITH_POINT] = fit_subset(usable, names, held)
    return subsets


DELAY_CHECK_PERCENTILES = (0.5, 99.5)  # the band of the training residuals a delay is usual in
DELAY_CHECK_MIN_RECORDS = 50  # records an IMU-period band needs for its residual band
DELAY_CHECK_RIDGE = 1e-3  # ridge penalty of the delay regression (per record)


def fit_delay_check(
    records: Sequence[Record], names: Sequence[tuple[str, float | None]], model: Mapping[str, Any]
) -> dict[str, Any]:
    """The statistical method's check of an impact's delay from onset to camera stamp
    (tail_beam_id.signals.timing): a ridge regression of the standardised log delay on the model's
    other inputs (with their pairwise products), and per band of IMU periods (TIMING_BIN_EDGES_S)
    the 0.5-99.5 % band of the training residuals (None where too few records fall)."""
    low_env, high_env = (np.array(v) for v in model["envelope"])
    z = (
        np.clip(
            np.array([base_vector(r.label.features, names) for r in records]), low_env, high_env
        )
        - np.array(model["mean"])
    ) / np.array(model["scale"])
    column = [n for n, _ in names].index("rebound_delay_s")
    x = delay_design(z, column)
    weights = np.linalg.solve(
        x.T @ x + DELAY_CHECK_RIDGE * len(x) * np.eye(x.shape[1]), x.T @ z[:, column]
    )
    residual = z[:, column] - x @ weights
    band = np.searchsorted(
        np.array(TIMING_BIN_EDGES_S), [r.label.features["imu_period_s"] for r in records]
    )
    low: list[float | None] = []
    high: list[float | None] = []
    for b in range(len(TIMING_BIN_EDGES_S) + 1):
        inside = residual[band == b]
        bounds = (
            np.percentile(inside, DELAY_CHECK_PERCENTILES)
            if inside.size >= DELAY_CHECK_MIN_RECORDS
            else (None, None)
        )
        low.append(None if bounds[0] is None else float(bounds[0]))
        high.append(None if bounds[1] is None else float(bounds[1]))
    return {
        "weights": weights.tolist(),
        "bands_s": list(TIMING_BIN_EDGES_S),
        "low": low,
        "high": high,
        "fitted_on": len(records),
    }


def fit_subset(
    records: Sequence[Record],
    names: Sequence[tuple[str, float | None]],
    held: set[tuple[str, int]],
) -> dict[str, Any]:
    """Standardise, fit the logistic weights on the training impacts, the temperature on the
    held-out impacts of drawn supports: each struck a support no training impact struck, as a
    user's support is one the model never saw (probabilities calibrated on unseen supports;
    the nominal support's own held-out impacts would make it surer than it has a right to be
    elsewhere). All held-out impacts when fewer than MIN_UNSEEN_IMPACTS are."""
    base = np.array([base_vector(r.label.features, names) for r in records])
    y = np.array([1.0 if r.is_coal else 0.0 for r in records])
    train = np.array([(r.scene_set, r.index) not in held for r in records])
    envelope = np.percentile(base[train], ENVELOPE_PERCENTILES, axis=0)
    x = np.clip(base, envelope[0], envelope[1])
    mean, scale = x[train].mean(axis=0), x[train].std(axis=0) + 1e-9
    z = (x - mean) / scale
    network = fit_network(z[train], y[train], seed=len(names))
    unseen = ~train & np.array([r.scene_set == "varied" for r in records])
    fit_on = unseen if unseen.sum() >= MIN_UNSEEN_IMPACTS else ~train
    logits = network_logit(network, z[fit_on])
    size = size_feature(names)
    if size is None:
        calibration: dict[str, Any] = {"temperature": fit_temperature(logits, y[fit_on])}
    else:
        column = [n for n, _ in names].index(size)
        reference = float(np.median(x[train, column]))
        temperature, slope = fit_size_temperature(logits, y[fit_on], x[fit_on, column], reference)
        calibration = {
            "temperature": temperature,
            "temperature_size": {"feature": size, "reference": reference, "slope": slope},
        }
    return {
        "features": [[n, f] for n, f in names],
        "mean": mean.tolist(),
        "scale": scale.tolist(),
        **network,
        **calibration,
        "envelope": envelope.tolist(),
        "trained_on": int(train.sum()),
        "calibrated_on": int((~train).sum()),
    }


def train_threshold(records: Sequence[Record]) -> dict[str, Any]:
    """One rule per candidate feature (a 1-D logistic on its log), best balanced accuracy first,
    fitted at the nominal noise (the study's conditions) on the IMU-only settings (the
    accelerometer's settings repeat their impacts)."""
    rules = []
    for name in THRESHOLD_FEATURES:
        usable = [
            r
            for r in records
            if name in r.label.features
            and r.setting.endswith("/x1")
            and not r.label.features.get(VIBRATION_CHANNEL)
        ]
        if len(usable) < 50:
            continue
        x = np.log(np.maximum([r.label.features[name] for r in usable], 1e-9))[:, None]
        y = np.array([1.0 if r.is_coal else 0.0 for r in usable])
        w = fit_logistic(x, y, l2=0.0)
        slope, threshold = float(w[0]), float(math.exp(-w[1] / w[0]))
        predicted = (slope * (x[:, 0] - math.log(threshold))) > 0
        balanced = 0.5 * (np.mean(predicted[y == 1]) + np.mean(~predicted[y == 0]))
        values = [r.label.features[name] for r in usable]
        rules.append(
            {
                "feature": name,
                "threshold": threshold,
                "slope": slope,
                "seen": [float(min(values)), float(max(values))],
                "training_balanced_accuracy": float(balanced),
            }
        )
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
            {
                "material": "coal",
                "radius_m": 0.025,
                "impact_speed_mps": 5.0,
                "position_m": 1.0,
                "restitution": float(e),
            },
            materials,
            support,
        )
        trajectory = solve(build_problem(support, impact, "calibrated", 0.01))
        elastic = hertz_elastic_impact(
            hertz_stiffness(impact.material, support.plate, 0.025), impact.mass_kg, 5.0
        )
        ratios.append(trajectory.contacts[0].duration_s / elastic["duration_s"])
    return {"restitution": grid.tolist(), "ratio": [float(r) for r in ratios]}


TIMING_BIN_EDGES_S = tuple(
    float(x) for x in np.geomspace(1.0 / 60000.0, 1.0 / 800.0, 9)
)  # IMU periods, s


def timing_table(records: Sequence[Record], vibration: bool = False) -> list[dict[str, float]]:
    """Per band of IMU periods (log-spaced; the physics method interpolates between them): the
    median and robust spread of (camera stamp - IMU onset) - true duration; with ``vibration``
    of the impacts whose channel was the accelerometer, else of the IMU's."""
    by_band: dict[int, list[tuple[float, float]]] = {}
    for r in records:
        if bool(r.label.features.get(VIBRATION_CHANNEL)) != vibration:
            continue
        f = r.label.features
        if "rebound_delay_s" in f:
            band = int(np.searchsorted(TIMING_BIN_EDGES_S, f["imu_period_s"]))
            by_band.setdefault(band, []).append(
                (f["imu_period_s"], f["rebound_delay_s"] - r.duration_s)
            )
    table = []
    for _, rows in sorted(by_band.items()):
        if len(rows) < 10:
            continue
        periods, lag = (np.array(v) for v in zip(*rows))
        median = float(np.median(lag))
        table.append(
            {
                "imu_period_s": float(np.exp(np.mean(np.log(periods)))),
                "mean_s": median,
                "std_s": float(1.4826 * np.median(np.abs(lag - median))),
                "count": len(rows),
            }
        )
    return table


# The cache layout: records with the accelerometer fed (vibration_channel) and each record's
# contact law and scale and camera frame rate.
CACHE_FORMAT = "tail_beam training records 5"


def save_cache(path: Path, records: Sequence[Record], paper: Sequence[Record]) -> None:
    """Keep the simulated training records as JSON: data only, nothing a reader executes
    (a pickle would run any code a tampered cache holds)."""
    payload = {
        "format": CACHE_FORMAT,
        "stream": [_record_json(r) for r in records],
        "paper": [_record_json(r) for r in paper],
    }
    path.write_text(json.dumps(payload), encoding="utf-8")


def _record_json(record: Record) -> dict[str, Any]:
    """A record as JSON data, its label as the ``label`` JSON object."""
    return {
        **dataclasses.asdict(record),
        "label": None if record.label is None else record.label.as_dict(),
    }


def _record(data: dict[str, Any]) -> Record:
    """The record :func:`_record_json` wrote."""
    label = data.get("label")
    return Record(
        **{
            **data,
            "label": None if label is None else Label.from_dict(label, "cache record label"),
        }
    )


def load_cache(path: Path) -> tuple[list[Record], list[Record]]:
    """The records :func:`save_cache` wrote; anything else is refused with one line."""
    try:
        payload = json.loads(path.read_text(encoding="utf-8"))
        if payload.get("format") != CACHE_FORMAT:
            raise ValueError(f"not a {CACHE_FORMAT!r} file")
        return [_record(r) for r in payload["stream"]], [_record(r) for r in payload["paper"]]
    except (
        ValueError,
        TypeError,
        KeyError,
        AttributeError,
    ) as exc:  # InputError (a bad label) is a ValueError
        raise SystemExit(
            f"training: error: --cache {path}: cannot be read ({exc}); delete it to simulate "
            "afresh"
        ) from None


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description="train the identification methods (writes tail_beam_id/models/*.json)"
    )
    parser.add_argument(
        "--count", type=int, default=400, help="training impacts (each at every setting)"
    )
    parser.add_argument(
        "--varied-count",
        type=int,
        default=1500,
        help="training impacts on drawn supports (each once)",
    )
    parser.add_argument(
        "--varied-paper-count",
        type=int,
        default=None,
        help="paper-scene training impacts on drawn supports (default: a fifth of --varied-count)",
    )
    parser.add_argument("--tier", default=None, help="simulation tier (default: the evaluation's)")
    parser.add_argument(
        "--cache",
        default=None,
        help="JSON file keeping the simulated training records (reused if present)",
    )
    parser.add_argument(
        "--point-models",
        action="store_true",
        help="only fit the statistical models that read the impact point and add them to the "
        "shipped statistical.json (every other model kept as it is; a plain run fits them too, "
        "after the others)",
    )
    parser.add_argument(
        "--jobs",
        type=int,
        default=None,
        help="processes simulating the training impacts (default: every core; the records "
        "and models are the same for any number)",
    )
    args = parser.parse_args(argv)
    for option, value in (
        ("--count", args.count),
        ("--varied-count", args.varied_count),
        ("--varied-paper-count", args.varied_paper_count),
    ):
        if value is not None and not 1 <= value <= MAX_TRAINING_IMPACTS:
            parser.error(f"{option} {value}: must be 1-{MAX_TRAINING_IMPACTS}")
    if args.jobs is None:
        args.jobs = default_workers()
    elif not 1 <= args.jobs <= 64:
        parser.error(f"--jobs {args.jobs}: must be 1-64")
    # the fits' small products in one BLAS thread: threads cost more than they save here
    single_blas_thread()
    params = load_parameters()
    seed = int(evaluation_params(params)["training_seed"])
    if {seed, seed + 1, seed + 2, seed + 3} & set(evaluation_params(params)["seeds"].values()):
        raise SystemExit("training_seed must differ from every evaluation seed")
    if args.point_models:
        return add_point_models(params, args, seed)
    paper_count = max(args.count // 4, 60)
    varied_count = args.varied_count
    varied_paper_count = (
        args.varied_count // 5 if args.varied_paper_count is None else args.varied_paper_count
    )
    cache = Path(args.cache) if args.cache else None
    if cache is not None and cache.is_file():
        records, paper = load_cache(cache)
    else:
        print(f"simulating the training impacts on {args.jobs} processes", flush=True)
        jobs: list[CollectJob] = [
            (params, "stream", args.count, seed, args.tier, False),
            # Supports other than the nominal one, at IMU rates drawn from 0.8-64 kHz.
            (params, "varied", varied_count, seed + 2, args.tier, False),
            # The same impacts as a calibrated identifier sees them (the support's profile known).
            (params, "varied", varied_count, seed + 2, args.tier, True),
            # The paper scene's impacts on drawn supports, both ways: without them the models
            # would know that scene on config/'s support alone, and label it less well on others.
            (params, "varied_paper", varied_paper_count, seed + 3, args.tier, False),
            (params, "varied_paper", varied_paper_count, seed + 3, args.tier, True),
            # The threshold is the study's idea for the study's scene: tuned on paper-scene
            # impacts.
            (params, "paper", paper_count, seed + 1, args.tier, False),
        ]
        *collected, paper = collect_all(jobs, args.jobs)
        records = [r for part in collected for r in part]
        if cache is not None:
            save_cache(cache, records, paper)
    provenance = {
        "training_seed": seed,
        "impacts": args.count,
        "varied_impacts": varied_count,
        "varied_seed": seed + 2,
        "varied_paper_impacts": varied_paper_count,
        "varied_paper_seed": seed + 3,
        "records": len(records),
        "vibration_records": sum(1 for r in records if r.label.features.get(VIBRATION_CHANNEL)),
        "scene_set": "stream+varied+varied_paper",
        "source_revision": source_revision(),
    }
    paper_provenance = {
        "training_seed": seed + 1,
        "impacts": paper_count,
        "records": len(paper),
        "scene_set": "paper",
    }
    outputs = {
        "threshold": {**train_threshold(paper), "provenance": paper_provenance},
        "statistical": {
            **train_statistical(
                records + paper, seed, params["identification"]["statistical"]["hysteresis"]
            ),
            "provenance": [provenance, paper_provenance],
        },
        "physics": {
            "duration_ratio": duration_ratio_table(params),
            "timing": timing_table(records),
            "timing_vibration": timing_table(records, vibration=True),
            "provenance": provenance,
        },
    }
    for name, model in outputs.items():
        path = MODELS_DIR / f"{name}.json"
        path.write_text(json.dumps(model, indent=1) + "\n", encoding="utf-8")
        print(f"wrote {path} ({path.stat().st_size} bytes)")
    # The models that read the impact point join statistical.json: written afresh above, it
    # would otherwise ship without them.
    return add_point_models(params, args, seed)


def point_cache(cache: Path) -> Path:
    """The file keeping the impact point's training records beside ``cache`` (the others'):
    ``records.json`` -> ``records.point.json``."""
    return cache.with_name(f"{cache.stem}.point{cache.suffix}")


def add_point_models(params: Mapping[str, Any], args: argparse.Namespace, seed: int) -> int:
    """Simulate the training impacts with the camera reporting the impact point (the same sets
    and seeds as the shipped models' training, so the same impacts), fit the ``WITH_POINT``
    models on them and add them to the shipped statistical.json, leaving every other model as
    it is."""
    pointed = copy.deepcopy(dict(params))
    pointed["sensors"]["camera_reports_impact_point"] = True
    cache = point_cache(Path(args.cache)) if args.cache else None
    varied_paper_count = (
        args.varied_count // 5 if args.varied_paper_count is None else args.varied_paper_count
    )
    if cache is not None and cache.is_file():
        records, paper = load_cache(cache)
    else:
        print(
            "simulating the training impacts again, the camera reporting the impact point",
            flush=True,
        )
        jobs: list[CollectJob] = [(pointed, "stream", args.count, seed, args.tier, False)]
        for scene_set, count, offset in (
            ("varied", args.varied_count, 2),
            ("varied_paper", varied_paper_count, 3),
        ):
            for true_profile in (False, True):
                jobs.append((pointed, scene_set, count, seed + offset, args.tier, true_profile))
        jobs.append((pointed, "paper", max(args.count // 4, 60), seed + 1, args.tier, False))
        *collected, paper = collect_all(jobs, args.jobs)
        records = [r for part in collected for r in part]
        if cache is not None:
            save_cache(cache, records, paper)
    records = records + paper
    path = MODELS_DIR / "statistical.json"
    model = json.loads(path.read_text(encoding="utf-8"))
    for family, fitted in train_point_models(records, seed).items():
        kept = {k: v for k, v in model[family].items() if not k.endswith(WITH_POINT)}
        model[family] = {**kept, **fitted}
    model["point_provenance"] = {
        "training_seed": seed,
        "impacts": args.count,
        "varied_impacts": args.varied_count,
        "varied_seed": seed + 2,
        "varied_paper_impacts": varied_paper_count,
        "varied_paper_seed": seed + 3,
        "paper_seed": seed + 1,
        "records": len(records),
        "with_point": sum(1 for r in records if IMPACT_X in r.label.features),
        "scene_set": "stream+varied+varied_paper+paper",
        "source_revision": source_revision(),
    }
    path.write_text(json.dumps(model, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {path} ({path.stat().st_size} bytes): the impact point's models added")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
