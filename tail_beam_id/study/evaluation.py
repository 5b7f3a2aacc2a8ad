"""Figures of merit of the identification methods over simulated scene sets.

Every impact counts: one that no label matches (missed detection) counts as wrong. Accuracy
carries a 95 % Wilson interval; balanced accuracy (mean of the coal and gangue recalls) a
95 % interval from the two recalls' Wilson half-widths combined in quadrature. Latency is
split into data latency (simulated time from the true contact to the newest stamp the
decision needed; also from the contact's end, the truth's ``final_separation_stamp``) and
compute time (wall-clock of features and decision, per impact).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tail_beam_id.study.runs import Record

Z95 = 1.959964  # two-sided 95 % normal quantile
CONFIDENT = 0.9  # a wrong label at or above this confidence counts as confidently wrong
RELIABILITY_BINS = (
    0.5,
    0.6,
    0.7,
    0.8,
    0.9,
    0.95,
    1.0,
)  # confidence bins of the calibration figures


def wilson(successes: int, total: int) -> tuple[float, float]:
    """95 % Wilson score interval of a proportion (0..1)."""
    if total == 0:
        return math.nan, math.nan
    p = successes / total
    denom = 1.0 + Z95**2 / total
    centre = (p + Z95**2 / (2 * total)) / denom
    half = Z95 * math.sqrt(p * (1 - p) / total + Z95**2 / (4 * total**2)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


@dataclass
class Summary:
    """Figures of one (scene set, setting, method) group."""

    scene_set: str
    setting: str
    method: str
    window_s: float
    n: int
    accuracy: float
    accuracy_ci: tuple[float, float]
    balanced_accuracy: float
    balanced_ci: tuple[float, float]
    detected: int
    false_labels: int
    confusion: dict[str, dict[str, int]]
    by_size: list[dict[str, Any]]
    data_latency_ms: dict[str, float]
    compute_ms: dict[str, float]
    mean_confidence_wrong: float
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """The fields as a JSON-ready dict."""
        return dict(self.__dict__)


def _percentiles(values: Sequence[float]) -> dict[str, float]:
    """Median, 95th percentile and maximum (NaN when empty)."""
    if not values:
        return {"median": math.nan, "p95": math.nan, "max": math.nan}
    array = np.asarray(values, dtype=float)
    return {
        "median": float(np.median(array)),
        "p95": float(np.percentile(array, 95)),
        "max": float(array.max()),
    }


def reliability(records: Sequence[Record]) -> tuple[float, list[dict[str, float]]]:
    """Expected calibration error of the stated confidences (the count-weighted mean of
    |accuracy - mean confidence| over RELIABILITY_BINS) and the bins, for a reliability diagram.
    Only labelled impacts have a confidence; missed and extra labels count in the accuracy."""
    labelled = [r for r in records if r.label]
    if not labelled:
        return math.nan, []
    confidence = np.array([r.label.confidence for r in labelled])
    correct = np.array([r.correct for r in labelled], dtype=float)
    index = np.clip(
        np.searchsorted(RELIABILITY_BINS, confidence, side="right") - 1,
        0,
        len(RELIABILITY_BINS) - 2,
    )
    bins, ece = [], 0.0
    for b in range(len(RELIABILITY_BINS) - 1):
        inside = index == b
        if inside.any():
            accuracy, mean_conf = float(correct[inside].mean()), float(confidence[inside].mean())
            ece += inside.sum() / confidence.size * abs(accuracy - mean_conf)
            bins.append(
                {
                    "low": RELIABILITY_BINS[b],
                    "high": RELIABILITY_BINS[b + 1],
                    "n": int(inside.sum()),
                    "accuracy": accuracy,
                    "confidence": mean_conf,
                }
            )
    return float(ece), bins


def summarise(records: Sequence[Record], size_bins_m: Sequence[float]) -> Summary:
    """The figures of one group of records (same scene set, setting and method)."""
    first = records[0]
    n = len(records)
    correct = sum(r.correct for r in records)
    recalls, halves = [], []
    for coal in (True, False):
        group = [r for r in records if r.is_coal == coal]
        hits = sum(r.correct for r in group)
        low, high = wilson(hits, len(group))
        recalls.append(hits / len(group) if group else math.nan)
        halves.append((high - low) / 2 if group else math.nan)
    balanced = float(np.mean(recalls))
    half = 0.5 * math.hypot(*halves)
    confusion = {truth: {"coal": 0, "gangue": 0, "missed": 0} for truth in ("coal", "gangue")}
    for r in records:
        said = r.label.material if r.label else "missed"
        confusion["coal" if r.is_coal else "gangue"][said] += 1
    by_size = []
    for low, high in zip(size_bins_m[:-1], size_bins_m[1:]):
        group = [
            r
            for r in records
            if low <= r.radius_m < high or (high == size_bins_m[-1] and r.radius_m == high)
        ]
        if group:
            hits = sum(r.correct for r in group)
            by_size.append(
                {
                    "radius_m": [low, high],
                    "n": len(group),
                    "accuracy": hits / len(group),
                    "ci": wilson(hits, len(group)),
                }
            )
    labelled = [r for r in records if r.label]
    data_latency = [(data_horizon_s(r) - r.contact_stamp_s) * 1e3 for r in labelled]
    after_end = [(data_horizon_s(r) - (r.contact_stamp_s + r.duration_s)) * 1e3 for r in labelled]
    wrong_conf = [r.label.confidence for r in labelled if not r.correct]
    calibration = reliability(records)
    return Summary(
        scene_set=first.scene_set,
        setting=first.setting,
        method=first.method,
        window_s=first.window_s,
        n=n,
        accuracy=correct / n,
        accuracy_ci=wilson(correct, n),
        balanced_accuracy=balanced,
        balanced_ci=(max(0.0, balanced - half), min(1.0, balanced + half)),
        detected=len(labelled),
        false_labels=sum(r.extra_labels for r in records),
        confusion=confusion,
        by_size=by_size,
        data_latency_ms=_percentiles(data_latency),
        compute_ms=_percentiles([r.label.latency_ms for r in labelled]),
        mean_confidence_wrong=float(np.mean(wrong_conf)) if wrong_conf else math.nan,
        # Wall-clock to process each impact's whole stream (detection over every sample, then
        # features and decision): what the per-label compute time leaves out.
        extra={
            "stream_processing_ms": _percentiles([1e3 * r.wall_s for r in records]),
            # From the contact's end (final separation) to the newest stamp the label needed, ms.
            "data_latency_after_contact_end_ms": _percentiles(after_end),
            "confident_wrong": sum(
                1 for r in labelled if not r.correct and r.label.confidence >= CONFIDENT
            ),
            # How many of the labels at >= 0.9 a calibrated identifier with these confidences gets
            # wrong, on average: sum(1 - confidence). A count of confident wrong labels near it is
            # honest confidence; only surer labels (better features), not recalibration, lower it.
            "confident_wrong_if_calibrated": float(
                sum(1.0 - r.label.confidence for r in labelled if r.label.confidence >= CONFIDENT)
            ),
            "outside_training": sum(1 for r in labelled if r.label.outside_training),
            # Extra labels count against accuracy too: correct / (impacts + labels with no impact).
            "accuracy_with_extras": correct / (n + sum(r.extra_labels for r in records)),
            "ece": calibration[0],
            "reliability": calibration[1],
        },
    )


def data_horizon_s(record: Record) -> float:
    """The newest stamp a labelled record's decision needed, s: the label's ``impact_stamp``
    (the detected onset) plus its ``data_latency_ms`` (measured from that onset)."""
    return record.label.impact_stamp_s + record.label.data_latency_ms / 1e3


def group(records: Iterable[Record]) -> dict[tuple[str, str, str, float], list[Record]]:
    """Records by (scene set, setting, method, data window)."""
    groups: dict[tuple[str, str, str, float], list[Record]] = {}
    for r in records:
        groups.setdefault((r.scene_set, r.setting, r.method, r.window_s), []).append(r)
    return groups


def summaries(records: Sequence[Record], size_bins_m: Sequence[float]) -> list[Summary]:
    """The figures of every (scene set, setting, method, data window) group."""
    return [summarise(g, size_bins_m) for g in group(records).values()]


def large_particle_accuracy(
    records: Sequence[Record], min_radius_m: float
) -> tuple[float, tuple[float, float], int]:
    """Accuracy (and its interval, count) over impacts of radius >= ``min_radius_m``."""
    chosen = [r for r in records if r.radius_m >= min_radius_m]
    hits = sum(r.correct for r in chosen)
    return (hits / len(chosen) if chosen else math.nan), wilson(hits, len(chosen)), len(chosen)


def format_table(items: Sequence[Summary]) -> str:
    """A plain-text table of the main figures, one line per group, columns as wide as the
    longest scene set, setting and method."""
    w_set = max([9, *(len(s.scene_set) for s in items)])
    w_setting = max([12, *(len(s.setting) for s in items)])
    w_method = max([11, *(len(s.method) for s in items)])
    lines = [
        f"{'set':{w_set}} {'setting':{w_setting}} {'method':{w_method}} {'win ms':>6} {'n':>4} "
        f"{'acc %':>6} {'95% CI':>13} {'bal %':>6} {'95% CI':>13} {'det':>4} {'fp':>3} "
        f"{'wrong>=.9':>9} {'ECE':>5} {'data ms med/p95':>16} {'cpu ms med/p95':>15}"
    ]
    for s in items:
        acc_low, acc_high = (100 * v for v in s.accuracy_ci)
        bal_low, bal_high = (100 * v for v in s.balanced_ci)
        data, cpu = s.data_latency_ms, s.compute_ms
        lines.append(
            f"{s.scene_set:{w_set}} {s.setting:{w_setting}} {s.method:{w_method}} "
            f"{1e3 * s.window_s:6.1f} {s.n:4d} {100 * s.accuracy:6.1f} "
            f"{acc_low:5.1f}-{acc_high:5.1f}  {100 * s.balanced_accuracy:6.1f} "
            f"{bal_low:5.1f}-{bal_high:5.1f}  {s.detected:4d} {s.false_labels:3d} "
            f"{s.extra.get('confident_wrong', 0):9d} {s.extra.get('ece', math.nan):5.3f} "
            f"{data['median']:7.1f}/{data['p95']:6.1f}  {cpu['median']:6.2f}/{cpu['p95']:6.2f}"
        )
    return "\n".join(lines)


def _group_name(s: Summary) -> str:
    return f"{s.scene_set} {s.setting} {s.method} {1e3 * s.window_s:g} ms"


def format_confusion(s: Summary) -> str:
    """One line: what each truth was labelled (coal, gangue, missed)."""
    c = s.confusion
    return (
        f"{_group_name(s)}: truth coal -> coal {c['coal']['coal']}, "
        f"gangue {c['coal']['gangue']}, missed {c['coal']['missed']}; "
        f"truth gangue -> coal {c['gangue']['coal']}, gangue {c['gangue']['gangue']}, "
        f"missed {c['gangue']['missed']}"
    )


def format_sizes(s: Summary) -> str:
    """One line: accuracy per radius bin."""
    parts = [
        f"{1e3 * b['radius_m'][0]:.0f}-{1e3 * b['radius_m'][1]:.0f} mm: "
        f"{100 * b['accuracy']:.0f}% (n {b['n']})"
        for b in s.by_size
    ]
    return f"{_group_name(s)}: " + "; ".join(parts)


def stamp_summary(items: Sequence[Summary]) -> list[dict[str, Any]]:
    """JSON-ready summaries."""
    return [s.as_dict() for s in items]
