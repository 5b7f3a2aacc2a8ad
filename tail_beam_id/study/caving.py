"""The caving study: a face drawn once through its sequence for each closing rule, each rule
fed by the true lumps or by labels, and the top-coal recovery and gangue content each gives.

Three kinds of source feed the rules:

- ``truth``: every lump that strikes the tail beam with its true material, confidence 1, at
  once; the ``gangue_share`` estimate is the true instantaneous share, its interval a point.
- ``stand-in``: labels drawn from the true lumps by :class:`LabelModel`, a cheap stand-in for
  the sensors and the identifier: each label right with chance ``accuracy``, its confidence
  drawn from a Beta distribution (mean ``confidence_right`` or ``confidence_wrong``), known
  ``latency_s`` after its impact; the ``gangue_share`` estimate is the share of gangue labels
  over each ``share_interval_s`` with its Wilson 95 % interval.
- ``identified:<layout>``: the drawn flow through the physics core, the layout's sensors and
  the identifier (:mod:`tail_beam_id.study.caving_pipeline`).

The oracle rule closes on the truth alone (:class:`~tail_beam_id.caving.events.TrueShare`),
the same under every source, and runs once. Every rule of a seed meets the same face (the
drawing model's and the labels' random numbers are seeded alike), so rules differ by what
they decide, not by the draw.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from tail_beam_id.caving.events import (
    LabelEvent,
    ShareEstimate,
)
from tail_beam_id.caving.rule_feed import RuleFeed
from tail_beam_id.caving.rules import Oracle, Rule, rule_factories
from tail_beam_id.study.caving_pipeline import (
    LAYOUTS,
    SOURCE_PREFIX,
    IdentifiedWindowFeed,
    Pipeline,
    layout_of,
)
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.drawing import GANGUE
from tail_beam_sim.physics.face import (
    DrawnCell,
    Face,
    FaceParams,
    ShareMeter,
    draw_window,
    schedule,
)
from tail_beam_sim.spec import CAVING, CAVING_LABELS, CAVING_PIPELINE

__all__ = [
    "FIELD_TRIAL",
    "ALL_SOURCES",
    "IDENTIFIED_SOURCES",
    "SOURCES",
    "CavingRun",
    "LabelModel",
    "ORACLE_CURVE",
    "Shortfall",
    "Summary",
    "oracle_curve_rules",
    "run_study",
    "run_one",
    "shortfalls",
    "summarise",
    "write_chart",
]

SOURCES = ("truth", "stand-in")
# The identified sources (:mod:`tail_beam_id.study.caving_pipeline`), one per sensor layout.
IDENTIFIED_SOURCES = tuple(SOURCE_PREFIX + layout for layout in LAYOUTS)
ALL_SOURCES = SOURCES + IDENTIFIED_SOURCES
# Tashan 8222 (12 m top coal, close at first gangue, groups of 9 supports): top coal drawn and
# gangue content, fractions.
FIELD_TRIAL = ("Tashan 8222 field trial", 0.8053, 0.0400)
WILSON_Z = 1.959964  # 95 %
ORACLE_CURVE = "oracle@"  # a rule name: the oracle at one level of its curve, oracle@0.25


@dataclass(frozen=True)
class LabelModel:
    """The stand-in identifier (``caving.labels``): lumps per tonne drawn that strike the beam
    (1/t), chance a label is right, mean confidences of right and wrong labels, their Beta
    concentration, latency (s) and the ``gangue_share`` estimate's interval (s)."""

    impacts_per_tonne: float
    accuracy: float
    confidence_right: float
    confidence_wrong: float
    confidence_concentration: float
    latency_s: float
    share_interval_s: float

    @classmethod
    def from_params(cls, labels: Mapping[str, Any]) -> LabelModel:
        return cls(**CAVING_LABELS.check(labels))

    def confidence(self, rng: np.random.Generator, right: bool) -> float:
        """A label's stated confidence, in [0.5, 1]: 0.5 + 0.5 Beta with the mean asked."""
        mean = self.confidence_right if right else self.confidence_wrong
        m = min(max((mean - 0.5) / 0.5, 1e-3), 1.0 - 1e-3)
        k = self.confidence_concentration
        return 0.5 + 0.5 * float(rng.beta(m * k, (1.0 - m) * k))


def wilson(gangue: int, total: int, z: float = WILSON_Z) -> tuple[float, float]:
    """Wilson score interval of a share ``gangue / total`` (total > 0)."""
    p = gangue / total
    denominator = 1.0 + z * z / total
    centre = (p + z * z / (2 * total)) / denominator
    half = z * math.sqrt(p * (1 - p) / total + z * z / (4 * total * total)) / denominator
    return min(max(0.0, centre - half), p), max(min(1.0, centre + half), p)


class WindowFeed(RuleFeed):
    """A window's controller in the study: asked after each drawn cell, it makes the lumps that
    struck the beam, their labels (``source``) and share estimates, feeds the rule whatever has
    become known by the cell's end, and says whether the rule decided."""

    def __init__(
        self,
        rule: Rule,
        source: str,
        model: LabelModel,
        rngs: tuple[np.random.Generator, np.random.Generator],
        window_kg: float,
        opened_s: float,
    ) -> None:
        self.source, self.model = source, model
        self.lumps_rng, self.labels_rng = rngs  # the lumps alike under every source
        self.meter = ShareMeter(window_kg)
        self.opened_s = opened_s
        self.interval = 0  # the share estimate's interval being counted
        self.counts = [0, 0]  # [labels, gangue labels] in it
        super().__init__(rule, opened_s)

    def _estimates_until(self, stamp_s: float) -> None:
        """Share estimates of the intervals that ended by ``stamp_s`` (stand-in source)."""
        length = self.model.share_interval_s
        while self.opened_s + (self.interval + 1) * length <= stamp_s:
            end = self.opened_s + (self.interval + 1) * length
            total, gangue = self.counts
            if total:
                low, high = wilson(gangue, total)
                share = gangue / total
                self._push(
                    ShareEstimate(end, share, low, high, length, end + self.model.latency_s)
                )
            self.interval += 1
            self.counts = [0, 0]

    def __call__(self, cell: DrawnCell) -> bool:
        share = self.meter.add(cell.material, cell.mass_kg)
        material = "gangue" if cell.material == GANGUE else "coal"
        lumps = self.lumps_rng.poisson(self.model.impacts_per_tonne * cell.mass_kg / 1000.0)
        stamps = np.sort(self.lumps_rng.uniform(cell.start_s, cell.end_s, lumps))
        for stamp in stamps.tolist():
            if self.source == "truth":
                self._push(LabelEvent(stamp, material, 1.0))
                continue
            self._estimates_until(stamp)
            right = bool(self.labels_rng.random() < self.model.accuracy)
            said = material if right else ("coal" if material == "gangue" else "gangue")
            confidence = self.model.confidence(self.labels_rng, right)
            self._push(LabelEvent(stamp, said, confidence, stamp + self.model.latency_s))
            self.counts[0] += 1
            self.counts[1] += said == "gangue"
        if self.source == "truth":
            self._push(ShareEstimate(cell.end_s, share, share, share, 0.0))
        else:
            self._estimates_until(cell.end_s)
        return self._end_cell(cell.end_s, share)


@dataclass(frozen=True)
class CavingRun:
    """One rule, one source, one seed over the face: top-coal recovery and gangue content
    (fractions), simulated drawing time (s), wall time (s), windows that ran to max_window_s,
    lumps struck on the beams (identified sources; 0 otherwise)."""

    rule: str
    source: str
    seed: int
    recovery: float
    gangue_content: float
    drawing_s: float
    wall_s: float
    timed_out: int
    lumps: int = 0


def run_one(
    face_params: FaceParams,
    make_rule: Callable[[], Rule],
    rule: str,
    source: str,
    model: LabelModel,
    seed: int,
    pipeline: Pipeline | None = None,
    window_done: Callable[[int, float], None] | None = None,
) -> CavingRun:
    """Draw the face once with ``make_rule`` closing every window, fed by ``source``; an
    identified source needs the ``pipeline`` of its layout. ``window_done(windows, clock_s)``
    after each window."""
    if source not in ALL_SOURCES:
        layout_of(source)  # names a bad layout
        raise InputError("source", source, f"must be one of {', '.join(ALL_SOURCES)}")
    layout = layout_of(source)
    if layout is not None and (pipeline is None or pipeline.layout != layout):
        raise InputError("pipeline", layout, f"source {source} needs the pipeline of its layout")
    start = time.perf_counter()
    params = face_params.with_changes(seed=seed)
    face = Face(params)
    rngs = (np.random.default_rng([seed, 1]), np.random.default_rng([seed, 2]))
    timed_out = lumps = 0
    for window, visit in enumerate(schedule(params)):
        if pipeline is not None and layout is not None:
            sensor_seed = int(np.random.SeedSequence([seed, 4, window]).generate_state(1)[0])
            feed: Callable[[DrawnCell], bool] = IdentifiedWindowFeed(
                make_rule(),
                pipeline,
                rngs,
                params.share_window_kg,
                face.clock_s,
                sensor_seed,
                window,
            )
        else:
            feed = WindowFeed(
                make_rule(), source, model, rngs, params.share_window_kg, face.clock_s
            )
        timed_out += draw_window(face, visit, feed).timed_out
        if isinstance(feed, IdentifiedWindowFeed):
            lumps += feed.tally.lumps
        if window_done is not None:
            window_done(window + 1, face.clock_s)
    return CavingRun(
        rule,
        source,
        seed,
        face.recovery(),
        face.gangue_content(),
        face.clock_s,
        time.perf_counter() - start,
        timed_out,
        lumps,
    )


def pipelines_for(
    sources: Sequence[str],
    physics: Mapping[str, Any] | None,
    caving: Mapping[str, Any],
) -> dict[str, Pipeline]:
    """The pipeline of each identified source among ``sources`` (layout -> Pipeline), on the
    ``physics`` parameters (:func:`~tail_beam_id.study.caving_pipeline.pipeline_parameters`)."""
    layouts = [layout for layout in map(layout_of, sources) if layout is not None]
    if not layouts:
        return {}
    if physics is None:
        raise InputError("physics", None, "identified sources need the physics parameters")
    section = CAVING_PIPELINE.check(caving.get("pipeline") or {})
    labels = CAVING_LABELS.check(caving.get("labels") or {})
    return {
        layout: Pipeline(physics, layout, section["lumps"], labels["impacts_per_tonne"])
        for layout in dict.fromkeys(layouts)
    }


def oracle_curve_rules(caving: Mapping[str, Any]) -> dict[str, Callable[[], Rule]]:
    """The oracle at each of ``caving.oracle_curve_levels``, by name (``oracle@0.25``): drawn
    over the same seeds, the most top coal any rule recovers at each gangue content."""
    levels = CAVING.check(caving, only=["oracle_curve_levels"])["oracle_curve_levels"]
    return {f"{ORACLE_CURVE}{level:g}": (lambda level=level: Oracle(level)) for level in levels}


def _rule_makers(caving: Mapping[str, Any], oracle_curve: bool) -> dict[str, Callable[[], Rule]]:
    """Every rule of the ``caving`` section by name, with the oracle's curve when asked."""
    makers = rule_factories(caving)
    if oracle_curve:
        makers.update(oracle_curve_rules(caving))
    return makers


def _is_oracle(rule: str) -> bool:
    """Whether ``rule`` reads the truth alone (the oracle, at its level or on its curve)."""
    return rule == "oracle" or rule.startswith(ORACLE_CURVE)


def run_study(
    face_params: FaceParams,
    caving: Mapping[str, Any],
    seeds: Iterable[int],
    rules: Sequence[str] | None = None,
    sources: Sequence[str] = SOURCES,
    progress: Callable[[int, int], None] | None = None,
    physics: Mapping[str, Any] | None = None,
    window_progress: Callable[[str, int, float], None] | None = None,
    jobs: int = 1,
    oracle_curve: bool = False,
) -> list[CavingRun]:
    """Every rule (``rules``: a subset by name) under every source for every seed; the oracle
    under the truth only (it reads the truth whatever the source), ``fixed_time`` under the
    truth and the stand-in only (it reads the clock alone). ``progress(done, total)`` after each
    run; ``window_progress(run, windows, clock_s)`` after each window of an identified run;
    ``physics``: the parameters identified sources run on; ``jobs``: worker processes (the
    runs are independent; per-window progress then is not reported); ``oracle_curve``: also
    the oracle at each of ``caving.oracle_curve_levels`` (:func:`oracle_curve_rules`)."""
    named = rule_factories(caving)
    model = LabelModel.from_params(caving.get("labels") or {})
    chosen = list(named) if rules is None else list(rules)
    for name in chosen:
        if name not in named:
            raise InputError("rules", name, f"must be among {', '.join(named)}")
    makers = _rule_makers(caving, oracle_curve)
    chosen += [name for name in makers if name not in named and name not in chosen]
    for source in sources:
        if source not in ALL_SOURCES:
            layout_of(source)
            raise InputError("sources", source, f"must be among {', '.join(ALL_SOURCES)}")
    plan = [
        (name, source, seed)
        for seed in seeds
        for name in chosen
        for source in (("truth",) if _is_oracle(name) else sources)
        if not (name == "fixed_time" and layout_of(source) is not None)
    ]
    if jobs > 1:
        return _run_in_processes(face_params, caving, plan, physics, jobs, progress, oracle_curve)
    pipelines = pipelines_for(sources, physics, caving)
    runs = []
    for done, (name, source, seed) in enumerate(plan, 1):
        layout = layout_of(source)
        tell = None
        if window_progress is not None and layout is not None:
            label = f"{done}/{len(plan)} {name} {source} seed {seed}"

            def tell(windows: int, clock_s: float, label: str = label) -> None:
                window_progress(label, windows, clock_s)

        runs.append(
            run_one(
                face_params,
                makers[name],
                name,
                source,
                model,
                seed,
                pipelines.get(layout) if layout is not None else None,
                tell,
            )
        )
        if progress is not None:
            progress(done, len(plan))
    return runs


_WORKER_PIPELINES: dict[str, Pipeline] = {}  # a worker process's pipelines, built once each


def _run_planned(
    face_params: FaceParams,
    caving: Mapping[str, Any],
    name: str,
    source: str,
    seed: int,
    physics: Mapping[str, Any] | None,
    oracle_curve: bool = False,
) -> CavingRun:
    """One planned run in a worker process (its rule and pipeline made there)."""
    layout = layout_of(source)
    pipeline = None
    if layout is not None:
        if layout not in _WORKER_PIPELINES:
            _WORKER_PIPELINES.update(pipelines_for([source], physics, caving))
        pipeline = _WORKER_PIPELINES[layout]
    model = LabelModel.from_params(caving.get("labels") or {})
    maker = _rule_makers(caving, oracle_curve)[name]
    return run_one(face_params, maker, name, source, model, seed, pipeline)


def _run_in_processes(
    face_params: FaceParams,
    caving: Mapping[str, Any],
    plan: Sequence[tuple[str, str, int]],
    physics: Mapping[str, Any] | None,
    jobs: int,
    progress: Callable[[int, int], None] | None,
    oracle_curve: bool = False,
) -> list[CavingRun]:
    """The plan's runs over ``jobs`` worker processes, in the plan's order (each run seeded on
    its own: the same runs as one process gives, wall times aside)."""
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from multiprocessing import get_context

    pipelines_for([s for _, s, _ in plan], physics, caving)  # bad settings refused up front
    out: list[CavingRun | None] = [None] * len(plan)
    with ProcessPoolExecutor(jobs, mp_context=get_context("spawn")) as pool:
        futures = {
            pool.submit(
                _run_planned, face_params, caving, name, source, seed, physics, oracle_curve
            ): k
            for k, (name, source, seed) in enumerate(plan)
        }
        for done, future in enumerate(as_completed(futures), 1):
            out[futures[future]] = future.result()
            if progress is not None:
                progress(done, len(plan))
    return [run for run in out if run is not None]


@dataclass(frozen=True)
class Summary:
    """A rule under a source over the seeds: means and 95 % t-intervals of recovery and gangue
    content (fractions), mean drawing time (s), total wall time (s)."""

    rule: str
    source: str
    seeds: int
    recovery: float
    recovery_interval: tuple[float, float]
    gangue_content: float
    gangue_interval: tuple[float, float]
    drawing_s: float
    wall_s: float
    timed_out: int


def _interval(values: np.ndarray) -> tuple[float, float]:
    mean = float(values.mean())
    if values.size < 2:
        return mean, mean
    half = float(stats.t.ppf(0.975, values.size - 1) * values.std(ddof=1) / math.sqrt(values.size))
    return mean - half, mean + half


def summarise(runs: Sequence[CavingRun]) -> list[Summary]:
    """Runs grouped by (rule, source), in the order they first appear."""
    groups: dict[tuple[str, str], list[CavingRun]] = {}
    for run in runs:
        groups.setdefault((run.rule, run.source), []).append(run)
    out = []
    for (rule, source), group in groups.items():
        recovery = np.array([r.recovery for r in group])
        gangue = np.array([r.gangue_content for r in group])
        out.append(
            Summary(
                rule,
                source,
                len(group),
                float(recovery.mean()),
                _interval(recovery),
                float(gangue.mean()),
                _interval(gangue),
                float(np.mean([r.drawing_s for r in group])),
                float(sum(r.wall_s for r in group)),
                sum(r.timed_out for r in group),
            )
        )
    return out


@dataclass(frozen=True)
class Shortfall:
    """How far a rule under a source falls below the oracle's curve: per seed, the top coal the
    oracle recovers at no more gangue content than the rule's (the curve's upper envelope,
    linear between its levels) minus the rule's recovery; mean and 95 % t-interval over the
    seeds where the curve reaches that low a gangue content (fractions)."""

    mean: float
    interval: tuple[float, float]
    seeds: int


def frontier_recovery(points: Sequence[tuple[float, float]], gangue: float) -> float:
    """The most recovery the (gangue content, recovery) ``points`` of one seed's oracle curve
    reach at no more than ``gangue``: their upper envelope (each point's recovery raised to the
    best of those with less gangue), linear between points, flat beyond the last; NaN below the
    first point's gangue content."""
    ordered = sorted(points)
    if not ordered or gangue < ordered[0][0]:
        return math.nan
    g = np.array([p[0] for p in ordered])
    r = np.maximum.accumulate(np.array([p[1] for p in ordered]))
    return float(np.interp(gangue, g, r))


def shortfalls(runs: Sequence[CavingRun]) -> dict[tuple[str, str], Shortfall]:
    """Each (rule, source)'s :class:`Shortfall` against the oracle curve run on the same seeds
    (``oracle@<level>`` runs, with ``oracle`` itself a point of it); empty without a curve."""
    curves: dict[int, list[tuple[float, float]]] = {}
    for run in runs:
        if _is_oracle(run.rule):
            curves.setdefault(run.seed, []).append((run.gangue_content, run.recovery))
    if not any(run.rule.startswith(ORACLE_CURVE) for run in runs):
        return {}
    gaps: dict[tuple[str, str], list[float]] = {}
    for run in runs:
        if run.rule.startswith(ORACLE_CURVE) or run.seed not in curves:
            continue
        best = frontier_recovery(curves[run.seed], run.gangue_content)
        gaps.setdefault((run.rule, run.source), [])
        if math.isfinite(best):
            gaps[(run.rule, run.source)].append(best - run.recovery)
    out = {}
    for key, values in gaps.items():
        if values:
            gap = np.array(values)
            out[key] = Shortfall(float(gap.mean()), _interval(gap), gap.size)
        else:
            out[key] = Shortfall(math.nan, (math.nan, math.nan), 0)
    return out


def write_chart(summaries: Sequence[Summary], path: str | Path, title: str = "") -> Path:
    """Top-coal recovery against gangue content, one point per rule and source with its
    intervals over seeds; the oracle, its curve over its levels when run, and the field trial
    marked."""
    from tail_beam_sim.plotting import pyplot, save_figure

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 5.5))
    markers = {"truth": "o", "stand-in": "s"}
    markers.update(zip(IDENTIFIED_SOURCES, ("D", "^", "v", "P")))
    curve = sorted(
        (100 * s.gangue_content, 100 * s.recovery)
        for s in summaries
        if s.rule.startswith(ORACLE_CURVE)
    )
    if curve:
        ax.plot(
            [p[0] for p in curve],
            [p[1] for p in curve],
            "--",
            color="black",
            linewidth=1,
            label="oracle at other levels (truth; seeds' means)",
        )
    rules = list(dict.fromkeys(s.rule for s in summaries if not _is_oracle(s.rule)))
    colours = {rule: plt.get_cmap("tab10")(k % 10) for k, rule in enumerate(rules)}
    for s in summaries:
        if s.rule.startswith(ORACLE_CURVE):
            continue
        x, y = 100 * s.gangue_content, 100 * s.recovery
        xerr = [[x - 100 * s.gangue_interval[0]], [100 * s.gangue_interval[1] - x]]
        yerr = [[y - 100 * s.recovery_interval[0]], [100 * s.recovery_interval[1] - y]]
        oracle = s.rule == "oracle"
        ax.errorbar(
            x,
            y,
            xerr=xerr,
            yerr=yerr,
            fmt="*" if oracle else markers.get(s.source, "o"),
            markersize=14 if oracle else 7,
            color="black" if oracle else colours[s.rule],
            markerfacecolor="none" if s.source == "truth" and not oracle else None,
            capsize=3,
            label=f"{s.rule} ({s.source})" if not oracle else "oracle (truth)",
        )
    name, recovery, gangue = FIELD_TRIAL
    ax.plot(100 * gangue, 100 * recovery, "X", color="red", markersize=12, label=name)
    ax.fill_between(
        [3.0, 5.0], 75.0, 90.0, color="0.9", zorder=0, label="published range, 10-12 m seams"
    )
    ax.set_xlabel("gangue content of the drawn mass, %")
    ax.set_ylabel("top-coal recovery, %")
    ax.set_title(
        title
        or "Closing rules: top-coal recovery against gangue content\n(open: truth-fed; "
        "square: stand-in; diamond, triangles, plus: identified layouts)",
        fontsize=9,
    )
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="lower right", ncol=2)
    return save_figure(fig, path, 120, "--chart")
