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
without the shortcuts; per impact the label's compute time (wall clock, ms) and the decision's
CPU time (process time, ms: on a shared machine the steadier of the two); medians over the
impacts of every round, and their ratio (without / with).

Usage: python test/bench/bench_decision_cost.py [--supports 2] [--impacts 20] [--repeats 3]
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
import statistics
import time
from collections.abc import Iterator
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--supports", type=int, default=2, help="drawn supports (default 2)")
    parser.add_argument("--impacts", type=int, default=20, help="impacts per support")
    parser.add_argument("--repeats", type=int, default=3, help="rounds of each (default 3)")
    args = parser.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.2f} ({os.cpu_count()} cores, shared)")
    params = load_parameters()
    shipped = settings(params, [1.0], ["shipped"])[0]
    streams = {
        name: list(
            support_streams(
                params, args.supports, args.impacts, SEED, which="structures", setting=setting
            )
        )
        for name, setting in (("shipped", shipped), ("drawn", None))
    }
    same = True
    for name, recorded_streams in streams.items():
        wall: dict[str, list[float]] = {"with": [], "without": []}
        cpu: dict[str, list[float]] = {"with": [], "without": []}
        for _ in range(args.repeats):
            for mode in ("without", "with"):
                labels = []
                with contextlib.ExitStack() as stack:
                    stack.enter_context(cpu_times(cpu[mode]))
                    if mode == "without":
                        stack.enter_context(straightforward())
                    for recorded in recorded_streams:
                        labels.append(identify(params, recorded))
                wall[mode] += [label.latency_ms for run in labels for label in run]
                kept = [[dataclasses.replace(x, latency_ms=None) for x in run] for run in labels]
                if mode == "without":
                    reference = kept
                else:
                    same = same and kept == reference
        impacts = len(wall["with"]) // args.repeats
        medians = {k: (statistics.median(wall[k]), statistics.median(cpu[k])) for k in wall}
        print(
            f"{name} sensors, {args.supports} supports, {impacts} labels, {args.repeats} rounds: "
            f"compute per impact median {medians['without'][0]:.2f} ms without the shortcuts, "
            f"{medians['with'][0]:.2f} ms with ({medians['without'][0] / medians['with'][0]:.2f} "
            f"x); CPU {medians['without'][1]:.2f} -> {medians['with'][1]:.2f} ms "
            f"({medians['without'][1] / medians['with'][1]:.2f} x)"
        )
    print(f"labels and features the same with and without: {same}")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
