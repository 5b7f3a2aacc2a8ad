"""Benchmark of the identification's compute per impact (what ``tail-beam evaluate`` reports as
"cpu ms" and "compute per impact": the wall-clock of deciding one impact, features and
decision) with the decision's shortcuts and without them; prints figures, asserts nothing.

The shortcuts, each of which leaves every label and feature as it was
(test/id/stream/test_decision_shortcuts.py):

* the read-outs get the samples about the pulse, not the whole buffers
  (:func:`tail_beam_id.stream.decision.around`);
* the contact fit's first-pass refinement is left out where every pair it could pick starts
  the same second ring-down (:func:`tail_beam_id.signals.contact_fit.one_second_ring_down`);
* the pressure response's peak and the fit's coarse durations are worked out once.

Supports drawn from the ``structures`` ranges (as ``tail-beam evaluate --sets structures``
draws them, on seeds of its own), each recorded as one stream of stream-scene impacts at the
shipped layout (accelerometer at 25.6 kHz) and with the sensors drawn with it, identified
knowing the support (the self-calibration left out: it costs seconds per support and does not
change what a decision computes). Each stream is identified in alternating rounds with and
without the shortcuts. Figures: the labels' compute time (wall clock, ms), median over the
impacts of every round, as evaluate takes it; and the decision's CPU time (process time, ms),
each impact's least over the rounds (the round the other processes disturbed least), median
over the impacts: on a shared machine the wall clock mostly measures the others' load. Ratios:
without / with. Then where a decision's CPU time goes: the shares of the pressure fit, the
impulse and the contact fit (its half-sine grid searches and its ring-down poles), and in how
many two-pass fits the first pass's refinement was left out.

With ``--before PATH`` (a checkout of other code, e.g. ``git worktree add /tmp/before
<commit>``) the same streams are also identified by that code and by this tree, each in a
process of its own (PYTHONPATH), in alternating rounds: the CPU figure of each and their ratio
(before / this), and whether every label and feature agrees.

Usage: python test/bench/bench_decision_cost.py [--supports 2] [--impacts 20] [--repeats 3]
       [--before PATH]
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from unittest import mock

import numpy as np

from tail_beam_id.signals import contact_fit
from tail_beam_id.signals.features import BeamModel
from tail_beam_id.stream import decision
from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.replay import point_tuples, replay
from tail_beam_id.study.dataset import settings, support_streams
from tail_beam_id.study.runs import true_profile_section
from tail_beam_sim.config import load_parameters

SEED = 52417  # no evaluation or training set uses it


def _pressure_peak_each_time(model: BeamModel, window_s: float) -> float:
    """BeamModel.pressure_peak worked out again on every call."""
    return float(np.max(np.abs(model.pressure_response(np.linspace(0.0, window_s, 200)))))


@contextlib.contextmanager
def straightforward() -> Iterator[None]:
    """The decision without its shortcuts (module docstring): the whole buffers to the
    read-outs, the first pass always refined, the pressure peak and the coarse durations worked
    out on every call."""
    with (
        mock.patch.object(decision, "around", lambda stamp_s, values, *_: (stamp_s, values)),
        mock.patch.object(contact_fit, "one_second_ring_down", lambda *_: False),
        mock.patch.object(BeamModel, "pressure_peak", _pressure_peak_each_time),
        mock.patch.object(
            contact_fit, "_coarse_durations", contact_fit._coarse_durations.__wrapped__
        ),
    ):
        yield


@contextlib.contextmanager
def cpu_times(into: list[float]) -> Iterator[None]:
    """Appends each decision's CPU time (process time, ms) to ``into``."""
    decide = decision.ImpactDecider.decide

    def timed(self, impact):
        started = time.process_time()
        try:
            return decide(self, impact)
        finally:
            into.append(1e3 * (time.process_time() - started))

    with mock.patch.object(decision.ImpactDecider, "decide", timed):
        yield


# The parts of a decision whose CPU time the split reports: (module, function name, label).
PARTS = (
    (decision, "fit_pressure", "pressure fit"),
    (decision, "imu_impulse", "impulse"),
    (decision, "fit_contact", "contact fit"),
    (contact_fit, "_best", "  of it: half-sine grid searches"),
    (contact_fit, "ringing_poles", "  of it: ring-down poles (matrix pencil)"),
)


def split(params: dict, streams: dict[str, list]) -> None:
    """Prints where a decision's CPU time goes (process time, shares of the decisions' total),
    over every stream once, with the shortcuts."""
    spent = {label: 0.0 for *_, label in PARTS}
    calls = {label: 0 for *_, label in PARTS}
    searches_per_fit: list[int] = []  # the grid searches of each contact fit that searched
    decisions: list[float] = []
    with contextlib.ExitStack() as stack:
        for module, name, label in PARTS:
            real = getattr(module, name)

            def timed(*args, _real=real, _label=label, **kwargs):
                started = time.process_time()
                calls[_label] += 1
                searches = calls[PARTS[3][2]]
                try:
                    return _real(*args, **kwargs)
                finally:
                    spent[_label] += time.process_time() - started
                    if _real is contact_fit.fit_contact and calls[PARTS[3][2]] > searches:
                        searches_per_fit.append(calls[PARTS[3][2]] - searches)

            stack.enter_context(mock.patch.object(module, name, timed))
        stack.enter_context(cpu_times(decisions))
        for recorded_streams in streams.values():
            for recorded in recorded_streams:
                identify(params, recorded)
    total = sum(decisions) / 1e3
    shares = ", ".join(f"{label.strip()} {100 * t / total:.0f} %" for label, t in spent.items())
    print(f"where a decision's CPU time goes ({len(decisions)} decisions): {shares}")
    two_pass = [n for n in searches_per_fit if n >= 3]
    print(
        f"contact fits that searched: {len(searches_per_fit)}, {len(two_pass)} of them in two "
        f"passes; the first pass's refinement left out in {two_pass.count(3)} "
        f"(grid searches per two-pass fit {np.mean(two_pass) if two_pass else 0:.2f}, 4 without)"
    )


def identify(params: dict, recorded) -> list:
    """Every label of one recorded support stream, identified knowing the support."""
    known = {**recorded.params, "calibration": true_profile_section(recorded.params)}
    return replay(
        StreamIdentifier("statistical", params["identification"], known),
        recorded.pressure,
        recorded.imu,
        recorded.rebounds,
        vibration=recorded.vibration,
        points=point_tuples(recorded.points),
    )


def draw(params: dict, supports: int, impacts: int) -> dict[str, list]:
    """The recorded support streams, by sensors: the shipped layout's, and drawn with each."""
    shipped = settings(params, [1.0], ["shipped"])[0]
    return {
        name: list(
            support_streams(params, supports, impacts, SEED, which="structures", setting=setting)
        )
        for name, setting in (("shipped", shipped), ("drawn", None))
    }


def worker(supports: int, impacts: int) -> None:
    """One round of the code on PYTHONPATH: prints, by sensors, each decision's CPU time (ms)
    and every label (stamp, material, confidence, features) as JSON."""
    params = load_parameters()
    out = {}
    for name, recorded_streams in draw(params, supports, impacts).items():
        times: list[float] = []
        with cpu_times(times):
            labels = [label for r in recorded_streams for label in identify(params, r)]
        out[name] = {
            "cpu_ms": times,
            "labels": [
                [x.impact_stamp_s, x.material, x.confidence, sorted(x.features.items())]
                for x in labels
            ],
        }
    print(json.dumps(out))


def against(before: Path, supports: int, impacts: int, repeats: int) -> None:
    """The CPU figure of the code at ``before`` and of this tree, alternating rounds, each in a
    process of its own; and whether their labels agree."""
    trees = {"before": str(before), "this tree": str(Path(__file__).resolve().parents[2])}
    rounds: dict[str, list[dict]] = {tree: [] for tree in trees}
    for _ in range(repeats):
        for tree, path in trees.items():
            done = subprocess.run(
                [sys.executable, __file__, "--worker"]
                + [f"--supports={supports}", f"--impacts={impacts}"],
                env={**os.environ, "PYTHONPATH": path},
                capture_output=True,
                text=True,
                check=True,
            )
            rounds[tree].append(json.loads(done.stdout.strip().splitlines()[-1]))
    for name in rounds["before"][0]:
        cpu = {
            tree: float(np.median(np.min([r[name]["cpu_ms"] for r in rounds[tree]], axis=0)))
            for tree in trees
        }
        same = rounds["before"][0][name]["labels"] == rounds["this tree"][0][name]["labels"]
        print(
            f"{name} sensors, against {before}: CPU per decision {cpu['before']:.2f} ms before, "
            f"{cpu['this tree']:.2f} ms this tree ({cpu['before'] / cpu['this tree']:.2f} x); "
            f"labels and features the same: {same}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--supports", type=int, default=2, help="drawn supports (default 2)")
    parser.add_argument("--impacts", type=int, default=20, help="impacts per support")
    parser.add_argument("--repeats", type=int, default=3, help="rounds of each (default 3)")
    parser.add_argument("--before", type=Path, default=None, help="code to compare against")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        worker(args.supports, args.impacts)
        return
    print(f"load average before: {os.getloadavg()[0]:.2f} ({os.cpu_count()} cores, shared)")
    params = load_parameters()
    streams = draw(params, args.supports, args.impacts)
    same = True
    for name, recorded_streams in streams.items():
        # Per round and mode, each decision's wall and CPU time in decision order (the same
        # impacts in the same order every round).
        wall: dict[str, list[list[float]]] = {"with": [], "without": []}
        cpu: dict[str, list[list[float]]] = {"with": [], "without": []}
        for _ in range(args.repeats):
            for mode in ("without", "with"):
                labels, times = [], []
                with contextlib.ExitStack() as stack:
                    stack.enter_context(cpu_times(times))
                    if mode == "without":
                        stack.enter_context(straightforward())
                    for recorded in recorded_streams:
                        labels.append(identify(params, recorded))
                wall[mode].append([label.latency_ms for run in labels for label in run])
                cpu[mode].append(times)
                kept = [[dataclasses.replace(x, latency_ms=None) for x in run] for run in labels]
                if mode == "without":
                    reference = kept
                else:
                    same = same and kept == reference
        figures = {
            mode: (
                statistics.median(v for run in wall[mode] for v in run),
                float(np.median(np.min(np.array(cpu[mode]), axis=0))),
            )
            for mode in wall
        }
        (wall_without, cpu_without), (wall_with, cpu_with) = figures["without"], figures["with"]
        print(
            f"{name} sensors, {args.supports} supports, {len(wall['with'][0])} labels, "
            f"{args.repeats} rounds: compute per impact (wall, median) {wall_without:.2f} ms "
            f"without the shortcuts, {wall_with:.2f} ms with ({wall_without / wall_with:.2f} x); "
            f"CPU (median over impacts of each one's least over the rounds) {cpu_without:.2f} "
            f"-> {cpu_with:.2f} ms ({cpu_without / cpu_with:.2f} x)"
        )
    print(f"labels and features the same with and without: {same}")
    split(params, streams)
    if args.before is not None:
        against(args.before, args.supports, args.impacts, args.repeats)
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
