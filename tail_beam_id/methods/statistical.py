"""A statistical classifier trained on the project's own simulations: a small neural network
(one hidden tanh layer) on the logarithms of the physical features, one model per set of
signals available (so it still labels when a stream is gone), with temperature-scaled
(calibrated) probabilities; the temperature grows as the impact's moment impulse gets smaller
(small particles are where the features are least sure).

The acceleration features (the ``imu`` signal's) come from whichever channel the identifier
used: the IMU, or the tail-beam accelerometer (``vibration``) while it is fed; the models decide
both alike, trained on the IMU's (tail_beam_id.study.training.train_family says why).

Any sensor rate: the models are trained on supports and sensor rates drawn from wide ranges
(tail_beam_id.study.supports), and the IMU sample period is a continuous input like any other
feature, never a category. Knowing its limits: each model keeps the envelope of its training
inputs (the 0.1 and 99.9 percentiles of each); an impact outside it is clamped to the envelope
before the pairwise products (no polynomial extrapolation), its confidence is capped and the
decision names the features that were outside.

A camera slower than any the training drew (``slowest_delay_camera_frame_rate_hz``) stamps its
rebound up to a frame after the contact's end, more than the contact durations the rebound
delay tells apart: its impacts are decided by twins of the models trained without the delay
(``WITHOUT_DELAY``), when the impact's contact duration was read from its pulse. When it was
not (an IMU slower than about 5 kHz gives its sample period), the delay is all the impact
says of the contact's duration, and the decision is averaged over the lag the camera may have
added (``_lag_rows``), as it is for any camera between the training's reference and slowest.

On a support whose profile carries its contact hysteresis (``calibration.hysteresis_weights``,
read by self-calibration from the recording's impacts: tail_beam_id.methods.hysteresis), an impact
with every signal has its logit moved by what knowing the support's hysteresis says
(``hysteresis_shift`` in its features, ``hysteresis_shift_read`` what the weights said): the
same rebound means coal on one support and mudstone on another, which no single impact tells.
The shift moves the boundary; it never makes a label surer than the impact alone says
(tail_beam_id.methods.hysteresis.applied_shift).

Where the particle struck: an impact whose camera reported its impact point (``impact_x_m``)
is decided by a twin of its signals' model fitted with the point as well (``WITH_POINT``),
and (on a support with a profile) the camera's frame period, when one was trained (``python -m
tail_beam_id.study.training --point-models``); the moment impulse is m v0 (1 + e) x, so
knowing x separates what the impulse alone leaves open. Its
delay check, signals and hysteresis reading are the model's without the point, which every
impact without a point (or decided over a slow camera's lags, or without the delay) still gets.

Why logarithms: the physics is a product of powers (moment impulse = m v0 (1 + e) x,
contact duration ~ R (rho / E*)^0.4 v0^-0.2, rebound speed = e v0), so the material shows as a
near-linear combination of the logs; the pairwise products let the model bend the boundary
and adapt to the noise level, which it sees through the measured noise features.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from functools import lru_cache
from typing import Any

import numpy as np

from tail_beam_id.methods.base import Decision, cap_confidence, model_array, sigmoid
from tail_beam_id.methods.hysteresis import applied_shift, hysteresis_shift, joint_inputs
from tail_beam_id.methods.inputs import IMPACT_X, POINT_USED, base_vector
from tail_beam_id.signals.timing import DELAY_UNTRUSTED, UNUSUAL
from tail_beam_sim.errors import InputError, require_section
from tail_beam_sim.spec import Section, integer, number, of_kind, positive

# Each signal's features, with the floor (in the feature's unit) below which a noisy reading is
# clipped before taking its log; None = used as is (a sign or a ratio near 1).
SIGNAL_FEATURES: dict[str, tuple[tuple[str, float | None], ...]] = {
    "jack_pressure": (("moment_impulse_pressure_nms", 0.05), ("pressure_noise_pa", 1.0)),
    "imu": (
        ("moment_impulse_imu_nms", 0.05),
        ("imu_ring_ratio", 1e-3),
        ("imu_pulse_polarity", None),
        ("imu_pulse_width_s", 1e-5),
        ("imu_noise_mps2", 1e-4),
        ("imu_period_s", 1e-6),
        ("contact_duration_s", 1e-5),
    ),
    "rebound_velocity": (("rebound_speed_mps", 0.05),),
}
# Features that need two signals at once.
JOINT_FEATURES: dict[tuple[str, str], tuple[tuple[str, float | None], ...]] = {
    ("imu", "rebound_velocity"): (("rebound_delay_s", 5e-5),),
}
SIGNAL_ORDER = ("jack_pressure", "imu", "rebound_velocity")
FULL_KEY = "+".join(
    SIGNAL_ORDER
)  # the model of every signal: the one the support's hysteresis refines
# The key suffix of a model fitted without the rebound delay, for a camera slower than any the
# training drew: its lag (up to a frame) then swamps the contact duration the delay carries.
WITHOUT_DELAY = "~without_delay"
# The key suffix of a model fitted with where the particle struck as well (the camera's
# impact point, ``impact_x_m``): used only for an impact that has one, and only where such a
# model was trained; every other impact is decided by the models without it, as before.
WITH_POINT = "~with_point"
# Its inputs besides the signals' own: the point, and (where the support's profile is known)
# the camera's frame period (s), the spread of the lag the rebound delay carries besides the
# contact's duration (up to a frame): knowing it, a model reads a fast camera's delay as the
# sharper measure of the duration it is. A frame shorter than any trained is read as the
# shortest trained, not as outside training: its delay is only sharper, so that errs less sure.
# (Identified with config/ alone, training's single impacts know only config/'s frame: those
# models read the point alone.)
FRAME_PERIOD = "camera_frame_period_s"
# The frame period as a model's input, floored at 10 us: a lag that short is below what the
# onset's timing resolves, so a camera stamped at the separation itself (the frame
# tail_beam_id.signals.camera.GRIDLESS_PERIOD_S) reads as one of 100 kHz. The models of a
# support with a profile (``calibrated_subsets``) with the rebound delay read it, so that the
# delay tells the contact's duration as sharply as the camera allows, from a stamp at the
# separation itself to a frame of 2 kHz (tail_beam_id.study.training.train_statistical).
FRAME_INPUT: tuple[str, float | None] = (FRAME_PERIOD, 1e-5)
POINT_FEATURES: tuple[tuple[str, float | None], ...] = ((IMPACT_X, 0.05),)
CALIBRATED_POINT_FEATURES = (*POINT_FEATURES, FRAME_INPUT)
LAG_ROWS = 16  # lags a camera slower than the training's is averaged over
# a camera frame this many times the reference (or slowest) frame or longer counts as slower
SLOWER = 1.05
# The features that say how large an impact is (its moment impulse), in order of preference: a
# model's temperature grows as it gets smaller (tail_beam_id.study.training.fit_size_temperature).
SIZE_FEATURES = ("moment_impulse_pressure_nms", "moment_impulse_imu_nms")


_CAP = dict(low=0.5, high=1.0)

STATISTICAL = Section(
    "identification.statistical",
    "The statistical method.",
    (
        number(
            "outside_confidence_cap",
            "Confidence cap outside the training envelope.",
            default=0.6,
            **_CAP,
        ),
        positive(
            "reference_camera_frame_rate_hz",
            "Camera frame rate of the training's streams.",
            "Hz",
            high=1e6,
            default=5000.0,
        ),
        positive(
            "slowest_delay_camera_frame_rate_hz",
            "Slower cameras are decided without the rebound delay.",
            "Hz",
            high=1e6,
            default=2000.0,
        ),
    ),
    file="identification.yaml",
    sections=("hysteresis",),
)

HYSTERESIS = Section(
    "identification.statistical.hysteresis",
    "The support's contact hysteresis read by self-calibration.",
    (
        positive("reference_restitution", "Gangue restitution the latent refers to.", high=0.999),
        of_kind("floats", "bin_edges", "Edges of the latent's bins (increasing)."),
        integer(
            "min_impacts",
            "Impacts with every signal needed to read it.",
            1,
            10**6,
            default=8,
        ),
    ),
    file="identification.yaml",
)


def size_feature(names: Sequence[tuple[str, float | None]]) -> str | None:
    """The feature among a model's ``names`` that measures the impact's size, or None."""
    present = {name for name, _ in names}
    return next((name for name in SIZE_FEATURES if name in present), None)


def temperature_of(model: Mapping[str, Any], x: np.ndarray) -> float:
    """The model's temperature for clipped inputs ``x`` (the base vector): ``temperature``,
    times exp(slope (reference - log size)) for a model with a ``temperature_size``."""
    temperature = float(model["temperature"])
    size = model.get("temperature_size")
    if size is None:
        return temperature
    column = [name for name, _ in model["features"]].index(size["feature"])
    return temperature * math.exp(
        float(size["slope"]) * (float(size["reference"]) - float(x[column]))
    )


def _check_temperature_size(key: str, model: Mapping[str, Any]) -> None:
    """A model's ``temperature_size``, if it has one, names one of its features and gives a
    finite slope and reference; anything else is refused by name when the model is loaded,
    not in the middle of a decision."""
    size = model.get("temperature_size")
    if size is None:
        return
    field = f"statistical model {key}.temperature_size"
    names = [name for name, _ in model["features"]]
    if not isinstance(size, Mapping) or size.get("feature") not in names:
        raise InputError(
            field,
            size,
            f"must name one of the model's features ({', '.join(names)}): retrain (python -m "
            "tail_beam_id.study.training)",
        )
    for part in ("slope", "reference"):
        value = size.get(part)
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
        ):
            raise InputError(
                f"{field}.{part}",
                value,
                "must be a finite number: retrain (python -m tail_beam_id.study.training)",
            )


def signals_of(features: Mapping[str, float]) -> tuple[str, ...]:
    """Which signals an impact's features came from (in SIGNAL_ORDER): those whose features are
    all there (an acceleration pulse whose contact duration could not be read counts as none)."""
    return tuple(
        s for s in SIGNAL_ORDER if all(name in features for name, _ in SIGNAL_FEATURES[s])
    )


def subset_key(signals: Sequence[str]) -> str:
    return "+".join(signals)


def feature_list(
    signals: Sequence[str], delay: bool = True, frame: bool = False
) -> list[tuple[str, float | None]]:
    """The (name, floor) of every feature a model on these signals uses (``delay=False``: all
    but the rebound delay; ``frame``: with the camera's frame period after the delay, which a
    model of a support with a profile reads: FRAME_INPUT)."""
    chosen = [f for s in signals for f in SIGNAL_FEATURES[s]]
    for pair, extra in JOINT_FEATURES.items():
        if all(s in signals for s in pair):
            chosen += list(extra)
    if not delay:
        return [f for f in chosen if f[0] != "rebound_delay_s"]
    if frame and any(name == "rebound_delay_s" for name, _ in chosen):
        chosen.append(FRAME_INPUT)
    return chosen


class StatisticalMethod:
    """Temperature-calibrated network; ``model['subsets'][key]`` (and ``calibrated_subsets``, for
    supports with a measured profile) hold each signal subset's feature names, standardisation,
    weights, temperature and training envelope."""

    name = "statistical"

    def __init__(
        self,
        subsets: Mapping[str, Mapping[str, Any]],
        outside_confidence_cap: float,
        calibrated_subsets: Mapping[str, Mapping[str, Any]] | None = None,
        reference_frame_period_s: float = 1.0 / 5000.0,
        slowest_delay_frame_period_s: float = 1.0 / 2000.0,
        hysteresis: Mapping[str, Any] | None = None,
        hysteresis_weights: Sequence[float] | None = None,
    ) -> None:
        self.subsets = subsets
        self.calibrated_subsets = calibrated_subsets or {}
        self.outside_confidence_cap = outside_confidence_cap
        self.reference_frame_period_s = (
            reference_frame_period_s  # the training streams' camera frame, s
        )
        # A camera frame longer than this (s) is decided without the rebound delay, where a model
        # without it was trained.
        self.slowest_delay_frame_period_s = slowest_delay_frame_period_s
        # The network reading an impact's class with its support's hysteresis, and the support's
        # bins' weights from its profile (tail_beam_id.methods.hysteresis); None: decided without
        # them.
        self.hysteresis = hysteresis
        self.hysteresis_weights = (
            None if hysteresis is None or hysteresis_weights is None else list(hysteresis_weights)
        )

    @classmethod
    def from_model(cls, model: Mapping[str, Any], params: Mapping[str, Any]) -> StatisticalMethod:
        section = require_section(
            "identification.statistical", (params.get("identification") or {}).get("statistical")
        )
        checked = STATISTICAL.check(section)
        cap = checked["outside_confidence_cap"]
        families = [model["subsets"], model.get("calibrated_subsets") or {}]
        stale = [
            key
            for family in families
            for key in family
            if "@" in key or "envelope" not in family[key]
        ]
        if stale:
            raise InputError(
                "statistical model",
                stale[0],
                "is a per-rate model without an envelope: retrain (python -m "
                "tail_beam_id.study.training)",
            )
        for family in families:
            for key, subset in family.items():
                _check_temperature_size(key, subset)
        rate = checked["reference_camera_frame_rate_hz"]
        slowest = checked["slowest_delay_camera_frame_rate_hz"]
        hysteresis = model.get("hysteresis")
        calibration = params.get("calibration") or {}
        weights = _profile_weights(
            calibration.get("hysteresis_weights"),
            calibration.get("hysteresis_bin_edges"),
            hysteresis,
        )
        return cls(
            model["subsets"],
            cap,
            model.get("calibrated_subsets"),
            1.0 / rate,
            1.0 / slowest,
            hysteresis,
            weights,
        )

    def decide(self, features: Mapping[str, float]) -> Decision:
        """P(coal) from the model of the signals there are; on a calibrated support (a measured
        profile: ``support_calibrated``) from the models trained on calibrated features. An
        impact with its impact point is decided by the model trained with it when there is one
        (:meth:`_with_point`); its other estimates are the decision's without the point."""
        without, key, single = self._decide_without_point(features)
        if single and WITHOUT_DELAY not in key:
            return self._with_point(features, without, key) or without
        return without

    def _with_point(
        self, features: Mapping[str, float], without: Decision, key: str
    ) -> Decision | None:
        """The decision of the model fitted with the impact point (``WITH_POINT``) for an impact
        that has one, decided without it by the model of ``key`` (one row, the delay kept);
        None when the impact has no point or no such model was trained. It keeps the decision's
        delay check and signals, and the hysteresis shift the support's profile reads, taken as
        far as it makes the label less sure or turns it."""
        if IMPACT_X not in features:
            return None
        family = (
            self.calibrated_subsets
            if features.get("support_calibrated") and self.calibrated_subsets
            else self.subsets
        )
        model = family.get(key + WITH_POINT)
        if model is None:
            return None
        names = [(n, f) for n, f in model["features"]]
        if not all(name in features for name, _ in names):
            return None  # an input the point's model reads is missing (no known camera frame)
        x = base_vector(features, names)
        low, high = model_array(model, "envelope")
        outside = tuple(
            name
            for (name, _), v, lo, hi in zip(names, x, low, high)
            if not lo <= v <= hi and not (name == FRAME_PERIOD and v < lo)
        )
        clipped = np.clip(x, low, high)
        z = (clipped - model_array(model, "mean")) / model_array(model, "scale")
        logit = float(network_logit(model, z[None, :])[0]) / temperature_of(model, clipped)
        estimates = dict(without.estimates)
        estimates["logit_without_point"] = estimates.get("logit", 0.0)
        said = estimates.get("hysteresis_shift_read")
        if said is not None:
            shift = applied_shift(logit, said)
            estimates["hysteresis_shift"] = shift
            logit += shift
        estimates["logit"] = logit
        estimates[POINT_USED] = 1.0
        p_coal = sigmoid(logit)
        outside = tuple(dict.fromkeys((*without.outside_training, *outside)))
        if outside:
            p_coal = cap_confidence(p_coal, self.outside_confidence_cap)
        return Decision(p_coal, estimates, outside, without.signals)

    def _decide_without_point(self, features: Mapping[str, float]) -> tuple[Decision, str, bool]:
        """P(coal) from the model of the signals there are, the impact point left aside; with
        the key of the model that decided and whether it read one row (no lag averaging)."""
        family = (
            self.calibrated_subsets
            if features.get("support_calibrated") and self.calibrated_subsets
            else self.subsets
        )
        signals = signals_of(features)
        key = subset_key(signals)
        if (
            self._camera_too_slow_for_the_delay(features) or features.get(DELAY_UNTRUSTED)
        ) and key + WITHOUT_DELAY in family:
            key += WITHOUT_DELAY
        model = family.get(key)
        if model is None:
            return Decision(0.5, {}, signals=()), key, False
        names = [(n, f) for n, f in model["features"]]
        if FRAME_PERIOD in dict(names) and FRAME_PERIOD not in features:
            # No frame known (none configured, none measured yet): the training's reference.
            features = {**features, FRAME_PERIOD: self.reference_frame_period_s}
        rows = self._lag_rows(features, names)
        low, high = model_array(model, "envelope")
        middle = rows[len(rows) // 2]
        outside = tuple(
            name
            for (name, _), v, lo, hi in zip(names, middle, low, high)
            if not lo <= v <= hi and not (name == FRAME_PERIOD and v < lo)
        )
        clipped = np.clip(rows, low, high)
        z = (clipped - model_array(model, "mean")) / model_array(model, "scale")
        logits = network_logit(model, z) / temperature_of(model, clipped[len(rows) // 2])
        if len(rows) == 1:
            logit = float(logits[0])
            p_coal = sigmoid(logit)
        else:  # the lags' average probability, and its logit
            p_coal = float(np.mean([sigmoid(float(v)) for v in logits]))
            logit = math.log(max(p_coal, 1e-300)) - math.log(max(1.0 - p_coal, 1e-300))
        if outside:
            p_coal = cap_confidence(p_coal, self.outside_confidence_cap)
        estimates = {"logit": float(logit)}
        if (
            self.hysteresis_weights is not None
            and family is self.calibrated_subsets
            and key == FULL_KEY
            and len(rows) == 1
            and not outside
        ):
            z_joint = joint_inputs(self.hysteresis, features)
            if z_joint is not None:
                # The support's hysteresis known from its recording moves the boundary: the
                # logit takes the shift as far as it makes the label less sure or turns it.
                said = hysteresis_shift(self.hysteresis, z_joint, self.hysteresis_weights)
                shift = applied_shift(float(logit), said)
                estimates = {
                    "logit": float(logit) + shift,
                    "hysteresis_shift": shift,
                    "hysteresis_shift_read": said,
                }
                p_coal = sigmoid(float(logit) + shift)
        if (
            "rebound_delay_s" in dict(names)
            and "imu_period_s" in features
            and not self._slower_than_trained(features)
        ):
            # The lag-corrected row (the middle lag) is the impact as the training's camera saw it.
            # (A camera slower than any trained lags more than the check's band allows for.)
            estimates.update(
                delay_check(model, names, z[len(rows) // 2], float(features["imu_period_s"]))
            )
        return Decision(p_coal, estimates, outside, signals), key, len(rows) == 1

    def _camera_too_slow_for_the_delay(self, features: Mapping[str, float]) -> bool:
        """Whether to decide without the delay: the impact's camera frame is longer than any the
        training drew, so its lag, up to a frame, is more than the contact durations the delay
        tells apart (averaged over its lags, such a delay leaves decisions unsure, and less often
        right than without it; slow cameras' figures: docs/results/robustness.md), and the pulse
        gave the contact's duration (duration_read)."""
        return self._slower_than_trained(features) and duration_read(features)

    def _slower_than_trained(self, features: Mapping[str, float]) -> bool:
        """The impact has a delay and its camera frame is longer than the slowest the training
        drew."""
        period = features.get("camera_frame_period_s")
        return (
            "rebound_delay_s" in features
            and period is not None
            and period > SLOWER * self.slowest_delay_frame_period_s
        )

    def _lag_rows(
        self, features: Mapping[str, float], names: Sequence[tuple[str, float | None]]
    ) -> np.ndarray:
        """The model's inputs (K, d): one row, or, for a camera slower than the model knows
        (``camera_frame_period_s`` > its reference), one per lag the camera may have added.

        The delay from onset to camera stamp is the contact duration plus the camera's lag,
        uniform over its frame period P. A model without the frame input learnt it with the
        training's cameras, whose lag is about half the reference frame P0; one with it
        (FRAME_INPUT) knows frames up to the slowest trained, its P0. So each row moves the delay
        by P0/2 - u for u over (0, min(P, delay)) (and gives the frame input P0), and the
        decision averages the rows' probabilities, so that a 1 kHz camera's lag is not read as
        a contact up to 1 ms long."""
        x = base_vector(features, names)
        period = features.get(FRAME_PERIOD)
        column = next((k for k, (name, _) in enumerate(names) if name == "rebound_delay_s"), None)
        frame = next((k for k, (name, _) in enumerate(names) if name == FRAME_PERIOD), None)
        reference = (
            self.reference_frame_period_s if frame is None else self.slowest_delay_frame_period_s
        )
        if column is None or period is None or not period > SLOWER * reference:
            return x[None, :]
        floor = dict(names)["rebound_delay_s"] or 0.0
        delay = float(features["rebound_delay_s"])
        # The lag is no longer than the delay itself (the contact lasted some time): lags up to
        # a frame longer than the delay read as contacts of no duration, the surest gangue.
        lags = (np.arange(LAG_ROWS) + 0.5) / LAG_ROWS * min(period, max(delay, 0.0))
        delays = delay + 0.5 * reference - lags
        rows = np.repeat(x[None, :], LAG_ROWS, axis=0)
        rows[:, column] = np.log(np.maximum(delays, floor))
        if frame is not None:
            rows[:, frame] = np.log(max(reference, dict(names)[FRAME_PERIOD] or 0.0))
        return rows


def duration_read(features: Mapping[str, float]) -> bool:
    """Whether the impact's contact duration was read from its pulse: a channel too slow for
    that gives exactly its sample period (tail_beam_id.signals.contact_fit.fit_contact). Without
    it the delay is the only timing the impact has, and even a slow camera's, averaged over its
    lag, tells more than none (measured: docs/results/archive.md, "A camera of 1 kHz with a
    slow IMU alone"); where the duration is read the delay adds little and a slow camera's
    blurs it."""
    duration, period = features.get("contact_duration_s"), features.get("imu_period_s")
    return duration is not None and period is not None and duration != period


def _profile_weights(
    weights: Any, edges: Any, hysteresis: Mapping[str, Any] | None
) -> list[float] | None:
    """A profile's ``calibration.hysteresis_weights``, checked against the model's bins: one
    finite non-negative weight per bin, summing to 1, and (where the profile says them) the
    same bins' edges as the model's; None when the profile has none."""
    if weights is None:
        return None
    field = "calibration.hysteresis_weights"
    if hysteresis is None:
        raise InputError(
            field,
            weights,
            "needs a statistical model with a hysteresis network: retrain (python -m "
            "tail_beam_id.study.training)",
        )
    model_edges = [float(e) for e in hysteresis["bin_edges"]]
    if edges is not None and (
        isinstance(edges, str)
        or not isinstance(edges, Sequence)
        or len(edges) != len(model_edges)
        or not all(
            isinstance(e, (int, float)) and not isinstance(e, bool) and abs(e - m) <= 1e-9
            for e, m in zip(edges, model_edges)
        )
    ):
        raise InputError(
            "calibration.hysteresis_bin_edges",
            edges,
            f"must be the models' bins ({model_edges}): the profile was "
            "made with other models; calibrate again (tail-beam calibrate)",
        )
    bins = len(model_edges) + 1
    if (
        not isinstance(weights, Sequence)
        or isinstance(weights, str)
        or len(weights) != bins
        or not all(
            isinstance(w, (int, float))
            and not isinstance(w, bool)
            and math.isfinite(w)
            and w >= 0.0
            for w in weights
        )
        or abs(sum(weights) - 1.0) > 1e-3
    ):
        raise InputError(
            field,
            weights,
            f"must be {bins} non-negative weights summing to 1 (one per hysteresis bin of the "
            "models): calibrate again (tail-beam calibrate) with these models",
        )
    return [float(w) for w in weights]


def delay_design(z: np.ndarray, column: int) -> np.ndarray:
    """The delay check's regressors (N, k) from standardised inputs ``z`` (N, d): every input
    but the delay (``column``), their pairwise products and squares, and 1."""
    others, first, second = _design_indices(z.shape[1], column)
    x = z[:, others]
    return np.concatenate([x, x[:, first] * x[:, second], np.ones((x.shape[0], 1))], axis=1)


@lru_cache(maxsize=64)
def _design_indices(inputs: int, column: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For :func:`delay_design`: the inputs but ``column``, and the pairs (i <= j, row by row)
    of those whose products it takes (read-only, shared)."""
    others = np.delete(np.arange(inputs), column)
    first, second = np.triu_indices(others.size)
    for indices in (others, first, second):
        indices.flags.writeable = False
    return others, first, second


def delay_check(
    model: Mapping[str, Any],
    names: Sequence[tuple[str, float | None]],
    z: np.ndarray,
    period_s: float,
) -> dict[str, float]:
    """``delay_residual`` (the standardised log delay less what the impact's other inputs predict)
    and ``delay_unusual`` (1.0 outside the training residuals' band at this IMU period, s), or
    nothing when the model has no check or no band for the period (tail_beam_id.signals.timing)."""
    check = model.get("delay_check")
    if check is None:
        return {}
    column = [name for name, _ in names].index("rebound_delay_s")
    residual = float(
        z[column] - delay_design(z[None, :], column)[0] @ model_array(check, "weights")
    )
    band = int(np.searchsorted(model_array(check, "bands_s"), period_s))
    low, high = check["low"][band], check["high"][band]
    if low is None or high is None:
        return {"delay_residual": residual}
    return {"delay_residual": residual, UNUSUAL: 0.0 if low <= residual <= high else 1.0}


def network_logit(model: Mapping[str, Any], z: np.ndarray) -> np.ndarray:
    """The network's logit for standardised inputs ``z`` (N, d), before the temperature."""
    hidden = np.tanh(z @ model_array(model, "w1").T + model_array(model, "b1"))
    return hidden @ model_array(model, "w2") + float(model["b2"])
