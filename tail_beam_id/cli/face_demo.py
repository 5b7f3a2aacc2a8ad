"""``tail-beam demo --face N``: a group of supports drawn one after another, live.

N supports under their own namespaces (``/support_001`` ...), each with its sim_node (the flow
source: its window opened and closed on ``window_cmd``, its own seed), its id_node and its
bag_recorder, and one caving_node that serves them all: it opens the first window, closes each
on its rule and opens the next. All real ROS 2 nodes, the supports' simulators and identifiers
spread over one process per core (``--processes P`` to choose; :mod:`tail_beam_id.cli.face_hosts`:
one process holds one core at most). At the end it prints, per
window, what was drawn (the flow's lumps between the window's opening and closing, drawn again
from the flow's seed: tail_beam_id.caving.drawn) against what the oracle rule would have drawn
from the same flow, and the round's totals.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

from tail_beam_id.caving.drawn import Drawn
from tail_beam_id.cli.face_hosts import (
    HostLost,
    SupportHost,
    SupportSummary,
    Windows,
    add_support,
    default_processes,
    progress,
    split_supports,
    summarise,
)
from tail_beam_sim.cli import EXIT_TIMEOUT
from tail_beam_sim.config import flatten, read_parameter_file
from tail_beam_sim.errors import InputError, require_new_path

MAX_FACE_DEMO = 12  # supports one process runs live
LAND_S = 1.5  # simulation s after a window's closing by which its last lumps have landed
SETTLE_S = 2.0  # wall s the identifiers and recorders get after the last window closed
IDLE_S = 5.0  # wall s without data before id_node takes a stream for stopped (or data ended)


def face_overrides(paths: list[str]) -> dict[str, Any]:
    """The dotted parameters of each ``--config`` file, later files winning."""
    values: dict[str, Any] = {}
    for path in paths:
        try:
            values.update(flatten(read_parameter_file(Path(path))))
        except OSError as exc:
            raise InputError("--config", path, f"must be a readable parameter file ({exc})")
    return values


def run_face(args: argparse.Namespace) -> int:
    from tail_beam_id.ros.caving_node import CavingNode
    from tail_beam_id.ros.id_node import IdNode
    from tail_beam_sim.ros.recorder_node import RecorderNode, default_bag_path
    from tail_beam_sim.ros.sim_node import SimNode
    from tail_beam_sim.ros.spin import NodeGroup, overrides

    count = args.face
    if not 1 <= count <= MAX_FACE_DEMO:
        raise InputError("--face", count, f"must be in [1, {MAX_FACE_DEMO}] supports")
    namespaces = [f"/support_{k:03d}" for k in range(1, count + 1)]
    processes = args.processes if args.processes is not None else default_processes(count)
    blocks = split_supports(namespaces, processes)
    bag = require_new_path("--bag", args.bag or default_bag_path("face"))
    extra = face_overrides(args.config or [])
    caving_values = {
        k: v for k, v in extra.items() if k.startswith(("caving.", "caving_node."))
    } | {"caving_node.supports": namespaces}
    if args.rule:
        caving_values["caving_node.rule"] = args.rule
    node_values = {k: v for k, v in extra.items() if k not in caving_values}
    # Nodes held up behind others for a moment (one process, or a busy machine): a stream late,
    # not stopped (labels then wait for it, as offline).
    id_values = {
        "id_node.flush_after_idle_s": IDLE_S,
        "id_node.stream_idle_s": IDLE_S,
    } | ({"method": args.method} if args.method else {})

    def sim_values(k: int) -> dict[str, Any]:
        return node_values | {
            "scenario.source": "flow",
            "flow.seed": args.seed + k,
            "flow.open_at_s": -1.0,
            "sim_node.realtime_factor": float(args.realtime_factor),
            "sim_node.exit_after_idle_s": 0.0,
            "sim_node.wait_for_subscribers": 2,
        }

    group = NodeGroup()
    sims: dict[str, SimNode] = {}
    identifiers: dict[str, IdNode] = {}
    recorders: dict[str, RecorderNode] = {}
    hosts: list[SupportHost] = []
    summaries: dict[str, SupportSummary] = {}
    try:
        # The controller first: a rule or parameter it refuses stops the demo before any bag.
        caving = group.add(
            CavingNode(context=group.context, parameter_overrides=overrides(caving_values))
        )
        for k, ns in enumerate(namespaces):
            common = {"context": group.context, "namespace": ns}
            recorders[ns] = group.add(
                RecorderNode(
                    **common,
                    parameter_overrides=overrides({"recorder.bag_path": str(bag / ns.strip("/"))}),
                )
            )
            if ns in blocks[0]:
                identifiers[ns], sims[ns] = add_support(group, ns, sim_values(k), id_values)
        # The other processes' supports, once this one's nodes took the same parameters.
        for block in blocks[1:]:
            values = [sim_values(namespaces.index(ns)) for ns in block]
            hosts.append(SupportHost(block, values, id_values, caving.oracle_level))
        for host in hosts:
            host.wait_ready()
        method = next(iter(identifiers.values())).identifier.method.name
        print(
            f"face: {count} supports {namespaces[0]} .. {namespaces[-1]}, drawn one after "
            f"another; closing rule {caving.rule_name}; identifying with {method}; realtime "
            f"factor {args.realtime_factor:g}; "
            + (
                f"{processes} processes ({' + '.join(str(len(b)) for b in blocks)} supports, "
                "the controller and the recorders in the first); "
                if processes > 1
                else ""
            )
            + f"recording to {bag}/support_NNN",
            flush=True,
        )
        started = time.monotonic()
        done_at = None
        said = 0
        while done_at is None or time.monotonic() - done_at < SETTLE_S:
            group.spin_once(0.05)
            for host in hosts:
                host.poll()
            said = _say_states(caving, said)
            if done_at is None and caving.round_done and _landed(_progress(sims, hosts)):
                done_at = time.monotonic()
        wall_s = time.monotonic() - started
        simulated_s = min(time_s for time_s, _ in _progress(sims, hosts).values())
    except HostLost as exc:
        lost = exc
    else:
        lost = None
    finally:
        for host in hosts:
            summaries.update({s.namespace: s for s in host.stop()})
        group.close()
    if lost is not None:
        print(
            f"tail-beam demo: error: {lost}; the round stopped there (bags so far: "
            f"{bag}/support_NNN)",
            file=sys.stderr,
        )
        return EXIT_TIMEOUT  # a peer (the supports' process) did not answer
    level = caving.oracle_level
    for ns, sim in sims.items():
        summaries[ns] = summarise(ns, sim, identifiers[ns], level)
    _print_round([summaries[ns] for ns in namespaces if ns in summaries], level)
    for w in caving.windows:
        ns = w.namespace
        rec, summary = recorders[ns], summaries.get(ns)
        print(
            f"{ns}: {summary.simulated_s if summary else math.nan:.1f} s simulated; recorder lost "
            f"{rec.vibration_lost_samples} vibration samples, {rec.lost_events} messages; "
            f"identifier lost {summary.identifier_lost if summary else '?'} samples; "
            f"{sum(w.refused.values())} controller input(s) set aside"
        )
    print(
        f"wall time {wall_s:.1f} s from the nodes' start; {simulated_s:.1f} s simulated "
        f"({simulated_s / max(wall_s, 1e-9):.2f} x real time, start-up and the last "
        f"{SETTLE_S:g} s included); bags: {bag}/support_NNN"
    )
    if args.check_offline:
        agree = check_offline(caving, bag, args.method)
        if not agree:
            return 1
    print(f"  offline: tail-beam identify {bag}/{namespaces[0].strip('/')}")
    return 0


def _print_round(summaries: list[SupportSummary], level: float) -> None:
    """Per window what was drawn against the oracle's draw from the same flow; the round's
    totals."""
    print()
    print(
        f"{'support':<13} {'rule closed at':>15} {'drawn t':>8} {'gangue %':>9} "
        f"{'oracle t':>9} {'oracle gangue %':>16} {'coal vs oracle %':>17}"
    )
    totals: list[tuple[Drawn, Drawn]] = []
    for summary in summaries:
        drawn, oracle = summary.drawn, summary.oracle
        if drawn is None:
            print(f"{summary.namespace:<13} window not closed")
            continue
        closed = summary.windows[0][1]
        totals += [(drawn, oracle)] if oracle is not None else []
        ratio = (
            f"{100.0 * drawn.coal_kg / oracle.coal_kg:17.1f}"
            if oracle is not None and oracle.coal_kg > 0
            else f"{'-':>17}"
        )
        print(
            f"{summary.namespace:<13} {closed:14.2f}s {drawn.mass_kg / 1e3:8.2f} "
            f"{100.0 * drawn.gangue_content:9.1f} "
            + (
                f"{oracle.mass_kg / 1e3:9.2f} {100.0 * oracle.gangue_content:16.1f}"
                if oracle is not None
                else f"{'-':>9} {'-':>16}"
            )
            + f" {ratio}"
        )
    if totals:
        mass = sum(d.mass_kg for d, _ in totals)
        gangue = sum(d.gangue_kg for d, _ in totals)
        o_mass = sum(o.mass_kg for _, o in totals)
        o_gangue = sum(o.gangue_kg for _, o in totals)
        coal, o_coal = mass - gangue, o_mass - o_gangue
        print(
            f"round: {mass / 1e3:.2f} t drawn at {100.0 * gangue / max(mass, 1e-9):.1f} % gangue, "
            f"the oracle's {o_mass / 1e3:.2f} t at {100.0 * o_gangue / max(o_mass, 1e-9):.1f} %; "
            f"coal drawn {100.0 * coal / max(o_coal, 1e-9):.1f} % of the oracle's "
            f"(oracle: true share by mass of a {summaries[0].interval_s:g} s interval "
            f">= {level:g})"
        )


def _progress(sims: dict[str, Any], hosts: list[SupportHost]) -> dict[str, tuple[float, Windows]]:
    """Each support's simulated time (s) and window stamps, here and in the other processes
    (a support of another process not yet heard from: not started)."""
    out = {ns: progress(sim) for ns, sim in sims.items()}
    for host in hosts:
        out.update({ns: host.status.get(ns, (0.0, [])) for ns in host.namespaces})
    return out


def check_offline(caving: Any, bag: Path, method: str | None) -> bool:
    """Identify each support's bag as ``tail-beam identify --no-calibrate`` does, feed the rule
    its labels, shares and share truths from the recorded opening, and say whether each
    decision (stamp and reason) is the live one."""
    from tail_beam_id.caving.feed import offline_decision
    from tail_beam_id.cli.identify_cmd import identify_bag
    from tail_beam_id.stream.label import Label
    from tail_beam_sim import topics
    from tail_beam_sim.bags.read import read_sensors

    agree = True
    for w in caving.windows:
        path = str(bag / w.namespace.strip("/"))
        recorded = read_sensors(path, required=()).json_topics
        opened = [s for s in recorded[topics.WINDOW_STATE] if s["state"] == "open"]
        live = [d for d in caving.decisions if d["support"] == w.namespace]
        if not opened or not live:
            print(f"{w.namespace}: offline check: no recorded opening or no live decision")
            agree = False
            continue
        shares: list = []
        labels = identify_bag(path, method, calibrate=False, shares=shares)
        decision = offline_decision(
            caving.make_rule(),
            opened[0]["stamp_s"],
            labels,
            shares,
            recorded[topics.GANGUE_SHARE_TRUTH],
        )
        # The same rule on the labels id_node published (as recorded): where this one agrees
        # and the offline one does not, the live labels differed from the offline ones.
        replayed = offline_decision(
            caving.make_rule(),
            opened[0]["stamp_s"],
            [Label.from_dict(obj) for obj in recorded[topics.LABEL]],
            [],
            recorded[topics.GANGUE_SHARE_TRUTH],
        )
        key = (live[0]["stamp_s"], live[0]["reason"])
        same = decision is not None and (decision.stamp_s, decision.reason) == key
        same_recorded = replayed is not None and (replayed.stamp_s, replayed.reason) == key
        agree &= same
        offline = "none" if decision is None else f"{decision.stamp_s:.4f} s: {decision.reason}"
        print(
            f"{w.namespace}: offline decision {offline}; live {live[0]['stamp_s']:.4f} s: "
            f"{live[0]['reason']}: {'same' if same else 'DIFFERENT'}; on the recorded live "
            f"labels: {'same' if same_recorded else 'DIFFERENT'}"
        )
    return agree


def _say_states(caving: Any, said: int) -> int:
    """Print the window states and decisions the controller has given since the last call."""
    for d in caving.decisions[said:]:
        print(
            f"{d['support']}: closed by {d['rule']} at {d['stamp_s']:.2f} s (opened "
            f"{d['opened_stamp_s']:.2f} s): {d['reason']}",
            flush=True,
        )
    return len(caving.decisions)


def _landed(progress: dict[str, tuple[float, Windows]]) -> bool:
    """Every window closed and its simulation LAND_S past the closing."""
    for time_s, windows in progress.values():
        if not windows or windows[-1][1] == float("inf"):
            return False
        if time_s < windows[-1][1] + LAND_S:
            return False
    return True
