"""Labels: the ``label`` JSON object the identifier gives (docs/interface.md), built here
(:func:`make_label`), and the one rule that says which impact a label is of when it is scored
against the truth (:func:`match`).

The rule (demo, evaluate, training, benchmarks and tests all use :func:`match`): a label is of
the impact whose contact start (``impact_truth.contact_start_stamp``) lies within
``identification.match_tolerance_s`` of its ``impact_stamp`` (inclusive). Labels and impacts
pair one to one, closest pair first: of all truth-label pairs within the tolerance the closest is
paired, then the closest of those left, and so on (ties: earlier truth, then earlier label). An
impact left without a label is missed; a label left without an impact is an extra (false)
detection.
"""

from __future__ import annotations

import bisect
import math
from functools import cached_property
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from tail_beam_id.methods import Decision
from tail_beam_sim.errors import require_range

TRUTH_STAMP = "contact_start_stamp"  # the impact_truth field a label's stamp is compared with, s
LABEL_STAMP = "impact_stamp"  # the label field holding the detected contact start, s
MATCH_TOLERANCE_MAX_S = 0.1  # above this a label could reach a neighbouring impact of a stream (>= 0.2 s apart), s


def match_tolerance_s(section: Mapping[str, Any]) -> float:
    """``identification.match_tolerance_s`` of the ``identification`` section, validated (0, 0.1] s."""
    return require_range("identification.match_tolerance_s", section.get("match_tolerance_s"), 0.0, MATCH_TOLERANCE_MAX_S,
                         low_open=True, unit="s")


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


def match_stamps(truth_stamps_s: Sequence[float], label_stamps_s: Sequence[float], tolerance_s: float) -> Matching:
    """The rule of this module on bare stamps (s): truths' contact starts, labels' impact stamps."""
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


def match(truths: Sequence[Mapping[str, Any]], labels: Sequence[Mapping[str, Any]], tolerance_s: float) -> Matching:
    """Pair ``impact_truth`` objects with ``label`` objects by the rule of this module."""
    return match_stamps([float(t[TRUTH_STAMP]) for t in truths], [float(l[LABEL_STAMP]) for l in labels], tolerance_s)


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
) -> dict[str, Any]:
    """The ``label`` object of one impact: the contract's fields (docs/interface.md) first, then
    the suite's own; the optional keys (``saturated``, ``imu_mount``, ``outside_training``) only
    when they say something. ``confidence``: the stated label's probability after any cap;
    ``compute_ms``: time the decision took (published as ``latency_ms``); ``features``: the
    impact's features, to which the method's estimates are added. A value that is no finite
    number never reaches the JSON (strict parsers refuse NaN and Infinity): such a feature is left
    out and named in ``non_finite_features``, and such a confidence becomes 0.5 (no idea)."""
    every = {**{k: float(v) for k, v in features.items()}, **{k: float(v) for k, v in decision.estimates.items()}}
    non_finite = sorted(k for k, v in every.items() if not math.isfinite(v))
    label: dict[str, Any] = {
        LABEL_STAMP: impact_stamp_s,
        "label": decision.label,
        "confidence": round(float(confidence), 6) if math.isfinite(confidence) else 0.5,
        "method": method,
        "latency_ms": compute_ms,
        "data_latency_ms": data_latency_ms,
        "signals": list(signals),
        "overlap": overlap,
        "calibrated": calibrated,
        "features": {k: v for k, v in every.items() if math.isfinite(v)},
    }
    if non_finite:
        label["non_finite_features"] = non_finite
    if saturated:
        label["saturated"] = list(saturated)
    if imu_inverted:
        label["imu_mount"] = "inverted"
    if decision.outside_training:
        label["outside_training"] = list(decision.outside_training)
    return label
