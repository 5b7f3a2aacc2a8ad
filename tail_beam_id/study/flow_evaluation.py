"""The ``flow`` scene set of ``tail-beam evaluate``: the gangue share read from the suite's
drawing-opening flows (:func:`tail_beam_sim.physics.flow.simulate_flow`, config/flow.yaml)
against the truth, on the nominal support and on supports drawn from the foreign ranges, at
flow rates from sparse to dense, with the shipped layout and with the IMU alone.

Each case is one flow (pure coal until about ``boundary_s``, the share by mass then rising to
``final_share_by_mass`` over about ``ramp_s``) and one pure-coal flow of ``coal_s``, both
identified as ``tail-beam identify`` does (a :class:`SharingIdentifier` on the replayed
streams), the support known to it by a profile: calibrated on its own flow by default, as
``identify`` does, or config/ (``--no-calibrate``), or the drawn support itself. Figures:

* the share's mean absolute error per interval (the estimate against the share by count of the
  lumps that struck in it; intervals where none struck or nothing was estimated are left out);
* the detection delay at 1/5 and 1/3: when the estimate first reaches the level (at or after the
  first gangue lump) minus when the true interval share first does, s (the interval ends; nan
  when the truth never reaches it, or reaches it less than ``CROSSING_WITHIN_S`` before the
  flow ends while the estimate has not yet; inf when the estimate never does);
* false crossings: intervals of the pure-coal flow whose estimate reaches 1/5;
* the same for the crossing rule (:mod:`tail_beam_id.stream.share_alarm`: the level measured
  from each flow's first ``alarm_reference_s`` of top coal, reached in ``alarm_intervals``
  consecutive intervals): its delay at 1/5 and 1/3, and the pure-coal intervals it is raised
  after;
* per-impact accuracy (Wilson 95 %) of the labels, extra and missed labels counting as wrong;
* what one label says of its lump: the area under the ROC curve of the matched labels' scores
  (:func:`tail_beam_id.stream.share.label_score`) for gangue, and the fraction of them resting
  on an acceleration pulse.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tail_beam_id.calibration.offline import calibrate, ringing_predictor, with_profile
from tail_beam_id.stream.label import match_stamps, match_tolerance_s
from tail_beam_id.stream.replay import point_tuples, replay
from tail_beam_id.stream.share import Z_95, GangueShare, ShareConfig, label_score
from tail_beam_id.stream.share_alarm import alarm_states
from tail_beam_id.stream.share_reader import SharingIdentifier
from tail_beam_id.study.dataset import evaluation_params
from tail_beam_id.study.evaluation import CONFIDENT, wilson
from tail_beam_id.study.flow import FlowRecording, record_sim_flow, true_shares
from tail_beam_id.study.runs import true_profile_section
from tail_beam_id.study.supports import SupportDraw, draw_support, support_ranges

FLOW_SEED = 46001  # the flow set's seed (training flows use share_training.TRAINING_SEED + n)
LEVELS = (0.2, 1.0 / 3.0)  # the shares whose crossing is timed
# A read should cross a level within this of the truth, s. Where the truth reached it less than
# this before the flow's last interval ended and the read had not yet, how long the read would
# have taken is unknown: that delay is not judged (nan), nor counted against the target.
CROSSING_WITHIN_S = 2.0
LAYOUTS = ("shipped", "imu")  # the shipped sensors; the same without the accelerometer
FLOW_PROFILES = ("nominal", "self-calibrated", "true")  # how the identifier knows the support
SENSOR_RATES = ("pressure_rate_hz", "imu_rate_hz", "camera_frame_rate_hz")


@dataclass(frozen=True)
class FlowScene:
    """The flow every case runs: its length, when the boundary arrives and how long the share
    by mass takes to rise to ``final_share_by_mass`` (s), and the pure-coal flow's length (s)."""

    duration_s: float = 12.0
    boundary_s: float = 6.0
    ramp_s: float = 2.0
    final_share_by_mass: float = 0.7
    coal_s: float = 12.0


@dataclass
class FlowCase:
    """One support, layout and rate: what the share read-out gave against the truth."""

    support: str
    layout: str
    rate_per_s: float
    errors: list[float] = field(default_factory=list)  # |estimate - truth| per interval
    signed: list[float] = field(default_factory=list)  # estimate - truth per interval
    standard_errors: list[float] = field(default_factory=list)  # the stated ones, per interval
    # Each label matched to a lump: (its score, the lump is gangue, the label used the
    # accelerometer): how much a single label says of its lump.
    scored: list[tuple[float, bool, bool]] = field(default_factory=list)
    # level -> delay, s; nan: the truth never reached the level, or too late to judge
    # (CROSSING_WITHIN_S); inf: the read never did while the truth did.
    delays_s: dict[float, float] = field(default_factory=dict)
    # The same with the estimate's lower 95 % bound reaching the level (a cautious alarm).
    low_delays_s: dict[float, float] = field(default_factory=dict)
    coal_intervals: int = 0
    false_crossings: int = 0  # pure-coal intervals whose estimate reached 1/5
    false_low_crossings: int = 0  # ... whose lower 95 % bound reached 1/5
    # The crossing rule (share_alarm): level -> delay, s, and pure-coal intervals raised at 1/5.
    alarm_delays_s: dict[float, float] = field(default_factory=dict)
    false_alarms: int = 0
    # Levels the truth reached less than CROSSING_WITHIN_S before the flow's last interval end.
    late_truth: set[float] = field(default_factory=set)
    methods: dict[str, int] = field(default_factory=dict)  # interval basis -> count
    # interval basis -> [intervals whose 95 % interval holds the truth, intervals scored]
    covered_by_method: dict[str, list[int]] = field(default_factory=dict)
    correct: int = 0
    confident_wrong: int = 0  # matched labels wrong at confidence >= CONFIDENT
    impacts: int = 0  # lumps, plus labels matching none
    series: list[tuple[float, float, float | None]] = field(default_factory=list)

    @property
    def mae(self) -> float:
        return float(np.mean(self.errors)) if self.errors else math.nan

    def mae_interval(self, hop_s: float = 0.5, interval_s: float = 1.0) -> tuple[float, float]:
        """A 95 % interval of the MAE: mean +- 1.96 standard deviations of the absolute errors
        over the root of the intervals' count divided by their overlap (interval_s / hop_s:
        overlapping intervals share lumps, so their errors are not independent)."""
        n = len(self.errors)
        if n < 2:
            return math.nan, math.nan
        effective = max(n * hop_s / interval_s, 1.0)
        half = Z_95 * float(np.std(self.errors, ddof=1)) / math.sqrt(effective)
        return max(0.0, self.mae - half), self.mae + half

    @property
    def bias(self) -> float:
        return float(np.mean(self.signed)) if self.signed else math.nan

    @property
    def stated_se(self) -> float:
        """The mean standard error the estimator stated."""
        return float(np.mean(self.standard_errors)) if self.standard_errors else math.nan

    @property
    def coverage(self) -> float:
        """The fraction of intervals whose 95 % interval holds the true share."""
        held = sum(h for h, _ in self.covered_by_method.values())
        return held / len(self.errors) if self.errors else math.nan

    @property
    def score_auc(self) -> float:
        """The area under the ROC curve of the matched labels' scores for their lumps being
        gangue (0.5: a label's score says nothing of its lump; 1: it separates them)."""
        return rank_auc([s for s, _, _ in self.scored], [g for _, g, _ in self.scored])

    @property
    def accelerometer_fraction(self) -> float:
        """The fraction of matched labels that rest on the accelerometer (or the IMU's pulse)."""
        return float(np.mean([a for _, _, a in self.scored])) if self.scored else math.nan

    @property
    def accuracy(self) -> float:
        return self.correct / self.impacts if self.impacts else math.nan

    def as_dict(self) -> dict[str, Any]:
        low, high = wilson(self.correct, self.impacts) if self.impacts else (math.nan, math.nan)
        return {
            "support": self.support,
            "layout": self.layout,
            "rate_per_s": self.rate_per_s,
            "mae": self.mae,
            "mae_ci": list(self.mae_interval()),
            "errors": self.signed,
            "bias": self.bias,
            "stated_se": self.stated_se,
            "coverage": self.coverage,
            "coverage_by_method": {k: list(v) for k, v in sorted(self.covered_by_method.items())},
            "score_auc": self.score_auc,
            "accelerometer_fraction": self.accelerometer_fraction,
            "intervals": len(self.errors),
            "delay_s": {f"{level:.3f}": d for level, d in self.delays_s.items()},
            "low_delay_s": {f"{level:.3f}": d for level, d in self.low_delays_s.items()},
            "false_low_crossings": self.false_low_crossings,
            "alarm_delay_s": {f"{level:.3f}": d for level, d in self.alarm_delays_s.items()},
            "false_alarms": self.false_alarms,
            "late_truth": sorted(self.late_truth),
            "coal_intervals": self.coal_intervals,
            "false_crossings": self.false_crossings,
            "methods": self.methods,
            "accuracy": self.accuracy,
            "confident_wrong": self.confident_wrong,
            "accuracy_ci": [low, high],
            "impacts": self.impacts,
        }


def rank_auc(scores: Sequence[float], positive: Sequence[bool]) -> float:
    """Area under the ROC curve (Mann-Whitney, ties counted half); nan without both classes."""
    x = np.asarray(scores, dtype=float)
    y = np.asarray(positive, dtype=bool)
    n_pos, n_neg = int(y.sum()), int((~y).sum())
    if n_pos == 0 or n_neg == 0:
        return math.nan
    order = np.argsort(x, kind="mergesort")
    ranks = np.empty(x.size)
    sorted_x = x[order]
    # Average ranks over ties.
    start = 0
    for end in range(1, x.size + 1):
        if end == x.size or sorted_x[end] != sorted_x[start]:
            ranks[order[start:end]] = 0.5 * (start + end - 1) + 1.0
            start = end
    return float((ranks[y].sum() - n_pos * (n_pos + 1) / 2.0) / (n_pos * n_neg))


def flow_supports(params: Mapping[str, Any], foreign: int, seed: int) -> list[tuple[str, Any]]:
    """(name, SupportDraw or None for the nominal) of the nominal support and ``foreign``
    supports drawn from the foreign ranges, with the shipped sensors."""
    ranges = support_ranges(evaluation_params(params), "foreign")
    rng = np.random.default_rng(np.random.SeedSequence([seed, 5]))
    rates = {k: float(params["sensors"][k]) for k in SENSOR_RATES}
    out: list[tuple[str, Any]] = [("nominal", None)]
    for n in range(foreign):
        draw = draw_support(ranges, rng, rng, params["modes"]).with_sensors(
            rates, float(params["sensors"]["vibration_rate_hz"]), 1.0
        )
        out.append((f"foreign-{n + 1}", draw))
    return out


def identify_flow(
    recording: FlowRecording,
    layout: str,
    method: str | None = None,
    model_params: Mapping[str, Any] | None = None,
) -> tuple[list, list[GangueShare]]:
    """Labels and shares of a recording as ``tail-beam identify`` reads a bag whose support it
    knows by ``model_params`` (:func:`reading_params`; default: the recorded support itself)."""
    model = recording.params if model_params is None else model_params
    section = dict(recording.params["identification"])
    # The profile's detection settings (the ringing it measured) with the evaluation's section.
    section["detection"] = {
        **section.get("detection", {}),
        **(model.get("identification", {}).get("detection") or {}),
    }
    identifier = SharingIdentifier(method, params=section, model_params=model)
    labels = replay(
        identifier,
        recording.pressure,
        recording.imu,
        recording.rebounds,
        vibration=recording.vibration if layout == "shipped" else None,
        points=point_tuples(recording.points),
    )
    return labels, identifier.take_shares()


def reading_params(
    params: Mapping[str, Any], recording: FlowRecording, profile: str, layout: str
) -> Mapping[str, Any]:
    """What the identifier knows of the recorded support under ``profile`` (FLOW_PROFILES):
    ``nominal`` config/ (``tail-beam identify --no-calibrate``), ``self-calibrated`` a profile
    calibrated on the recording itself with the layout's signals (``tail-beam identify``'s
    default), ``true`` the drawn support's own parameters (:func:`tail_beam_id.study.runs.
    true_profile_section`: not what a calibration reads from a recording besides them, such
    as the ringing's decay, so no upper bound)."""
    if profile == "true":
        section = true_profile_section(recording.params)
        if layout == "shipped" and recording.vibration is not None:
            # what a calibration would also read from the recording: the ringing's predictor
            section.update(
                ringing_predictor(
                    recording.params,
                    (recording.vibration.sample_stamps_s(), recording.vibration.accel_mps2),
                )
            )
        return {**recording.params, "calibration": section}
    if profile == "nominal":
        return params
    vibration = recording.vibration if layout == "shipped" else None
    found = calibrate(
        params,
        (recording.pressure.stamp_s, recording.pressure.pressure_pa),
        (recording.imu.stamp_s, recording.imu.linear_acceleration_mps2[:, 2]),
        lambda calibrated: identify_flow(recording, layout, "statistical", calibrated)[0],
        (vibration.sample_stamps_s(), vibration.accel_mps2)
        if vibration is not None and vibration.count
        else None,
        [r.stamp_s for r in recording.rebounds],
    )
    return with_profile(params, found)


def first_reaching(
    ends_s: Sequence[float], values: Sequence[float | None], level: float, after_s: float
) -> float:
    """The first interval end at or after ``after_s`` whose value reaches ``level`` (nan if
    none), s."""
    for end, value in zip(ends_s, values):
        if end >= after_s and value is not None and not math.isnan(value) and value >= level:
            return end
    return math.nan


def crossing_delay(true_at_s: float, seen_at_s: float, last_end_s: float) -> float:
    """How long after the truth (at ``true_at_s``) a read reached a level (at ``seen_at_s``), s,
    in a flow whose last interval ends at ``last_end_s``; either stamp nan where it never did.
    nan: the truth never reached the level, or did less than CROSSING_WITHIN_S before the end
    while the read had not (how long it would have taken is unknown); inf: the read never did,
    though the flow ran CROSSING_WITHIN_S or more past the truth's crossing."""
    if math.isnan(true_at_s):
        return math.nan
    if math.isnan(seen_at_s):
        return math.nan if true_at_s > last_end_s - CROSSING_WITHIN_S else math.inf
    return seen_at_s - true_at_s


def alarm_values(shares: Sequence[GangueShare], level: float, config: ShareConfig) -> list:
    """1 after each interval the crossing rule at ``level`` is raised, else 0."""
    return [1.0 if on else 0.0 for on in alarm_states(shares, level, config)]


def score_case(
    case: FlowCase,
    recording: FlowRecording,
    labels: Sequence,
    shares: Sequence[GangueShare],
    config: ShareConfig = ShareConfig(),
) -> None:
    """Fill ``case`` with one flow's figures."""
    intervals = [(s.start_stamp_s, s.end_stamp_s) for s in shares]
    truth = true_shares(recording, intervals)
    ends = [s.end_stamp_s for s in shares]
    for share, (true, n) in zip(shares, truth):
        case.methods[share.basis_method] = case.methods.get(share.basis_method, 0) + 1
        if share.share is not None and n:
            case.errors.append(abs(share.share - true))
            case.signed.append(share.share - true)
            case.standard_errors.append(float(share.standard_error or 0.0))
            holds = share.low - 1e-9 <= true <= share.high + 1e-9
            tally = case.covered_by_method.setdefault(share.basis_method, [0, 0])
            tally[0] += holds
            tally[1] += 1
    case.series = [(s.end_stamp_s, t, s.share) for s, (t, _) in zip(shares, truth)]
    # The boundary arrives with the first gangue lump.
    gangue_at = recording.lump_stamps_s()[recording.gangue()]
    boundary = float(gangue_at.min()) if gangue_at.size else math.inf
    last_end = ends[-1] if ends else math.nan
    for level in LEVELS:
        true_at = first_reaching(ends, [t for t, _ in truth], level, boundary)
        if true_at > last_end - CROSSING_WITHIN_S:
            case.late_truth.add(level)
        for delays, values, reach in (
            (case.delays_s, [s.share for s in shares], level),
            (case.low_delays_s, [None if s.share is None else s.low for s in shares], level),
            (case.alarm_delays_s, alarm_values(shares, level, config), 1.0),
        ):
            delays[level] = crossing_delay(
                true_at, first_reaching(ends, values, reach, boundary), last_end
            )
    tolerance = match_tolerance_s(recording.params["identification"])
    stamps = list(recording.lump_stamps_s())
    matching = match_stamps(stamps, [lab.impact_stamp_s for lab in labels], tolerance)
    gangue = recording.gangue()
    right = [(labels[j].material == "gangue") == gangue[i] for i, j in matching.pairs]
    case.correct += sum(right)
    case.confident_wrong += sum(
        not ok and labels[j].confidence >= CONFIDENT for ok, (_, j) in zip(right, matching.pairs)
    )
    case.scored += [
        (
            label_score(labels[j]),
            bool(gangue[i]),
            bool({"vibration", "imu"} & set(labels[j].signals)),
        )
        for i, j in matching.pairs
    ]
    case.impacts += len(stamps) + len(matching.extra)


def score_coal(
    case: FlowCase, shares: Sequence[GangueShare], config: ShareConfig = ShareConfig()
) -> None:
    """Count the pure-coal flow's intervals, those whose estimate (its lower bound) reached 1/5
    and those the crossing rule at 1/5 is raised after."""
    case.coal_intervals += len(shares)
    case.false_crossings += sum(s.share is not None and s.share >= LEVELS[0] for s in shares)
    case.false_low_crossings += sum(s.share is not None and s.low >= LEVELS[0] for s in shares)
    case.false_alarms += sum(alarm_states(shares, LEVELS[0], config))


def scene_flow(
    params: Mapping[str, Any],
    scene: FlowScene,
    rate_per_s: float,
    seed: int,
    draw: SupportDraw | None,
    vibration: bool = True,
) -> FlowRecording:
    """The flow of ``scene`` at ``rate_per_s`` lumps a second on ``draw`` (None: the nominal
    support), as the flow set records it (its pure-coal flow aside)."""
    return record_sim_flow(
        params,
        rate_per_s,
        scene.duration_s,
        scene.boundary_s,
        scene.ramp_s,
        scene.final_share_by_mass,
        seed,
        draw,
        vibration=vibration,
    )


def run_flow_set(
    params: Mapping[str, Any],
    rates_per_s: Sequence[float],
    foreign: int,
    scene: FlowScene = FlowScene(),
    layouts: Sequence[str] = LAYOUTS,
    seed: int = FLOW_SEED,
    method: str | None = None,
    profile: str = "self-calibrated",
) -> Iterator[FlowCase]:
    """Every case of the flow set, support by support, rate by rate, layout by layout, each
    support known to the identifier by ``profile`` (:func:`reading_params`)."""
    accelerometer = "shipped" in layouts  # the IMU layout alone: not simulated at all
    for s_index, (name, draw) in enumerate(flow_supports(params, foreign, seed)):
        for r_index, rate in enumerate(rates_per_s):
            case_seed = seed + 100 * s_index + r_index
            flow = scene_flow(params, scene, rate, case_seed, draw, accelerometer)
            coal = record_sim_flow(
                params,
                rate,
                scene.coal_s,
                0.0,
                0.0,
                0.0,
                case_seed + 50,
                draw,
                vibration=accelerometer,
            )
            config = ShareConfig.from_params(flow.params["identification"].get("gangue_share"))
            for layout in layouts:
                case = FlowCase(name, layout, float(rate))
                # A support is calibrated once, on its flow; its pure-coal flow is read with it.
                model = reading_params(params, flow, profile, layout)
                labels, shares = identify_flow(flow, layout, method, model)
                score_case(case, flow, labels, shares, config)
                score_coal(case, identify_flow(coal, layout, method, model)[1], config)
                yield case


def describe_support(draw: SupportDraw | None) -> str:
    return "config/" if draw is None else draw.describe()


def coverage_line(cases: Sequence[FlowCase]) -> str:
    """How often the stated 95 % intervals held the true share, over ``cases``, in all and by
    the method that read the interval: whether the intervals are honest."""
    totals: dict[str, list[int]] = {}
    for case in cases:
        for method, (held, scored) in case.covered_by_method.items():
            tally = totals.setdefault(method, [0, 0])
            tally[0] += held
            tally[1] += scored
    held = sum(t[0] for t in totals.values())
    scored = sum(t[1] for t in totals.values())
    if not scored:
        return "95 % intervals holding the true share: none scored"
    parts = ", ".join(
        f"{method} {h} of {n} ({100 * h / n:.0f} %)" for method, (h, n) in sorted(totals.items())
    )
    return (
        f"95 % intervals holding the true share: {held} of {scored} "
        f"({100 * held / scored:.0f} %; {parts})"
    )


def confident_wrong_line(cases: Sequence[FlowCase]) -> str:
    """How many of ``cases``' lumps got a wrong label at confidence CONFIDENT or more (a
    confident wrong label is worse than an unsure one)."""
    wrong = sum(c.confident_wrong for c in cases)
    impacts = sum(c.impacts for c in cases)
    share = f" ({100 * wrong / impacts:.1f} %)" if impacts else ""
    return (
        f"wrong labels at confidence >= {CONFIDENT:g}: {wrong} of {impacts} impacts{share}, "
        "impacts being the lumps and any extra labels"
    )


def format_flow_table(cases: Sequence[FlowCase]) -> str:
    """One line per case: MAE, delays and pure-coal intervals reaching 1/5 (by the estimate;
    in brackets by its lower 95 % bound), how the intervals were read, per-impact accuracy."""
    lines = [
        "support     layout  lumps/s  MAE pts (n)  bias  SE  95%in  delay 1/5 s    delay 1/3 s    "
        "coal >= 1/5    alarm 1/5, 1/3 s  coal alarm  AUC  accel  intervals by          "
        "per-impact accuracy (95 %)"
    ]
    for c in cases:
        low, high = wilson(c.correct, c.impacts) if c.impacts else (math.nan, math.nan)
        how = ", ".join(f"{k} {v}" for k, v in sorted(c.methods.items()))
        d1, d3 = (c.delays_s.get(level, math.nan) for level in LEVELS)
        b1, b3 = (c.low_delays_s.get(level, math.nan) for level in LEVELS)
        mae = (
            f"{100 * c.mae:5.1f} ({len(c.errors):3d}) {100 * c.bias:+5.1f} "
            f"{100 * c.stated_se:4.1f} {100 * c.coverage:4.0f}%"
        )
        coal = f"{c.false_crossings:2d} ({c.false_low_crossings:2d})/{c.coal_intervals:<3d}"
        accuracy = f"{100 * c.accuracy:5.1f} % ({100 * low:.1f}-{100 * high:.1f})"
        a1, a3 = (c.alarm_delays_s.get(level, math.nan) for level in LEVELS)
        alarm = (
            f"{a1:5.1f}, {a3:5.1f}     {c.false_alarms:3d}/{c.coal_intervals:<3d}  "
            f"{c.score_auc:4.2f} {100 * c.accelerometer_fraction:4.0f}%"
        )
        lines.append(
            f"{c.support:11s} {c.layout:7s} {c.rate_per_s:7g}  {mae}  {d1:5.1f} ({b1:5.1f})  "
            f"{d3:5.1f} ({b3:5.1f})  {coal}  {alarm}  {how:20s}  {accuracy}"
        )
    return "\n".join(lines)
