"""A statistical classifier trained on the project's own simulations: logistic regression on
the logarithms of the physical features and their pairwise products, one model per set of
signals available (so it still labels when a stream is gone) and, with the IMU, per IMU sample
period, with temperature-scaled (calibrated) probabilities.

Why logarithms: the physics is a product of powers (moment impulse = m v0 (1 + e) x,
contact duration ~ R (rho / E*)^0.4 v0^-0.2, rebound speed = e v0), so the material shows as a
near-linear combination of the logs; the pairwise products let the model bend the boundary
and adapt to the noise level, which it sees through the measured noise features.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from itertools import combinations_with_replacement
from typing import Any

import numpy as np

from tail_beam_id.methods import Decision, sigmoid

# Each signal's features, with the floor (in the feature's unit) below which a noisy reading is
# clipped before taking its log; None = used as is (a sign or a ratio near 1).
SIGNAL_FEATURES: dict[str, tuple[tuple[str, float | None], ...]] = {
    "jack_pressure": (("moment_impulse_pressure_nms", 0.05), ("pressure_noise_pa", 1.0)),
    "imu": (
        ("moment_impulse_imu_nms", 0.05), ("imu_ring_ratio", 1e-3), ("imu_pulse_polarity", None),
        ("imu_pulse_width_s", 1e-5), ("imu_noise_mps2", 1e-4), ("imu_period_s", 1e-6),
    ),
    "rebound_velocity": (("rebound_speed_mps", 0.05),),
}
# Features that need two signals at once.
JOINT_FEATURES: dict[tuple[str, str], tuple[tuple[str, float | None], ...]] = {
    ("imu", "rebound_velocity"): (("rebound_delay_s", 5e-5),),
}
SIGNAL_ORDER = ("jack_pressure", "imu", "rebound_velocity")


def signals_of(features: Mapping[str, float]) -> tuple[str, ...]:
    """Which signals an impact's features came from (in SIGNAL_ORDER)."""
    return tuple(s for s in SIGNAL_ORDER if SIGNAL_FEATURES[s][0][0] in features)


def subset_key(signals: Sequence[str]) -> str:
    return "+".join(signals)


def feature_list(signals: Sequence[str]) -> list[tuple[str, float | None]]:
    """The (name, floor) of every feature a model on these signals uses."""
    chosen = [f for s in signals for f in SIGNAL_FEATURES[s]]
    for pair, extra in JOINT_FEATURES.items():
        if all(s in signals for s in pair):
            chosen += list(extra)
    return chosen


def base_vector(features: Mapping[str, float], names: Sequence[tuple[str, float | None]]) -> np.ndarray:
    """The model's inputs before expansion: logs of the clipped magnitudes, raw signs."""
    values = []
    for name, floor in names:
        value = float(features[name])
        values.append(value if floor is None else math.log(max(value, floor)))
    return np.array(values)


def expand(x: np.ndarray) -> np.ndarray:
    """x plus every pairwise product (rows of a 2-D array, or one vector)."""
    x2 = np.atleast_2d(x)
    pairs = [x2[:, i] * x2[:, j] for i, j in combinations_with_replacement(range(x2.shape[1]), 2)]
    out = np.hstack([x2, np.column_stack(pairs)]) if pairs else x2
    return out if x.ndim == 2 else out[0]


class StatisticalMethod:
    """Calibrated logistic regression; ``model['subsets'][key]`` holds each signal subset's
    feature names, standardisation, weights and temperature."""

    name = "statistical"

    def __init__(self, subsets: Mapping[str, Mapping[str, Any]]) -> None:
        self.subsets = subsets

    @classmethod
    def from_model(cls, model: Mapping[str, Any]) -> StatisticalMethod:
        return cls(model["subsets"])

    def _model(self, features: Mapping[str, float]) -> Mapping[str, Any] | None:
        """The model for these signals; with the IMU, the one trained at the nearest IMU
        sample period (its timing features mean different things at 2 and 20 kHz)."""
        key = subset_key(signals_of(features))
        if "imu_period_s" not in features:
            return self.subsets.get(key)
        periods = [float(k.split("@")[1]) for k in self.subsets if k.split("@")[0] == key and "@" in k]
        if not periods:
            return self.subsets.get(key)
        nearest = min(periods, key=lambda p: abs(math.log(p / features["imu_period_s"])))
        return self.subsets[f"{key}@{nearest:g}"]

    def decide(self, features: Mapping[str, float]) -> Decision:
        model = self._model(features)
        if model is None:
            return Decision(0.5, {})
        names = [(n, f) for n, f in model["features"]]
        z = (expand(base_vector(features, names)) - np.array(model["mean"])) / np.array(model["scale"])
        logit = float(z @ np.array(model["weights"]) + model["bias"]) / float(model["temperature"])
        return Decision(sigmoid(logit), {"logit": logit})
