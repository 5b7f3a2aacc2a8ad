"""``tail-beam demo``: the suite's main job in one command.

Runs sim_node (a generated caving stream), id_node and bag_recorder as real ROS 2 nodes in
one process, prints each impact with its label as they come, then the confusion table and the
accuracy against the truth, and leaves the bag (its path printed) for ``bag_replay`` and
``tail-beam identify``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from tail_beam_id.stream.label import Label, Matching, match, match_tolerance_s
from tail_beam_sim.bags.records import STORAGES
from tail_beam_sim.config import load_parameters
from tail_beam_sim.errors import InputError, require_new_path, require_range

# Fields the scoreboard reads of a truth, and their types: a message without them (another
# process on the topic, a foreign tool) is skipped, not trusted; a label must read as a Label.
TRUTH_FIELDS = {
    "contact_start_stamp": (int, float),
    "label": str,
    "material": str,
    "radius_m": (int, float),
    "position_m": (int, float),
}
LABELS = ("coal", "gangue")
LATE_S = 2.0  # wall time after which an impact is shown without its label, s
SETTLE_S = 1.5  # wall time the identifier gets after the data ends, s (its flush comes first)


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "demo", help="simulate a caving stream, identify it live and record it, then score it"
    )
    parser.add_argument(
        "--count", type=int, default=20, help="particles in the stream (default 20)"
    )
    parser.add_argument(
        "--gangue-fraction",
        type=float,
        default=0.5,
        help="share of gangue particles (default 0.5)",
    )
    parser.add_argument(
        "--seed", type=int, default=1, help="seed of the generated stream (default 1)"
    )
    parser.add_argument(
        "--realtime-factor",
        type=float,
        default=1.0,
        help="simulation s per wall s; 0 = as fast as possible",
    )
    parser.add_argument("--method", help="identification method (default: identification.method)")
    parser.add_argument(
        "--bag", help="bag directory to create (default out/bags/demo_<UTC date-time>)"
    )
    parser.add_argument(
        "--storage", choices=sorted(STORAGES), default="mcap", help="bag storage (default mcap)"
    )
    parser.add_argument(
        "--namespace", default="", help="run the support under this namespace, e.g. /support_07"
    )
    parser.add_argument(
        "--face",
        type=int,
        nargs="?",
        const=3,
        metavar="N",
        help="instead: a group of N supports (default 3) drawn one after another under "
        "/support_001 ..., their windows closed by one caving_node (docs/caving.md)",
    )
    parser.add_argument("--rule", help="with --face: the closing rule (default: caving_node.rule)")
    parser.add_argument(
        "--config",
        action="append",
        metavar="YAML",
        help="with --face: a parameter file applied to every node (flow, caving, ...); repeatable",
    )
    parser.add_argument(
        "--processes",
        type=int,
        metavar="P",
        help="with --face: run the supports' sim_node and id_node over P processes (default: "
        "one per core, at most one per support); the first also runs the controller and every "
        "recorder",
    )
    parser.add_argument(
        "--check-offline",
        action="store_true",
        help="with --face: afterwards, identify each support's bag offline and feed the same rule "
        "its labels: the decisions must be the live ones",
    )
    parser.set_defaults(func=run)


@dataclass
class Scoreboard:
    """Impacts (truths) and labels as they arrive, paired by
    :func:`tail_beam_id.stream.label.match`
    within ``tolerance_s`` (s); prints progress."""

    count: int
    tolerance_s: float
    truths: list[dict[str, Any]] = field(default_factory=list)
    labels: list[Label] = field(default_factory=list)
    # later decisions for an impact already labelled (docs/interface.md, ``revises``): counted
    # apart, never paired with an impact
    revisions: list[Label] = field(default_factory=list)
    arrived: dict[int, float] = field(default_factory=dict)  # id(obj) -> wall s of arrival
    shown: set[int] = field(default_factory=set)
    skipped: dict[str, int] = field(default_factory=dict)  # topic -> messages that were not ours

    def add(self, kind: str, item: dict[str, Any] | Label) -> None:
        (self.truths if kind == "truth" else self.labels).append(item)
        self.arrived[id(item)] = time.monotonic()

    def receive(self, kind: str, topic: str, text: str) -> None:
        """Add a truth or label as published; a message that is not a JSON object with the fields
        the scoreboard reads is skipped and counted, with one warning line per topic."""
        item: dict[str, Any] | Label | None
        if kind == "truth":
            item = parse_message(text, TRUTH_FIELDS)
            item = item if item is not None and item["label"] in LABELS else None
        else:
            try:
                item = Label.from_json(text)
            except InputError:
                item = None
        if item is None:
            self.skipped[topic] = self.skipped.get(topic, 0) + 1
            if self.skipped[topic] == 1:
                print(
                    f"warning: skipping messages on {topic} that are not the suite's {kind} JSON "
                    f"(another publisher on the topic?): {text[:60]!r}",
                    flush=True,
                )
            return
        if isinstance(item, Label) and item.revises is not None:
            self.revisions.append(item)
            return
        self.add(kind, item)

    def matching(self) -> Matching:
        """The truths and labels so far, paired one to one (the pairing may change as more
        arrive)."""
        return match(self.truths, self.labels, self.tolerance_s)

    def label_of(self, matching: Matching, truth: int) -> Label | None:
        """The label ``matching`` paired with truth number ``truth`` (from 0), or None."""
        paired = matching.label_index(truth)
        return None if paired is None else self.labels[paired]

    def show_ready(self, final: bool = False) -> None:
        """Print every impact whose label is in (or overdue), and labels that match nothing."""
        now = time.monotonic()
        matching = self.matching()
        for index, truth in enumerate(self.truths, 1):
            label = self.label_of(matching, index - 1)
            overdue = final or now - self.arrived[id(truth)] > LATE_S
            if id(truth) in self.shown or (label is None and not overdue):
                continue
            self.shown.add(id(truth))
            if label is not None:
                self.shown.add(id(label))
            print(
                f"[{index:>3}/{self.count}] {truth['contact_start_stamp']:8.3f} s  "
                f"{impact_text(truth):<44} -> {label_text(truth, label)}",
                flush=True,
            )
        extra = set(matching.extra)
        for number, label in enumerate(self.labels):
            late = final or now - self.arrived[id(label)] > LATE_S
            if id(label) not in self.shown and late and number in extra:
                self.shown.add(id(label))
                print(
                    f"          {label.impact_stamp_s:8.3f} s  {'(no impact here)':<44} -> "
                    f"{label.material} ({label.confidence:.2f}): false detection",
                    flush=True,
                )

    def table(self) -> str:
        """Confusion table (missed impacts count as wrong) and accuracy."""
        rows = {"coal": [0, 0, 0], "gangue": [0, 0, 0]}
        matching = self.matching()
        for number, truth in enumerate(self.truths):
            label = self.label_of(matching, number)
            column = 2 if label is None else (0 if label.material == "coal" else 1)
            rows[truth["label"]][column] += 1
        correct = rows["coal"][0] + rows["gangue"][1]
        total = len(self.truths)
        extra = len(matching.extra)
        lines = [
            f"{'':>14} {'label coal':>11} {'label gangue':>13} {'no label':>9}",
            *(
                f"{'truth ' + name:>14} {r[0]:>11} {r[1]:>13} {r[2]:>9}"
                for name, r in rows.items()
            ),
            f"false detections (labels with no impact): {extra}",
            f"revisions (later decisions for an impact already labelled, not scored): "
            f"{len(self.revisions)}",
            f"accuracy: {correct}/{total} = {100.0 * correct / max(total, 1):.1f} % (an impact "
            "without a label counts as wrong)",
        ]
        return "\n".join(lines)


def parse_message(
    text: str, fields: Mapping[str, type | tuple[type, ...]]
) -> dict[str, Any] | None:
    """The JSON object in ``text`` if it has every field with its type (finite numbers), else
    None."""
    try:
        item = json.loads(text)
    except (ValueError, RecursionError):
        return None
    if not isinstance(item, dict):
        return None
    for name, kind in fields.items():
        value = item.get(name)
        if not isinstance(value, kind) or isinstance(value, bool):
            return None
        if isinstance(value, float) and not math.isfinite(value):
            return None
    return item


def impact_text(truth: Mapping[str, Any]) -> str:
    return (
        f"{truth['material']:<9} R {truth['radius_m'] * 1e3:3.0f} mm, "
        f"{truth.get('drop_height_m') or 0:.1f} m, "
        f"at {truth['position_m']:.2f} m"
    )


def label_text(truth: Mapping[str, Any], label: Label | None) -> str:
    if label is None:
        return "no label"
    mark = "ok" if label.material == truth["label"] else "WRONG"
    return f"{label.material:<6} ({label.confidence:.2f}, {label.method})  {mark}"


def run(args: argparse.Namespace) -> int:
    if args.face is not None:
        from tail_beam_id.cli.face_demo import run_face

        return run_face(args)
    from tail_beam_id.ros.id_node import UNDECIDED_AFTER_S, IdNode
    from tail_beam_sim import topics
    from tail_beam_sim.ros.recorder_node import RecorderNode, default_bag_path
    from tail_beam_sim.ros.sim_node import SimNode
    from tail_beam_sim.ros.spin import NodeGroup, overrides

    if args.count < 1:
        raise InputError("--count", args.count, "must be >= 1")
    require_range("--gangue-fraction", args.gangue_fraction, 0.0, 1.0)
    bag = require_new_path("--bag", args.bag or default_bag_path("demo"))

    board = Scoreboard(args.count, match_tolerance_s(load_parameters()["identification"]))
    group = NodeGroup()
    try:
        common = {"context": group.context, "namespace": args.namespace}
        recorder = group.add(
            RecorderNode(
                **common,
                parameter_overrides=overrides(
                    {"recorder.bag_path": str(bag), "recorder.storage": args.storage}
                ),
            )
        )
        id_values = {
            "id_node.flush_after_idle_s": 0.5,
            **({"method": args.method} if args.method else {}),
        }
        identifier = group.add(IdNode(**common, parameter_overrides=overrides(id_values)))
        sim = group.add(
            SimNode(
                **common,
                parameter_overrides=overrides(
                    {
                        "scenario.source": "generated",
                        "scenario.count": args.count,
                        "scenario.seed": args.seed,
                        "scenario.gangue_fraction": float(args.gangue_fraction),
                        "sim_node.realtime_factor": float(args.realtime_factor),
                        "sim_node.exit_after_idle_s": 0.5,
                        "sim_node.wait_for_subscribers": 2,
                    }
                ),
            )
        )
        group.listener(
            "tail_beam_demo",
            args.namespace,
            {
                topics.IMPACT_TRUTH: lambda data: board.receive(
                    "truth", topics.IMPACT_TRUTH, data
                ),
                topics.LABEL: lambda data: board.receive("label", topics.LABEL, data),
            },
        )
        print(
            f"simulating {args.count} particles (seed {args.seed}, realtime factor "
            f"{args.realtime_factor:g}); "
            f"identifying with {identifier.identifier.method.name}; recording to {bag}",
            flush=True,
        )
        started = time.monotonic()
        done_at = None
        while done_at is None or time.monotonic() - done_at < SETTLE_S:
            group.spin_once(0.05)
            board.show_ready()
            if done_at is None and sim.finished.done():
                done_at = time.monotonic()
        board.show_ready(final=True)
        wall_s = time.monotonic() - started
    finally:
        group.close()
    print()
    for topic, count in board.skipped.items():
        print(f"skipped {count} message(s) on {topic} that were not the suite's JSON")
    print(board.table())
    v = recorder.vibration
    sim_s = sim.stream.time_s
    print(
        f"vibration: {v.samples} samples in {v.blocks} blocks recorded, "
        f"{v.samples / max(sim_s, 1e-9):,.0f} samples per s over "
        f"{sim_s:.1f} s of simulation ({wall_s:.1f} s wall, start-up included); lost: recorder "
        f"{v.lost_samples} samples, identifier {identifier.vibration_lost_samples} samples "
        f"and {identifier.vibration_late_blocks} late blocks"
    )
    print(
        f"identifier: {identifier.undecided_impacts} impact(s) not decided within "
        f"{UNDECIDED_AFTER_S:g} s of being found; at most {identifier.max_lag_s:.3f} s behind "
        "real time"
    )
    print(f"bag: {bag} ({recorder.writer.message_count} messages, {args.storage})")
    print(f"  offline: tail-beam identify {bag}")
    print(
        f"  replay:  bag_replay --ros-args -p replay.bag_path:={bag} -p "
        '"replay.topics:=[jack_pressure, imu, vibration, rebound_velocity]"'
    )
    return 0
