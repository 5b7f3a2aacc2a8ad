"""Benchmark: one slow subscriber beside the nodes; prints figures, asserts nothing.

sim_node and id_node run as their own processes (as deployed) on a generated stream; a third
process is a client that subscribes to jack_pressure and imu (reliable, depth 10 000 unless
told) and spends ``--work-ms`` of CPU on each IMU message. This process scores the labels
against impact_truth (tail_beam_id.stream.label.match) and reports, per run: impacts labelled
right, extra labels, revisions (docs/interface.md, ``revises``), impacts without a label, the
label delay (label arrival minus the wall time of the contact end: the stamp mapped to wall
clock through sim_node's /clock, whose earliest delivered message gives the mapping) and what
id_node logged about lag, undecided impacts and lost samples.

``--sim-depth`` and ``--id-depth`` set the sensor QoS history depths of sim_node's writers
and id_node's readers (sim_node.qos_depth, id_node.qos_depth), so that the writer history the
nodes shipped with before (10 000) can be compared with the shipped one without another
checkout.

Usage: python test/bench/bench_slow_subscriber.py [--count 40] [--no-client]
    [--sim-depth N] [--id-depth N] [--client-depth N] [--work-ms 2]
"""

from __future__ import annotations

import argparse
import bisect
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BIN = Path(sys.executable).parent
os.environ.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 50))


def client(depth: int, work_ms: float, seconds: float) -> None:
    """The slow client: reliable subscriptions to jack_pressure and imu, busy on each IMU."""
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.experimental import EventsExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import FluidPressure, Imu

    rclpy.init()
    node = rclpy.create_node("slow_client")
    qos = QoSProfile(
        depth=abs(depth),
        reliability=ReliabilityPolicy.RELIABLE if depth > 0 else ReliabilityPolicy.BEST_EFFORT,
    )
    got = {"imu": 0, "jack_pressure": 0}

    def on_imu(_msg: Imu) -> None:
        got["imu"] += 1
        end = time.perf_counter() + work_ms * 1e-3
        while time.perf_counter() < end:
            pass

    def on_pressure(_msg: FluidPressure) -> None:
        got["jack_pressure"] += 1

    node.create_subscription(Imu, "imu", on_imu, qos)
    node.create_subscription(FluidPressure, "jack_pressure", on_pressure, qos)
    executor = EventsExecutor()
    executor.add_node(node)
    end = time.monotonic() + seconds
    try:
        while time.monotonic() < end and rclpy.ok():
            executor.spin_once(timeout_sec=0.05)
    except (KeyboardInterrupt, ExternalShutdownException):  # stopped by the scorer: say it
        pass
    print(json.dumps(got), flush=True)
    rclpy.try_shutdown()


def start(exe: list[str], params: dict[str, object], log: Path) -> subprocess.Popen:
    args = exe + (
        ["--ros-args"] + [a for k, v in params.items() for a in ("-p", f"{k}:={v}")]
        if params
        else []
    )
    with log.open("w") as out:
        return subprocess.Popen(args, stdout=out, stderr=subprocess.STDOUT)


def run(args: argparse.Namespace) -> dict[str, object]:
    import rclpy
    from rclpy.experimental import EventsExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import String

    from tail_beam_id.stream.label import Label, match, match_tolerance_s
    from tail_beam_sim.config import load_parameters

    tolerance = match_tolerance_s(load_parameters()["identification"])
    logs = Path(tempfile.mkdtemp(prefix="bench_slow_"))
    procs: list[subprocess.Popen] = []
    duration_s = args.count * 0.55 + 6.0
    rclpy.init()
    node = rclpy.create_node("bench_scorer")
    events = QoSProfile(
        depth=1000,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )
    truths: list[dict] = []
    labels: list[tuple[Label, float]] = []
    clock: list[tuple[float, float]] = []  # (stamp s, wall arrival s) of each /clock

    def on_clock(msg: Clock) -> None:
        clock.append((msg.clock.sec + msg.clock.nanosec * 1e-9, time.monotonic()))

    def on_truth(msg: String) -> None:
        truths.append(json.loads(msg.data))
        truths[-1]["_arrived"] = time.monotonic()

    node.create_subscription(String, "impact_truth", on_truth, events)
    node.create_subscription(
        String, "label", lambda m: labels.append((Label.from_json(m.data), time.monotonic())),
        events,
    )
    node.create_subscription(Clock, "/clock", on_clock, 100)
    executor = EventsExecutor()
    executor.add_node(node)
    try:
        id_params: dict[str, object] = {}
        if args.id_depth is not None:
            id_params["id_node.qos_depth"] = args.id_depth
        procs.append(start([str(BIN / "id_node")], id_params, logs / "id_node.log"))
        if not args.no_client:
            procs.append(
                start(
                    [sys.executable, __file__, "--client", "--client-depth",
                     str(args.client_depth), "--work-ms", str(args.work_ms),
                     "--client-seconds", str(duration_s + 15)],
                    {},
                    logs / "client.log",
                )
            )
        time.sleep(2.0)
        sim_params: dict[str, object] = {
            "scenario.source": "generated",
            "scenario.count": args.count,
            "scenario.seed": args.seed,
            "sim_node.wait_for_subscribers": 1,
            "sim_node.publish_clock": True,
        }
        if args.sim_depth is not None:
            sim_params["sim_node.qos_depth"] = args.sim_depth
        sim = start([str(BIN / "sim_node")], sim_params, logs / "sim_node.log")
        procs.append(sim)
        deadline = time.monotonic() + duration_s + 60
        while sim.poll() is None and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        settle = time.monotonic() + 3.0
        while time.monotonic() < settle:
            executor.spin_once(timeout_sec=0.05)
    finally:
        for proc in reversed(procs):
            if proc.poll() is None:
                proc.send_signal(2)
        for proc in procs:
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    firsts = [(label, t) for label, t in labels if label.extra.get("revises") is None]
    revisions = len(labels) - len(firsts)
    matching = match(truths, [label for label, _ in firsts], tolerance)
    right = sum(
        1 for i, j in matching.pairs if firsts[j][0].material == truths[i]["label"]
    )
    stamps = [stamp for stamp, _ in clock]

    def published_s(stamp: float) -> float:
        """Wall time /clock first reached ``stamp``: when sim_node had published it."""
        k = min(bisect.bisect_left(stamps, stamp), len(clock) - 1)
        return clock[k][1]

    delays = [
        (firsts[j][1] - published_s(truths[i]["contact_end_stamp"])) * 1e3
        for i, j in matching.pairs
    ]
    moving = [(s, w) for s, w in clock if s > 0.0]  # the clock is held at 0 until subscribers
    ratio = (
        (moving[-1][0] - moving[0][0]) / (moving[-1][1] - moving[0][1])
        if len(moving) > 1
        else float("nan")
    )
    after_truth = [(firsts[j][1] - truths[i]["_arrived"]) * 1e3 for i, j in matching.pairs]
    id_log = (logs / "id_node.log").read_text()
    lag = [float(x) for x in re.findall(r"behind real time by ([0-9.]+) s", id_log)]
    return {
        "client": "none"
        if args.no_client
        else f"{'reliable' if args.client_depth > 0 else 'best effort'}/{abs(args.client_depth)}",
        "sim_depth": args.sim_depth,
        "id_depth": args.id_depth,
        "impacts": len(truths),
        "right": right,
        "extra": len(matching.extra),
        "revisions": revisions,
        "unlabelled": len(matching.missed),
        "delay_median_ms": round(statistics.median(delays), 1) if delays else None,
        "delay_max_ms": round(max(delays), 1) if delays else None,
        "sim_realtime_ratio": round(ratio, 3),
        "after_truth_median_ms": round(statistics.median(after_truth), 1) if delays else None,
        "lag_warnings": len(lag),
        "lag_max_s": max(lag, default=0.0),
        "undecided_logged": len(re.findall(r"found but not decided", id_log)),
        "lost_logged": re.findall(r"lost[^\n]*", id_log)[-1:] or "",
        "client_received": (logs / "client.log").read_text().strip()[-80:]
        if not args.no_client
        else "",
        "logs": str(logs),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=40)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--no-client", action="store_true")
    parser.add_argument("--sim-depth", type=int)
    parser.add_argument("--id-depth", type=int)
    parser.add_argument(
        "--client-depth", type=int, default=10000, help="negative: best effort, this deep"
    )
    parser.add_argument("--work-ms", type=float, default=2.0)
    parser.add_argument("--client", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--client-seconds", type=float, default=60.0, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.client:
        client(args.client_depth, args.work_ms, args.client_seconds)
        return
    print(json.dumps(run(args)), flush=True)


if __name__ == "__main__":
    main()
