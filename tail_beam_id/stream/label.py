"""Labels: :class:`Label`, the one typed form of the ``label`` JSON object (docs/interface.md)
that the identifier gives (:func:`make_label`) and id_node, ``tail-beam identify``, the demo,
the evaluation and the tests read; and the one rule that says which impact a label is of when it
is scored against the truth (:func:`match`).

The rule (demo, evaluate, training, benchmarks and tests all use :func:`match`): a label is of
the impact whose contact start (``impact_truth.contact_start_stamp``) lies within
``identification.match_tolerance_s`` of its ``impact_stamp`` (inclusive). Labels and impacts
pair one to one, closest pair first: of all truth-label pairs within the tolerance the closest is
paired, then the closest of those left, and so on (ties: earlier truth, then earlier label). An
impact left without a label is missed; a label left without an impact is an extra (false)
detection.

One impact, one label (:class:`Revisions`, which id_node and ``tail-beam identify`` both run on
the identifier's labels in the order it decides them): a decision for an impact that already has
a label (its impact stamp within ``match_tolerance_s`` of that label's) is published as a
revision, never as a new impact: the first label's ``impact_stamp``, and ``revises`` set to it.
A revision is the identifier's later word on the impact (typically from more streams than the
first, when a stream came late); a consumer that keeps one answer per impact takes the newest,
and scoring counts revisions apart (:func:`firsts`), so that they are neither extra detections nor
a second chance.
"""

from __future__ import annotations

import bisect
import dataclasses
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

from tail_beam_id.methods import Decision
from tail_beam_id.stream.config import IDENTIFICATION
from tail_beam_sim.errors import InputError, require_finite, require_range

TRUTH_STAMP = "contact_start_stamp"  # the impact_truth field a label's stamp is compared with, s
LABEL_STAMP = "impact_stamp"  # the label field holding the detected contact start, s
# Above this a label could reach a neighbouring impact of a stream (>= 0.2 s apart), s.
MATCH_TOLERANCE_MAX_S = IDENTIFICATION["match_tolerance_s"].high


MATERIALS = ("coal", "gangue")  # the values of a label's "label" field
# The label JSON keys this module reads and writes (docs/interface.md); any other key of a label
# is another identifier's, kept in Label.extra.
JSON_KEYS = frozenset(
    {
        LABEL_STAMP,
        "label",
        "confidence",
        "method",
        "latency_ms",
        "data_latency_ms",
        "signals",
        "overlap",
        "calibrated",
        "features",
        "non_finite_features",
        "saturated",
        "imu_mount",
        "vibration_mount",
        "outside_training",
        "revises",
    }
)


@dataclass(frozen=True)
class Label:
    """One impact's label (docs/interface.md, ``label`` JSON). The first four fields are the
    contract's; the rest are the suite's own and have defaults, so that a label from another
    identifier that gives only the contract's fields is read too (its other keys are kept in
    ``extra`` and written back as they were).

    ``material``: the JSON ``label`` field, "coal" or "gangue"; ``confidence``: the stated
    label's probability, 0..1; ``latency_ms``: the decision's compute time, ms (wall clock);
    ``data_latency_ms``: from the impact stamp to the newest data the decision needed, ms of
    stamp time; ``features``: the impact's features and the method's estimates (units in names).
    """

    impact_stamp_s: float
    material: str
    confidence: float
    method: str
    latency_ms: float | None = (
        None  # None: not measured (a label from another identifier may not say)
    )
    data_latency_ms: float | None = None
    signals: tuple[str, ...] = ()
    overlap: bool = False
    calibrated: bool = False
    features: Mapping[str, float] = field(default_factory=dict)
    non_finite_features: tuple[str, ...] = ()
    saturated: tuple[str, ...] = ()
    imu_mount: str | None = (
        None  # "inverted" when the IMU read -g (mounted upside down, corrected)
    )
    vibration_mount: str | None = (
        None  # "inverted" when the tail-beam accelerometer read -g (corrected)
    )
    outside_training: tuple[str, ...] = ()
    revises: float | None = None  # a revision: the impact stamp of the impact's first label, s
    extra: Mapping[str, Any] = field(
        default_factory=dict
    )  # keys of another identifier's label, kept as they came

    def decision(self) -> tuple[float, str, float, str]:
        """What live and offline identification of the same data agree on exactly (the compute
        time apart): (impact_stamp_s, material, confidence, method)."""
        return self.impact_stamp_s, self.material, self.confidence, self.method

    def as_dict(self) -> dict[str, Any]:
        """The ``label`` JSON object: the contract's fields first, then the suite's; the
        optional keys only when they say something; a timing that was not measured (None) left
        out."""
        out: dict[str, Any] = {
            LABEL_STAMP: self.impact_stamp_s,
            "label": self.material,
            "confidence": self.confidence,
            "method": self.method,
        }
        for key in ("latency_ms", "data_latency_ms"):
            if getattr(self, key) is not None:
                out[key] = getattr(self, key)
        out.update(
            signals=list(self.signals),
            overlap=self.overlap,
            calibrated=self.calibrated,
            features=dict(self.features),
        )
        optional = {
            "non_finite_features": list(self.non_finite_features),
            "saturated": list(self.saturated),
            "imu_mount": self.imu_mount,
            "vibration_mount": self.vibration_mount,
            "outside_training": list(self.outside_training),
            "revises": self.revises,
        }
        out.update({k: v for k, v in optional.items() if v or (k == "revises" and v is not None)})
        out.update({k: v for k, v in self.extra.items() if k not in out})
        return out

    def to_json(self) -> str:
        """The label as published on ``label`` and printed by ``tail-beam identify``: strict
        JSON."""
        return json.dumps(self.as_dict(), allow_nan=False)

    @classmethod
    def from_dict(cls, obj: object, where: str = "label") -> Label:
        """Read a ``label`` object (from a topic, a bag or a file); raise InputError naming the
        field (``<where>.<field>``) and what it allows for anything else."""
        if not isinstance(obj, Mapping):
            raise InputError(
                where, obj, "must be a JSON object with impact_stamp, label, confidence and method"
            )
        for key in (LABEL_STAMP, "label", "confidence", "method"):
            if key not in obj:
                raise InputError(
                    f"{where}.{key}", None, "is required (docs/interface.md, label JSON)"
                )
        material = obj["label"]
        if material not in MATERIALS:
            raise InputError(f"{where}.label", material, f"must be one of {', '.join(MATERIALS)}")
        if not isinstance(obj["method"], str):
            raise InputError(f"{where}.method", obj["method"], "must be a string")
        return cls(
            impact_stamp_s=_number(obj[LABEL_STAMP], f"{where}.{LABEL_STAMP}"),
            material=material,
            confidence=require_range(
                f"{where}.confidence", _number(obj["confidence"], f"{where}.confidence"), 0.0, 1.0
            ),
            method=obj["method"],
            latency_ms=_optional_number(obj, "latency_ms", where),
            data_latency_ms=_optional_number(obj, "data_latency_ms", where),
            signals=_strings(obj, "signals", where),
            overlap=_flag(obj, "overlap", where),
            calibrated=_flag(obj, "calibrated", where),
            features=_features(obj, where),
            non_finite_features=_strings(obj, "non_finite_features", where),
            saturated=_strings(obj, "saturated", where),
            imu_mount=_mount(obj, "imu_mount", where),
            vibration_mount=_mount(obj, "vibration_mount", where),
            outside_training=_strings(obj, "outside_training", where),
            revises=_optional_number(obj, "revises", where),
            extra={k: v for k, v in obj.items() if k not in JSON_KEYS},
        )

    @classmethod
    def from_json(cls, text: str | bytes, where: str = "label") -> Label:
        """Read a ``label`` message's JSON text (as :meth:`from_dict`); strict JSON: NaN and
        Infinity, which Python's json would take, are refused (the label could not be written
        back)."""
        try:
            obj = json.loads(text, parse_constant=_refuse_constant)
        except _NotStrictJson as exc:
            raise InputError(
                where, text, f"must be strict JSON ({exc} is not strict JSON)"
            ) from None
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise InputError(where, text, f"must be a JSON object ({exc})") from None
        except RecursionError:
            raise InputError(
                where, text, "must be a JSON object (nested too deep to read)"
            ) from None
        return cls.from_dict(obj, where)


class _NotStrictJson(ValueError):
    """A NaN or Infinity in a label's text."""


def _refuse_constant(name: str) -> None:
    raise _NotStrictJson(name)


def _number(value: object, name: str) -> float:
    if isinstance(value, bool):
        raise InputError(name, value, "must be a finite number")
    return require_finite(name, value, allow_text=False)


def _optional_number(obj: Mapping[str, Any], key: str, where: str) -> float | None:
    return _number(obj[key], f"{where}.{key}") if key in obj else None


def _flag(obj: Mapping[str, Any], key: str, where: str) -> bool:
    value = obj.get(key, False)
    if not isinstance(value, bool):
        raise InputError(f"{where}.{key}", value, "must be true or false")
    return value


def _strings(obj: Mapping[str, Any], key: str, where: str) -> tuple[str, ...]:
    value = obj.get(key, [])
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise InputError(f"{where}.{key}", value, "must be a list of strings")
    return tuple(value)


def _features(obj: Mapping[str, Any], where: str) -> dict[str, float]:
    value = obj.get("features", {})
    if not isinstance(value, Mapping):
        raise InputError(f"{where}.features", value, "must be a JSON object of name: number")
    return {str(k): _number(v, f"{where}.features.{k}") for k, v in value.items()}


def _mount(obj: Mapping[str, Any], key: str, where: str) -> str | None:
    """A sensor's mounting field (``imu_mount``, ``vibration_mount``): absent, or "inverted"."""
    value = obj.get(key)
    if value not in (None, "inverted"):
        raise InputError(f"{where}.{key}", value, 'must be "inverted" when given')
    return value


def match_tolerance_s(section: Mapping[str, Any]) -> float:
    """``identification.match_tolerance_s`` of the ``identification`` section, validated (0, 0.1]
    s."""
    return IDENTIFICATION.check(section, only=("match_tolerance_s",))["match_tolerance_s"]


@dataclass(frozen=True)
class Matching:
    """Which label each impact got, by index into the sequences given to :func:`match`.

    ``pairs``: (truth index, label index), in truth order; ``missed``: truths no label matched;
    ``extra``: labels no truth matched (false detections); both in index order.
    """

    pairs: tuple[tuple[int, int], ...]
    missed: tuple[int, ...]
    extra: tuple[int, ...]

    @cached_property
    def _by_truth(self) -> dict[int, int]:
        return dict(self.pairs)

    def label_index(self, truth: int) -> int | None:
        """The index of the label paired with truth ``truth``, or None when it was missed."""
        return self._by_truth.get(truth)


def match_stamps(
    truth_stamps_s: Sequence[float], label_stamps_s: Sequence[float], tolerance_s: float
) -> Matching:
    """The rule of this module on bare stamps (s): truths' contact starts, labels' impact
    stamps."""
    order = sorted(range(len(label_stamps_s)), key=lambda j: label_stamps_s[j])
    ordered = [label_stamps_s[j] for j in order]
    candidates: list[tuple[float, int, int]] = []  # (|offset| s, truth index, label index)
    for i, truth in enumerate(truth_stamps_s):
        lo = bisect.bisect_left(ordered, truth - tolerance_s)
        hi = bisect.bisect_right(ordered, truth + tolerance_s)
        for k in range(lo, hi):
            offset = abs(ordered[k] - truth)
            if offset <= tolerance_s:
                candidates.append((offset, i, order[k]))
    candidates.sort()
    truth_taken: dict[int, int] = {}
    label_taken: set[int] = set()
    for _, i, j in candidates:
        if i not in truth_taken and j not in label_taken:
            truth_taken[i] = j
            label_taken.add(j)
    return Matching(
        pairs=tuple(sorted(truth_taken.items())),
        missed=tuple(i for i in range(len(truth_stamps_s)) if i not in truth_taken),
        extra=tuple(j for j in range(len(label_stamps_s)) if j not in label_taken),
    )


def match(
    truths: Sequence[Mapping[str, Any]], labels: Sequence[Label], tolerance_s: float
) -> Matching:
    """Pair ``impact_truth`` objects with labels by the rule of this module."""
    return match_stamps(
        [float(t[TRUTH_STAMP]) for t in truths],
        [label.impact_stamp_s for label in labels],
        tolerance_s,
    )


def make_label(
    *,
    impact_stamp_s: float,
    decision: Decision,
    confidence: float,
    method: str,
    compute_ms: float,
    data_latency_ms: float,
    signals: Sequence[str],
    overlap: bool,
    calibrated: bool,
    features: Mapping[str, float],
    saturated: Sequence[str] = (),
    imu_inverted: bool = False,
    vibration_inverted: bool = False,
) -> Label:
    """The label of one impact. ``confidence``: the stated label's probability after any cap;
    ``compute_ms``: time the decision took (published as ``latency_ms``); ``features``: the
    impact's features, to which the method's estimates are added. A value that is no finite
    number never reaches the JSON (strict parsers refuse NaN and Infinity): such a feature is left
    out and named in ``non_finite_features``, and such a confidence becomes 0.5 (no idea)."""
    every = {
        **{k: float(v) for k, v in features.items()},
        **{k: float(v) for k, v in decision.estimates.items()},
    }
    return Label(
        impact_stamp_s=impact_stamp_s,
        material=decision.label,
        confidence=round(float(confidence), 6) if math.isfinite(confidence) else 0.5,
        method=method,
        latency_ms=compute_ms,
        data_latency_ms=data_latency_ms,
        signals=tuple(signals),
        overlap=overlap,
        calibrated=calibrated,
        features={k: v for k, v in every.items() if math.isfinite(v)},
        non_finite_features=tuple(sorted(k for k, v in every.items() if not math.isfinite(v))),
        saturated=tuple(saturated),
        imu_mount="inverted" if imu_inverted else None,
        vibration_mount="inverted" if vibration_inverted else None,
        outside_training=tuple(decision.outside_training),
    )


MAX_REMEMBERED = 10_000  # first labels a Revisions keeps to compare later decisions with


class Revisions:
    """The one-label rule (module docstring): turns each decision after the first for the same
    impact (impact stamps within ``tolerance_s``, s, of a first label's; the closest) into a
    revision of it. Give it every label in the order the identifier decided them; start it
    afresh (:meth:`restart`) where the identifier does, at a new time base, whose stamps say
    nothing of the old one's impacts."""

    def __init__(self, tolerance_s: float) -> None:
        self.tolerance_s = tolerance_s
        self._firsts: list[float] = []  # impact stamps of first labels, sorted, s
        self.revisions = 0  # revisions given so far
        self.changed = 0  # of them, those whose material differs from the first label's
        self._material: dict[float, str] = {}

    def restart(self) -> None:
        self._firsts.clear()
        self._material.clear()

    def first_of(self, stamp_s: float) -> float | None:
        """The first label's impact stamp this one is of, s, or None: a new impact."""
        k = bisect.bisect_left(self._firsts, stamp_s)
        near = [
            self._firsts[i]
            for i in (k - 1, k)
            if 0 <= i < len(self._firsts) and abs(self._firsts[i] - stamp_s) <= self.tolerance_s
        ]
        return min(near, key=lambda s: abs(s - stamp_s)) if near else None

    def admit(self, label: Label) -> Label:
        """``label`` as it is to be published: as it is for a new impact, else a revision."""
        first = self.first_of(label.impact_stamp_s)
        if first is None:
            bisect.insort(self._firsts, label.impact_stamp_s)
            self._material[label.impact_stamp_s] = label.material
            if len(self._firsts) > MAX_REMEMBERED:  # the oldest impact is long decided
                oldest = self._firsts.pop(0)
                self._material.pop(oldest, None)
            return label
        self.revisions += 1
        self.changed += self._material.get(first) != label.material
        return dataclasses.replace(label, impact_stamp_s=first, revises=first)


def firsts(labels: Sequence[Label]) -> tuple[list[Label], list[Label]]:
    """(first labels, revisions) of a sequence of published labels: what scoring pairs with
    impacts, and what it counts apart."""
    return (
        [label for label in labels if label.revises is None],
        [label for label in labels if label.revises is not None],
    )
