"""Recovery and gangue content against label latency: the caving study on the stand-in labels,
each label (and gangue_share estimate) known a given time after its impact.

A window controller acts on what it knows, and a label that comes late lets the window draw on
meanwhile: each second of latency is about 300 kg more drawn before a closing decision takes
effect. The stand-in source (:class:`~tail_beam_id.study.caving.LabelModel`) states its
latency (``caving.labels.latency_s``); this runs the study once per latency asked, the rest of
the face, the labels and the seeds unchanged, and charts each rule's recovery and gangue
content against it, the oracle (which reads the truth, at no latency) drawn across.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tail_beam_id.caving.rules import rule_factories
from tail_beam_id.study.caving import Summary, run_study, summarise
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.face import FaceParams
from tail_beam_sim.spec import CAVING_LABELS

__all__ = ["LatencyRow", "latency_study", "parse_latencies", "write_latency_chart"]

SOURCE = "stand-in"


@dataclass(frozen=True)
class LatencyRow:
    """One rule's :class:`Summary` with the stand-in labels known ``latency_s`` after impact."""

    latency_s: float
    summary: Summary


def latency_study(
    face_params: FaceParams,
    caving: Mapping[str, Any],
    seeds: Sequence[int],
    latencies_s: Sequence[float],
    rules: Sequence[str] | None = None,
    jobs: int = 1,
    progress: Callable[[int, int], None] | None = None,
) -> list[LatencyRow]:
    """Every rule (``rules``: a subset by name; the oracle once, at no latency) on the stand-in
    labels at each latency (s, each checked as ``caving.labels.latency_s``), over ``seeds``."""
    if not latencies_s:
        raise InputError("latencies", latencies_s, "must name at least one latency, s")
    labels = dict(caving.get("labels") or {})
    checked = []
    for latency in latencies_s:
        value = CAVING_LABELS.check({**labels, "latency_s": latency}, only=["latency_s"])
        checked.append(float(value["latency_s"]))
    names = list(rule_factories(caving)) if rules is None else list(rules)
    plans = [[r for r in names if r != "oracle" or k == 0] for k in range(len(checked))]
    total = len(seeds) * sum(len(chosen) for chosen in plans)  # one run per rule and seed
    rows: list[LatencyRow] = []
    done = 0
    for latency, chosen in zip(checked, plans):
        if not chosen:
            continue
        section = {**caving, "labels": {**labels, "latency_s": latency}}
        tell = None
        if progress is not None:

            def tell(runs: int, _: int, before: int = done) -> None:
                progress(before + runs, total)

        runs = run_study(face_params, section, seeds, chosen, (SOURCE,), tell, jobs=jobs)
        done += len(runs)
        rows += [LatencyRow(0.0 if s.rule == "oracle" else latency, s) for s in summarise(runs)]
    return rows


def write_latency_chart(rows: Sequence[LatencyRow], path: str | Path) -> Path:
    """Two panels against latency (s): top-coal recovery and gangue content (%), one line per
    rule with its 95 % intervals over seeds; the oracle as a dashed line across each."""
    from tail_beam_sim.plotting import pyplot, save_figure

    plt = pyplot()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7.5, 7.0), sharex=True)
    rules = list(dict.fromkeys(r.summary.rule for r in rows if r.summary.rule != "oracle"))
    colours = {rule: plt.get_cmap("tab10")(k % 10) for k, rule in enumerate(rules)}
    for rule in rules:
        mine = sorted((r for r in rows if r.summary.rule == rule), key=lambda r: r.latency_s)
        x = [r.latency_s for r in mine]
        for ax, value, interval in (
            (top, "recovery", "recovery_interval"),
            (bottom, "gangue_content", "gangue_interval"),
        ):
            y = [100 * getattr(r.summary, value) for r in mine]
            low = [y_ - 100 * getattr(r.summary, interval)[0] for y_, r in zip(y, mine)]
            high = [100 * getattr(r.summary, interval)[1] - y_ for y_, r in zip(y, mine)]
            ax.errorbar(
                x, y, yerr=[low, high], fmt="o-", capsize=3, color=colours[rule], label=rule
            )
    for r in rows:
        if r.summary.rule == "oracle":
            top.axhline(100 * r.summary.recovery, color="black", ls="--", label="oracle (truth)")
            bottom.axhline(100 * r.summary.gangue_content, color="black", ls="--")
    top.set_ylabel("top-coal recovery, %")
    bottom.set_ylabel("gangue content, %")
    bottom.set_xlabel("label latency (stand-in labels), s")
    latencies = [r.latency_s for r in rows if r.latency_s > 0]
    if latencies and max(latencies) / max(min(latencies), 1e-9) > 20 and min(latencies) > 0:
        bottom.set_xscale("log")
    top.set_title("Closing rules against label latency (stand-in labels)", fontsize=9)
    for ax in (top, bottom):
        ax.grid(True, alpha=0.3)
    top.legend(fontsize=7, loc="best")
    return save_figure(fig, path, 120, "--latency-chart")


def parse_latencies(text: str) -> list[float]:
    """Comma-separated latencies (s); InputError naming ``--latencies`` for one that is no
    finite number."""
    out = []
    for part in (p.strip() for p in text.split(",")):
        try:
            value = float(part)
        except ValueError:
            raise InputError("--latencies", part, "must be comma-separated seconds") from None
        if not math.isfinite(value):
            raise InputError("--latencies", part, "must be a finite number of seconds")
        out.append(value)
    return out
