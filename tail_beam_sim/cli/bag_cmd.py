"""``tail-beam bag info|repair BAG``: what a bag holds; recover a bag whose recorder was killed."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import yaml

from tail_beam_sim import topics
from tail_beam_sim.bags.read import ANY_NAMESPACE, open_segments_note, raw_messages
from tail_beam_sim.bags.records import TYPESTORE, vibration_fields
from tail_beam_sim.bags.write import METADATA, repair
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.sensors import IndexSpan


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("bag", help="inspect or repair a rosbag2 bag")
    actions = parser.add_subparsers(
        dest="action", required=True, parser_class=type(parser), metavar="ACTION"
    )
    info = actions.add_parser("info", help="topics, types, counts and stamp span of a bag")
    info.add_argument("bag", help="bag directory")
    info.set_defaults(func=run_info)
    fix = actions.add_parser(
        "repair", help="salvage the segments a killed recorder left open; rewrite metadata.yaml"
    )
    fix.add_argument("bag", help="bag directory")
    fix.set_defaults(func=run_repair)


def run_info(args: argparse.Namespace) -> int:
    """Every topic of every namespace with its type and count; for vibration the samples, the
    rate and the samples missing from the running index; the recorder's loss counts."""
    counts: dict[str, list] = {}
    spans: dict[str, IndexSpan] = {}
    periods: dict[str, dict[float, int]] = {}  # per vibration topic: blocks per period
    blockless: dict[str, int] = {}  # per vibration topic: messages carrying no block
    first = last = None
    for raw in raw_messages(args.bag, namespace=ANY_NAMESPACE, any_type=True):
        name = raw.full_topic or raw.topic
        entry = counts.setdefault(name, [raw.msgtype, 0])
        entry[1] += 1
        first = raw.log_time_ns if first is None else min(first, raw.log_time_ns)
        last = raw.log_time_ns if last is None else max(last, raw.log_time_ns)
        if raw.topic == topics.VIBRATION and raw.msgtype == topics.MSG_TYPES[topics.VIBRATION]:
            try:
                index, _, samples, period_s, _ = vibration_fields(
                    TYPESTORE.deserialize_cdr(raw.data, raw.msgtype)
                )
            except InputError:  # a message carrying no block: counted, the rest listed
                blockless[name] = blockless.get(name, 0) + 1
                continue
            spans.setdefault(name, IndexSpan()).add(index, samples.size)
            periods.setdefault(name, {}).setdefault(period_s, 0)
            periods[name][period_s] += 1
    print(
        f"bag {args.bag}: {sum(c[1] for c in counts.values())} messages, log time "
        f"{first * 1e-9:.3f} .. {last * 1e-9:.3f} s"
    )
    width = max(18, *(len(t) for t in counts))
    for topic, (msgtype, count) in sorted(counts.items()):
        line = f"  {topic:<{width}} {msgtype:<32} {count:>8}"
        if topic in spans:
            span = spans[topic]
            period = max(periods[topic], key=periods[topic].get)  # the most blocks'
            line += f"  ({span.samples} samples at {1.0 / period:.0f} Hz"
            line += f", {span.lost_samples} samples lost"
            if len(periods[topic]) > 1:
                line += (
                    f", {sum(periods[topic].values()) - periods[topic][period]} at another rate"
                )
            line += ")"
        if topic in blockless:
            line += f"  ({blockless[topic]} carrying no block)"
        print(line)
    custom = _custom_data(Path(args.bag))
    lost = {k: v for k, v in custom.items() if k.startswith("tail_beam.")}
    if lost:
        print(
            "  recorder: "
            + ", ".join(f"{k.removeprefix('tail_beam.')} {v}" for k, v in sorted(lost.items()))
        )
    note = open_segments_note(args.bag)
    if note:
        print(f"tail-beam bag info: {note}", file=sys.stderr)
    return 0


def _custom_data(bag: Path) -> dict[str, str]:
    """The ``custom_data`` of a bag's metadata.yaml (the recorder's loss counts), or none."""
    try:
        info = yaml.safe_load((bag / METADATA).read_text(encoding="utf-8"))[
            "rosbag2_bagfile_information"
        ]
    except (OSError, yaml.YAMLError, KeyError, TypeError):
        return {}
    return {str(k): str(v) for k, v in (info.get("custom_data") or {}).items()}


def run_repair(args: argparse.Namespace) -> int:
    """Repair, then read the whole bag back: say it reads, or say clearly that it does not."""
    report = repair(args.bag)
    try:
        count = sum(1 for _ in raw_messages(args.bag, any_type=True))
    except InputError as exc:
        print(
            f"tail-beam bag: error: could not repair {args.bag} ({report.summary()}): "
            f"{exc.allowed}",
            file=sys.stderr,
        )
        return 2
    print(
        f"bag {args.bag}: {report.summary()}; metadata.yaml rewritten; the bag reads: {count} "
        "messages"
    )
    return 0
