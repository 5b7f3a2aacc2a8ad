"""``tail-beam bag info|repair BAG``: what a bag holds; recover a bag whose recorder was killed."""

from __future__ import annotations

import argparse

from tail_beam_sim.bagread import check_bag_path, raw_messages
from tail_beam_sim.bagwrite import repair


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("bag", help="inspect or repair a rosbag2 bag")
    actions = parser.add_subparsers(dest="action", required=True, parser_class=type(parser), metavar="ACTION")
    info = actions.add_parser("info", help="topics, types, counts and stamp span of a bag")
    info.add_argument("bag", help="bag directory")
    info.set_defaults(func=run_info)
    fix = actions.add_parser("repair", help="salvage the segments a killed recorder left open; rewrite metadata.yaml")
    fix.add_argument("bag", help="bag directory")
    fix.set_defaults(func=run_repair)


def run_info(args: argparse.Namespace) -> int:
    counts: dict[str, list] = {}
    first = last = None
    for raw in raw_messages(args.bag):
        entry = counts.setdefault(raw.topic, [raw.msgtype, 0])
        entry[1] += 1
        first = raw.log_time_ns if first is None else min(first, raw.log_time_ns)
        last = raw.log_time_ns if last is None else max(last, raw.log_time_ns)
    print(f"bag {args.bag}: {sum(c[1] for c in counts.values())} messages, log time {first * 1e-9:.3f} .. {last * 1e-9:.3f} s")
    for topic, (msgtype, count) in sorted(counts.items()):
        print(f"  {topic:<18} {msgtype:<32} {count:>8}")
    return 0


def run_repair(args: argparse.Namespace) -> int:
    segments, messages = repair(args.bag)
    check_bag_path(args.bag)
    print(f"bag {args.bag}: salvaged {messages} messages from {segments} open segment(s); metadata.yaml rewritten")
    return 0
