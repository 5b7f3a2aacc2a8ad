"""Benchmark of face_host: what one support costs when several share a process; prints a table,
asserts nothing.

For each support count, a fresh child process runs face_host's nodes (each support's sim_node
and id_node, with --record its bag_recorder too) at the shipped layout and real time, on one
executor as the executable does, with a generated scenario of impacts (the shipped scenario.*
ranges) running through the whole measurement. Measured from the moment every simulator has
started (imports, models and discovery left out) for --seconds of wall time:

- CPU s per simulated s per support: the process's CPU time (every thread: executor and DDS)
  over the simulated time summed over the supports; 1.0 is one core per support.
- real-time ratio: simulated s per wall s, the slowest support (below 1: the host cannot keep
  up; sim_node then runs slower than real time rather than skip samples).
- samples lost: what the identifiers (and recorders) counted missing, summed over the supports
  and streams (docs/nodes.md, QoS).

With ``--split 2+1`` a row runs a face over several host processes at once (here two: supports
1-2 in one, 3 in the other, each by its ``face_host.namespaces``), as docs/nodes.md says to
spread a face over cores: CPU summed over the processes, the slowest support's ratio.

Usage: python test/bench/bench_face_host.py [--supports 1 2 3] [--split 2+1] [--seconds 15]
[--record]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 50))
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
SCENARIO_IMPACTS = 100  # enough for the longest measurement (0.4-0.7 s apart: about 55 s)


def measure(
    supports: int, seconds: float, record: bool, bag_dir: str, first: int = 1
) -> dict[str, float]:
    """One host of ``supports`` supports in this process (``/support_<first>`` on); its
    figures."""
    import rclpy
    from rclpy.experimental import EventsExecutor

    from tail_beam_id.ros.face_host import FaceHost
    from tail_beam_sim.ros.spin import spin_once, with_members

    namespaces = ", ".join(f"/support_{k:03d}" for k in range(first, first + supports))
    values = {
        "face_host.supports": supports,
        "face_host.namespaces": f"[{namespaces}]",
        "face_host.record": str(record).lower(),
        "recorder.bag_path": bag_dir,
        "scenario.source": "generated",
        "scenario.count": SCENARIO_IMPACTS,
    }
    # As on face_host's command line: global arguments reach every support's nodes.
    context = rclpy.Context()
    rclpy.init(
        context=context,
        args=["--ros-args"] + [a for k, v in values.items() for a in ("-p", f"{k}:={v}")],
    )
    host = FaceHost(context=context)
    executor = EventsExecutor(context=context)
    nodes = with_members(host)
    for node in nodes:
        executor.add_node(node)
    try:
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and not all(s.stream.time_s > 0 for s in host.sims):
            spin_once(executor, 0.05)
        cpu0, wall0 = time.process_time(), time.monotonic()
        sim0 = [s.stream.time_s for s in host.sims]
        while time.monotonic() - wall0 < seconds:
            spin_once(executor, 0.05)
        cpu_s, wall_s = time.process_time() - cpu0, time.monotonic() - wall0
        sim_s = [s.stream.time_s - t for s, t in zip(host.sims, sim0)]
        lost = sum(sum(i.lost_samples.values()) for i in host.identifiers)
        recorder_lost = sum(
            r.vibration_lost_samples + sum(g.lost_samples for g in r.grid_gaps.values())
            for r in host.recorders
        )
        labels = sum(i.published for i in host.identifiers)
    finally:
        executor.shutdown()
        for node in nodes:
            if hasattr(node, "close"):
                node.close()
            node.destroy_node()
        rclpy.try_shutdown(context=context)
    return {
        "supports": supports,
        "cpu_s": cpu_s,
        "sim_s": sum(sim_s),
        "cpu_per_sim_s_per_support": cpu_s / max(sum(sim_s), 1e-9),
        "realtime_ratio": min(sim_s) / wall_s,
        "identifier_lost": lost,
        "recorder_lost": recorder_lost,
        "labels": labels,
        "wall_s": wall_s,
    }


def run_row(parts: list[int], seconds: float, record: bool) -> dict[str, float] | str:
    """One row: a host process per entry of ``parts`` (its support count), all at once, the
    supports numbered on across them; the summed figures, or the failure's last words."""
    children = []
    first = 1
    for n in parts:
        command = [sys.executable, __file__, "--child", str(n), "--first", str(first)]
        command += ["--seconds", str(seconds)] + (["--record"] if record else [])
        children.append(
            subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        )
        first += n
    figures = []
    for child in children:
        out, err = child.communicate()
        line = next((x for x in out.splitlines() if x.startswith("FIGURES ")), None)
        if line is None:
            return f"failed: {err.strip()[-500:]}"
        figures.append(json.loads(line.removeprefix("FIGURES ")))
    return {
        "cpu_per_sim_s_per_support": sum(f["cpu_s"] for f in figures)
        / max(sum(f["sim_s"] for f in figures), 1e-9),
        "realtime_ratio": min(f["realtime_ratio"] for f in figures),
        "labels": sum(f["labels"] for f in figures),
        "identifier_lost": sum(f["identifier_lost"] for f in figures),
        "recorder_lost": sum(f["recorder_lost"] for f in figures),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--supports", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument(
        "--split",
        nargs="*",
        default=[],
        help="rows of several host processes at once, e.g. 2+1 (supports per process)",
    )
    parser.add_argument("--seconds", type=float, default=15.0)
    parser.add_argument("--record", action="store_true")
    parser.add_argument("--child", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--first", type=int, default=1, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child is not None:
        with tempfile.TemporaryDirectory() as bag_dir:
            figures = measure(args.child, args.seconds, args.record, f"{bag_dir}/face", args.first)
        print("FIGURES " + json.dumps(figures), flush=True)
        return 0
    rows: list[list[int]] = [[n] for n in args.supports]
    for split in args.split:
        try:
            parts = [int(p) for p in split.split("+")]
        except ValueError:
            parser.error(f"--split {split}: give supports per process, e.g. 2+1")
        if not parts or min(parts) < 1:
            parser.error(f"--split {split}: every process needs at least one support")
        rows.append(parts)
    print(
        f"face_host at the shipped layout, real time, generated impacts; {args.seconds:g} s "
        f"measured per row; {'with' if args.record else 'without'} bag_recorder; "
        f"{os.cpu_count()} cores"
    )
    print(
        f"{'supports':>8} {'processes':>9} {'CPU s/sim s/support':>20} {'real-time ratio':>16} "
        f"{'labels':>7} {'lost (id_node)':>15} {'lost (recorder)':>16}"
    )
    for parts in rows:
        f = run_row(parts, args.seconds, args.record)
        name = "+".join(str(p) for p in parts)
        if isinstance(f, str):
            print(f"{sum(parts):>8} {name:>9} {f}")
            continue
        print(
            f"{sum(parts):>8} {name:>9} {f['cpu_per_sim_s_per_support']:>20.2f} "
            f"{f['realtime_ratio']:>16.3f} {f['labels']:>7} {f['identifier_lost']:>15} "
            f"{(f['recorder_lost'] if args.record else '-'):>16}",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
