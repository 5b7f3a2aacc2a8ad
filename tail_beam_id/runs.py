"""Run identification methods over simulated scene sets and record, per impact, the truth and
what each method said (shared by training and evaluation)."""

from __future__ import annotations

import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from tail_beam_id.dataset import Setting, simulate_set
from tail_beam_id.identifier import StreamIdentifier
from tail_beam_id.replay import replay


@dataclass
class Record:
    """One impact at one setting under one method: the truth and the matched label (or None).

    ``extra_labels`` counts labels that matched no impact (false detections); times in s.
    """

    scene_set: str
    setting: str
    method: str
    window_s: float
    index: int
    material: str
    is_coal: bool
    radius_m: float
    contact_stamp_s: float
    duration_s: float
    label: dict[str, Any] | None
    extra_labels: int
    wall_s: float

    @property
    def correct(self) -> bool:
        return self.label is not None and (self.label["label"] == "coal") == self.is_coal


def match(labels: Sequence[Mapping[str, Any]], contact_stamp_s: float, tolerance_s: float) -> tuple[dict[str, Any] | None, int]:
    """The label nearest the true contact within the tolerance, and how many others there are."""
    near = [l for l in labels if abs(l["impact_stamp"] - contact_stamp_s) <= tolerance_s]
    best = min(near, key=lambda l: abs(l["impact_stamp"] - contact_stamp_s), default=None)
    return (dict(best) if best else None), len(labels) - (1 if best else 0)


def run_set(
    params: Mapping[str, Any],
    scene_set: str,
    count: int,
    seed: int,
    chosen: Sequence[Setting],
    methods: Sequence[str],
    tolerance_s: float,
    tier: str | None = None,
    windows_s: Sequence[float] = (),
) -> Iterator[Record]:
    """Simulate ``count`` impacts of ``scene_set`` and identify each with every method, at the
    configured data window and at each of ``windows_s`` (s) as well."""
    built: dict[str, Any] = {}
    sections = [dict(params["identification"])] + [with_window(params["identification"], w) for w in windows_s]
    for impact in simulate_set(params, scene_set, count, seed, chosen, tier):
        for key, result in impact.results.items():
            truth = result.truth()
            for method in methods:
                for section in sections:
                    identifier = StreamIdentifier(method, section, params, prebuilt=built.get(method))
                    built[method] = identifier.method
                    started = time.perf_counter()
                    labels = replay(identifier, result.pressure, result.imu, [result.rebound])
                    wall = time.perf_counter() - started
                    label, extra = match(labels, result.contact_stamp_s, tolerance_s)
                    yield Record(
                        scene_set=scene_set, setting=key, method=method, window_s=float(section["window_s"]), index=impact.index,
                        material=truth["material"], is_coal=truth["label"] == "coal", radius_m=truth["radius_m"],
                        contact_stamp_s=result.contact_stamp_s,
                        duration_s=truth["final_separation_stamp"] - truth["contact_start_stamp"],
                        label=label, extra_labels=extra, wall_s=wall,
                    )


def with_window(section: Mapping[str, Any], window_s: float) -> dict[str, Any]:
    """The identification section with another data window (s); the windows that must fit in
    it shrink with it."""
    changed = dict(section)
    changed["window_s"] = window_s
    changed["impulse_post_s"] = min(float(section["impulse_post_s"]), window_s)
    changed["overlap_window_s"] = min(float(section["overlap_window_s"]), window_s)
    return changed
