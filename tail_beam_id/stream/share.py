"""The gangue share of a caving flow over a sliding interval: how much of what strikes the tail
beam is rock, read from the impacts' labels (docs/gangue_share.md).

Basis: the share by count, the fraction of the lumps striking in the interval that are gangue.

* Separable impacts (a sparse flow: few labels per second, few of them overlapping another
  impact): the share is the fraction of labels that say gangue; its 95 % interval is that of
  the true count given each label's confidence (a Poisson-binomial: each lump is gangue with
  the probability its label states), so a label that may be wrong widens it
  (``method: labels``).
* Dense flow (responses overlap and per-impact labels are often wrong): the share is the
  mixture proportion that makes the labels' scores (their logits of gangue) likeliest, given
  how coal and gangue impacts score in that regime, learnt on simulated flows at 5-200 lumps/s
  on the nominal and on drawn supports (``tail_beam_id/models/gangue_share.json``); its 95 %
  interval is the profile-likelihood one widened by the model's systematic error at that flow
  density (``method: mixture``). A label that is wrong at random then costs precision, not
  bias; a support that scores unlike training's biases it, which the systematic error states.

An interval ends on the grid ``k hop_s`` of stamp time and rests on the labels whose impact
stamp lies in it: live (id_node) and offline (tail-beam identify) give the same shares.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tail_beam_id.stream.label import Label
from tail_beam_sim.errors import InputError
from tail_beam_sim.spec import Section, integer, number, positive

BASIS = "count"  # the share is the fraction of lumps that are gangue, by number
Z_95 = 1.959963984540054  # two-sided 95 % normal quantile
MODEL_PATH = Path(__file__).resolve().parent.parent / "models" / "gangue_share.json"
SCORE_LIMIT = 12.0  # label scores (logits of gangue) are clipped to +-this
POINT_SIGNAL = "impact_point"  # in a label's signals when its decision read the camera's point
LOGIT_WITHOUT_POINT = "logit_without_point"  # that label's logit had the point been left aside
# Flow density classes of the score model: labels per second below, between and above these.
RATE_CLASS_EDGES_PER_S = (15.0, 40.0, 80.0, 150.0)
SHARE_GRID = 1000  # the mixture estimate's share grid: steps from 0 to 1
CHI2_95_1DOF = 3.841458820694124  # 95 % quantile of chi-square with one degree of freedom

GANGUE_SHARE = Section(
    "identification.gangue_share",
    "The gangue share of the flow over a sliding interval (topic gangue_share).",
    (
        positive("interval_s", "Length of each interval.", "s", high=60.0, default=1.0),
        positive("hop_s", "A new interval ends every this long.", "s", high=60.0, default=0.5),
        positive(
            "settle_s",
            "An interval is published once every live stream is this far past its end and no "
            "impact before its end waits for a decision.",
            "s",
            high=10.0,
            default=0.1,
        ),
        positive(
            "max_labels_per_s",
            "Above this many labels per second of interval the mixture estimate decides.",
            "1/s",
            high=10000.0,
            default=15.0,
        ),
        number(
            "max_overlap_fraction",
            "Above this fraction of overlapping labels the mixture estimate decides.",
            "",
            0.0,
            1.0,
            default=0.25,
        ),
        integer(
            "min_labels",
            "Fewer labels in an interval: the mixture estimate decides.",
            0,
            1000,
            default=1,
        ),
        number(
            "alarm_z",
            "A share alarm at a level needs the estimate this many standard errors above it.",
            "",
            0.0,
            10.0,
            default=0.5,
        ),
        integer(
            "alarm_intervals",
            "A share alarm needs that evidence in this many consecutive intervals; it clears "
            "once the estimate falls below the level (measured from the reference).",
            1,
            100,
            default=2,
        ),
        number(
            "alarm_reference_s",
            "The intervals ending within this of the first one's start are the window's top "
            "coal: the alarm's reference, during which it cannot rise (0: no reference).",
            "s",
            0.0,
            600.0,
            default=3.0,
        ),
        number(
            "alarm_margin",
            "With a reference, a share alarm needs the estimate this far above the level "
            "measured from the reference.",
            "",
            0.0,
            1.0,
            default=0.05,
        ),
    ),
)


@dataclass(frozen=True)
class ShareConfig:
    """The ``identification.gangue_share`` section, validated (times in s)."""

    interval_s: float = 1.0
    hop_s: float = 0.5
    settle_s: float = 0.1
    max_labels_per_s: float = 15.0
    max_overlap_fraction: float = 0.25
    min_labels: int = 1
    alarm_z: float = 0.5
    alarm_intervals: int = 2
    alarm_reference_s: float = 3.0
    alarm_margin: float = 0.05

    @classmethod
    def from_params(cls, section: Mapping[str, Any] | None) -> ShareConfig:
        checked = cls(**GANGUE_SHARE.check(section or {}))
        if checked.hop_s > checked.interval_s:
            raise InputError(
                "identification.gangue_share.hop_s",
                checked.hop_s,
                f"must be at most interval_s ({checked.interval_s:g} s): every impact in one "
                "interval at least",
            )
        return checked


def gangue_probability(label: Label) -> float:
    """The probability that a label's lump is gangue, as its material and confidence state it
    (a non-finite confidence says nothing: 0.5)."""
    confidence = float(label.confidence)
    if not math.isfinite(confidence):
        return 0.5
    confidence = min(max(confidence, 0.0), 1.0)
    return confidence if label.material == "gangue" else 1.0 - confidence


def count_interval(
    gangue_probabilities: Sequence[float], level: float = 0.95
) -> tuple[float, float, float]:
    """The share of gangue among n lumps, each gangue with its own probability (the count is
    Poisson-binomial): its central ``level`` interval (low, high; whole counts over n, each
    tail at most (1 - level) / 2) and its standard deviation. n > 0."""
    p = np.clip(np.asarray(gangue_probabilities, dtype=float), 0.0, 1.0)
    n = p.size
    if n == 0:
        raise InputError("gangue_probabilities", "[]", "must hold one lump at least")
    pmf = np.zeros(n + 1)
    pmf[0] = 1.0
    for k, q in enumerate(p):  # add one lump at a time: P(count) after k + 1 lumps
        pmf[1 : k + 2] = pmf[1 : k + 2] * (1.0 - q) + pmf[: k + 1] * q
        pmf[0] *= 1.0 - q
    cdf = np.cumsum(pmf)
    tail = 0.5 * (1.0 - level)
    tiny = 1e-12  # rounding in the sums: a tail of exactly ``tail`` is kept out
    low = int(np.searchsorted(cdf, tail - tiny, side="right"))
    high = int(np.searchsorted(cdf, 1.0 - tail - tiny, side="left"))
    sd = math.sqrt(float(np.sum(p * (1.0 - p)))) / n
    return low / n, min(high, n) / n, sd


@dataclass(frozen=True)
class GangueShare:
    """One interval's estimate: the share (0..1, None when nothing struck and the vibration
    says nothing), its 95 % interval and standard error, on what it rests."""

    start_stamp_s: float
    end_stamp_s: float
    share: float | None
    low: float
    high: float
    standard_error: float | None
    lumps: int  # labels (impacts identified) in the interval
    gangue_lumps: int  # of those, labelled gangue
    overlapping: int  # of those, overlapping another impact
    basis_method: str  # labels | vibration | none
    signals: tuple[str, ...]
    basis: str = BASIS

    def to_json(self) -> str:
        return json.dumps(
            {
                "start_stamp_s": self.start_stamp_s,
                "end_stamp_s": self.end_stamp_s,
                "share": self.share,
                "basis": self.basis,
                "low": self.low,
                "high": self.high,
                "standard_error": self.standard_error,
                "lumps": self.lumps,
                "gangue_lumps": self.gangue_lumps,
                "overlapping": self.overlapping,
                "method": self.basis_method,
                "signals": list(self.signals),
            },
            sort_keys=True,
        )

    @classmethod
    def from_json(cls, text: str) -> GangueShare:
        """Decode a ``gangue_share`` message; anything else raises InputError naming the field."""
        try:
            data = json.loads(text)
        except (TypeError, ValueError) as exc:
            raise InputError("gangue_share", str(text)[:60], f"must be JSON ({exc})") from None
        if not isinstance(data, dict):
            raise InputError("gangue_share", str(text)[:60], "must be a JSON object")
        try:
            share = data["share"]
            if share is not None and not 0.0 <= float(share) <= 1.0:
                raise InputError("gangue_share.share", share, "must be in [0, 1] or null")
            return cls(
                float(data["start_stamp_s"]),
                float(data["end_stamp_s"]),
                None if share is None else float(share),
                float(data["low"]),
                float(data["high"]),
                None if data["standard_error"] is None else float(data["standard_error"]),
                int(data["lumps"]),
                int(data["gangue_lumps"]),
                int(data["overlapping"]),
                str(data["method"]),
                tuple(str(s) for s in data["signals"]),
                str(data["basis"]),
            )
        except KeyError as exc:
            raise InputError(f"gangue_share.{exc.args[0]}", None, "missing") from None
        except (TypeError, ValueError) as exc:
            raise InputError("gangue_share", str(text)[:60], f"a field of the wrong type ({exc})")


def label_score(label: Label, logit_name: str = "logit") -> float:
    """How gangue-like a label's impact is: the method's logit of gangue (its ``logit``
    estimate, or ``logit_name``, which no confidence cap has touched), else the logit of the
    probability its material and confidence state; clipped to the score range."""
    logit = label.features.get(logit_name) if label.features else None
    if logit is not None and math.isfinite(float(logit)):
        value = -float(logit)  # the methods' logit is of coal
    else:
        p = label.confidence if label.material == "gangue" else 1.0 - label.confidence
        p = min(max(p, 1e-6), 1.0 - 1e-6)
        value = math.log(p / (1.0 - p))
    return float(np.clip(value, -SCORE_LIMIT, SCORE_LIMIT))


def regime_of(label: Label, labels_per_s: float) -> str:
    """The group of labels whose scores share one distribution: the signals the label rested on
    (which network decided it), whether its impact overlapped another, and how dense the flow
    is (labels per second, in classes split at RATE_CLASS_EDGES_PER_S), e.g.
    ``jack_pressure+rebound_velocity/overlap/2``."""
    overlap = "overlap" if label.overlap else "alone"
    return f"{'+'.join(sorted(label.signals))}/{overlap}/{rate_class(labels_per_s)}"


def scored(label: Label, labels_per_s: float, model: ScoreModel) -> tuple[float, str]:
    """The score and regime ``model`` reads a label with: its own; or, for a label that read
    the camera's impact point in a regime the model does not know (one learnt on flows without
    the point), the score its method gave without the point, in the regime of its signals
    without it. Turning the camera's point on then never leaves a dense flow without a model."""
    regime = regime_of(label, labels_per_s)
    features = label.features or {}
    if (
        POINT_SIGNAL in label.signals
        and LOGIT_WITHOUT_POINT in features
        and model.density_of(regime) is None
    ):
        signals = "+".join(sorted(s for s in label.signals if s != POINT_SIGNAL))
        return label_score(label, LOGIT_WITHOUT_POINT), f"{signals}/{regime.split('/', 1)[1]}"
    return label_score(label), regime


def rate_class(labels_per_s: float) -> int:
    """The flow-density class of RATE_CLASS_EDGES_PER_S a rate of labels (1/s) falls in."""
    return int(np.searchsorted(RATE_CLASS_EDGES_PER_S, labels_per_s, side="right"))


@dataclass(frozen=True)
class ScoreModel:
    """The distribution of :func:`label_score` for coal and for gangue impacts in each
    :func:`regime_of`, learnt on simulated flows (histogram densities over ``edges``, per unit
    score), what turns a dense flow's labels into a share however often each is wrong; and the
    systematic error of a mixture share per flow-density class (RATE_CLASS_EDGES_PER_S): how
    far, beyond its statistical error, the share of a flow the densities were not learnt on
    (another support, another flow) lies from the truth, measured across training flows held
    out of the fit."""

    edges: np.ndarray
    densities: dict[str, tuple[np.ndarray, np.ndarray]]  # regime -> (coal, gangue)
    systematic_se: tuple[float, ...] = ()  # per rate class; () or missing classes: 0

    def density_of(self, regime: str) -> tuple[np.ndarray, np.ndarray] | None:
        """The densities of ``regime``, else of the nearest flow-density class with the same
        signals and overlap, else of the same signals with the other overlap; None if the
        signals are unknown."""
        if regime in self.densities:
            return self.densities[regime]
        signals, overlap, rate = regime.rsplit("/", 2)
        other = "alone" if overlap == "overlap" else "overlap"
        for flag in (overlap, other):
            classes = sorted(
                (abs(int(k.rsplit("/", 1)[1]) - int(rate)), k)
                for k in self.densities
                if k.rsplit("/", 1)[0] == f"{signals}/{flag}"
            )
            if classes:
                return self.densities[classes[0][1]]
        return None

    def likelihoods(self, scores: np.ndarray, regimes: Sequence[str]) -> np.ndarray | None:
        """(n, 2) densities of each score under coal and gangue; None if a regime's signals
        are unknown (:meth:`density_of`)."""
        out = np.empty((len(regimes), 2))
        bins = np.clip(
            np.searchsorted(self.edges, scores, side="right") - 1, 0, self.edges.size - 2
        )
        for i, (b, regime) in enumerate(zip(bins, regimes)):
            pair = self.density_of(regime)
            if pair is None:
                return None
            out[i] = pair[0][b], pair[1][b]
        return out

    def systematic(self, labels_per_s: float) -> float:
        """The systematic standard error of a mixture share at this label rate (1/s)."""
        k = rate_class(labels_per_s)
        return float(self.systematic_se[k]) if k < len(self.systematic_se) else 0.0

    def as_dict(self) -> dict[str, Any]:
        return {
            "edges": self.edges.tolist(),
            "densities": {
                r: {"coal": c.tolist(), "gangue": g.tolist()}
                for r, (c, g) in sorted(self.densities.items())
            },
            "systematic_se": list(self.systematic_se),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ScoreModel:
        edges = np.asarray(data["edges"], dtype=float)
        densities = {}
        for regime, entry in data["densities"].items():
            coal = np.asarray(entry["coal"], dtype=float)
            gangue = np.asarray(entry["gangue"], dtype=float)
            if coal.shape != (edges.size - 1,) or gangue.shape != coal.shape:
                raise InputError(f"gangue_share model {regime}", coal.shape, "one value per bin")
            if (coal <= 0).any() or (gangue <= 0).any():
                raise InputError(f"gangue_share model {regime}", "densities", "must be > 0")
            densities[regime] = (coal, gangue)
        systematic = tuple(float(v) for v in data.get("systematic_se", ()))
        if any(not (0.0 <= v <= 1.0) for v in systematic):
            raise InputError("gangue_share model systematic_se", systematic, "must be in [0, 1]")
        return cls(edges, densities, systematic)


def load_score_model(path: str | Path | None = None) -> ScoreModel | None:
    """The shipped score model (``models/gangue_share.json``), or the one at ``path``; None when
    there is none."""
    where = Path(path) if path is not None else MODEL_PATH
    if not where.exists():
        return None
    try:
        return ScoreModel.from_dict(json.loads(where.read_text()))
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(
            "gangue_share model",
            str(where),
            f"is no score model ({type(exc).__name__}: {exc}); rebuild it with "
            "python -m tail_beam_id.study.share_training",
        ) from None


def mixture_share(likelihoods: np.ndarray) -> tuple[float, float, float, float]:
    """The gangue share by count that makes the labels' scores likeliest (each score drawn from
    the coal density with probability 1 - share, the gangue one with the share), on a grid of
    SHARE_GRID steps: (share, its 95 % profile-likelihood interval low and high, the standard
    error from the curvature at the optimum)."""
    grid = np.linspace(0.0, 1.0, SHARE_GRID + 1)
    coal, gangue = likelihoods[:, 0:1], likelihoods[:, 1:2]
    loglik = np.log((1.0 - grid) * coal + grid * gangue).sum(axis=0)
    best = int(np.argmax(loglik))
    inside = grid[loglik >= loglik[best] - 0.5 * CHI2_95_1DOF]
    p = float(grid[best])
    mix = (1.0 - p) * coal[:, 0] + p * gangue[:, 0]
    information = float(np.sum(((gangue[:, 0] - coal[:, 0]) / mix) ** 2))
    se = 1.0 / math.sqrt(information) if information > 0 else math.inf
    return p, float(inside.min()), float(inside.max()), min(se, 1.0)


def estimate_share(
    labels: Sequence[Label],
    start_s: float,
    end_s: float,
    config: ShareConfig,
    model: ScoreModel | None = None,
) -> GangueShare:
    """The share over [start_s, end_s) from the labels whose impact lies in it: the fraction
    labelled gangue while they are separable (few overlap), else the mixture estimate of their
    scores through ``model`` (:func:`mixture_share`)."""
    if not end_s > start_s:
        raise InputError("end_stamp_s", end_s, f"must be after start_stamp_s ({start_s})")
    # In stamp order: the sums below then do not depend on the order the labels came in.
    inside = sorted(
        (lab for lab in labels if start_s <= lab.impact_stamp_s < end_s),
        key=lambda lab: lab.impact_stamp_s,
    )
    n = len(inside)
    if n == 0:
        return GangueShare(start_s, end_s, None, 0.0, 1.0, None, 0, 0, 0, "none", ())
    k = sum(lab.material == "gangue" for lab in inside)
    overlapping = sum(bool(lab.overlap) for lab in inside)
    signals = tuple(sorted({s for lab in inside for s in lab.signals}))
    separable = (
        n >= config.min_labels
        and n <= config.max_labels_per_s * (end_s - start_s)
        and overlapping <= config.max_overlap_fraction * n
    )
    likelihoods = None
    if not separable and model is not None:
        rate = n / (end_s - start_s)
        pairs = [scored(lab, rate, model) for lab in inside]
        likelihoods = model.likelihoods(
            np.array([score for score, _ in pairs]), [regime for _, regime in pairs]
        )
    if likelihoods is None:
        # The labels' own count, within the interval of the true count their confidences give
        # (widened to hold it, should confident labels disagree with their own count).
        p = k / n
        low, high, labels_sd = count_interval([gangue_probability(lab) for lab in inside])
        low, high = min(low, p), max(high, p)
        # The flow's share: the lumps a sample of it (binomial), their labels each may be wrong.
        se = math.sqrt(p * (1 - p) / n + labels_sd * labels_sd)
        return GangueShare(start_s, end_s, p, low, high, se, n, k, overlapping, "labels", signals)
    p, low, high, se = mixture_share(likelihoods)
    # The systematic error (a support or flow unlike training's) adds to the statistical one
    # in quadrature, on the standard error and on each side of the profile interval.
    systematic = model.systematic(n / (end_s - start_s)) if model is not None else 0.0
    if systematic > 0.0:
        se = min(math.hypot(se, systematic), 1.0)
        low = max(0.0, p - math.hypot(p - low, Z_95 * systematic))
        high = min(1.0, p + math.hypot(high - p, Z_95 * systematic))
    return GangueShare(
        start_s, end_s, p, round(low, 6), round(high, 6), se, n, k, overlapping, "mixture", signals
    )


def interval_ends(first_s: float, last_s: float, config: ShareConfig) -> list[float]:
    """Ends ``k hop_s`` of every interval that lies wholly in [first_s, last_s] (s)."""
    if not (math.isfinite(first_s) and math.isfinite(last_s)):
        return []
    k0 = math.ceil((first_s + config.interval_s) / config.hop_s - 1e-9)
    k1 = math.floor(last_s / config.hop_s + 1e-9)
    return [k * config.hop_s for k in range(k0, k1 + 1)]
