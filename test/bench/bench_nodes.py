"""Benchmark of the node suite over the real middleware; prints figures, asserts nothing.

1. Highest sensor rates sim_node -> id_node sustain in real time with zero loss: sim_node runs
   as its own process (as deployed) at realtime_factor 1 with pressure and IMU at each rate;
   id_node runs in this process. Reported per rate: messages id_node lost (the worst of the
   repeats; expected count from the stamps), the real-time ratio achieved (simulation s per
   wall s over the run) and the label latency.
2. Label latency: from the moment the sample at the contact end reached id_node's process to
   the moment the label arrived there (wall clock; the contact end from impact_truth).
3. Recorder: bag_recorder in this process recording sim_node running as fast as it can
   (realtime_factor 0); messages written per wall second, and any lost; and its writer alone.

Usage: python test/bench/bench_nodes.py [--rates 2000 5000 10000] [--duration 6] [--repeats 3]
Each figure is the median over the repeats. Keep it small on a shared machine.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

BIN = Path(sys.executable).parent
os.environ.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 50))


def start_sim(rate_hz: float, duration_s: float, factor: float, count: int) -> subprocess.Popen:
    params = {
        "sensors.pressure_rate_hz": rate_hz,
        "sensors.imu_rate_hz": rate_hz,
        "sim_node.realtime_factor": factor,
        "sim_node.wait_for_subscribers": 1,
        "sim_node.exit_after_idle_s": duration_s,
        "scenario.source": "generated",
        "scenario.count": count,
    }
    args = [str(BIN / "sim_node"), "--ros-args"] + [
        a for k, v in params.items() for a in ("-p", f"{k}:={v}")
    ]
    return subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def run_identification(rate_hz: float, duration_s: float) -> dict[str, float | str]:
    """One run of sim_node (process) -> id_node (here); loss, real-time ratio, latencies.

    id_node's own counters give the loss; it also notes when each pressure sample arrived, for
    the latency. If the identifier fails at some rate, the error is reported.
    """
    import rclpy
    from rclpy.experimental import EventsExecutor
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import FluidPressure
    from std_msgs.msg import String

    from tail_beam_id.ros.id_node import IdNode
    from tail_beam_id.stream.label import Label, match, match_tolerance_s
    from tail_beam_sim.config import load_parameters
    from tail_beam_sim.ros import messages as ros_messages

    context = rclpy.Context()
    rclpy.init(context=context)
    executor = EventsExecutor(context=context)
    # No end-of-data flush within the run: only labels decided while the data streams count.
    arrivals: list[
        tuple[float, float]
    ] = []  # (stamp s, wall s) of the pressure samples, as they reach id_node

    class TimedIdNode(IdNode):
        def _on_pressure(self, msg: FluidPressure) -> None:
            arrivals.append((ros_messages.stamp_s(msg.header.stamp), time.monotonic()))
            super()._on_pressure(msg)

    ident = TimedIdNode(
        context=context, parameter_overrides=[Parameter("id_node.flush_after_idle_s", value=100.0)]
    )
    watch = rclpy.create_node("bench_watch", context=context)
    truths, labels = [], []
    watch.create_subscription(
        String, "impact_truth", lambda m: truths.append(json.loads(m.data)), 100
    )
    watch.create_subscription(
        String, "label", lambda m: labels.append((Label.from_json(m.data), time.monotonic())), 100
    )
    executor.add_node(ident)
    executor.add_node(watch)
    sim = start_sim(rate_hz, duration_s, 1.0, max(1, int(duration_s / 0.6)))
    error = ""
    end = None
    while end is None or time.monotonic() < end:
        try:
            executor.spin_once(timeout_sec=0.05)
        except Exception as exc:  # the identifier failed: keep measuring the transport
            error = f"id_node raised {type(exc).__name__}: {exc}"
            executor.remove_node(ident)
        if end is None and sim.poll() is not None:
            end = time.monotonic() + 1.5
    stamps = np.array([a[0] for a in arrivals])
    walls = np.array([a[1] for a in arrivals])
    expected = int(round(stamps.max() * rate_hz)) + 1 if stamps.size else 0
    lost = 2 * expected - ident.received["jack_pressure"] - ident.received["imu"]
    ratio = (stamps[-1] - stamps[0]) / (walls[-1] - walls[0]) if stamps.size > 1 else 0.0
    latencies = []
    matching = match(
        truths,
        [label for label, _ in labels],
        match_tolerance_s(load_parameters()["identification"]),
    )
    for number, paired in matching.pairs:
        reached = np.searchsorted(stamps, truths[number]["contact_end_stamp"])
        if reached < walls.size:
            latencies.append((labels[paired][1] - walls[reached]) * 1e3)
    executor.shutdown()
    for node in (ident, watch):
        node.destroy_node()
    rclpy.try_shutdown(context=context)
    return {
        "lost": float(lost),
        "ratio": ratio,
        "latency_ms": statistics.median(latencies) if latencies else float("nan"),
        "labelled": float(len(latencies)),
        "impacts": float(len(truths)),
        "error": error,
    }


def run_recorder(duration_s: float) -> dict[str, float]:
    """sim_node as fast as it can -> bag_recorder here; messages written per wall second."""
    import rclpy
    from rclpy.experimental import EventsExecutor
    from rclpy.parameter import Parameter

    from tail_beam_sim.bags.read import read_sensors
    from tail_beam_sim.ros.recorder_node import RecorderNode

    bag = Path(tempfile.mkdtemp()) / "bench"
    context = rclpy.Context()
    rclpy.init(context=context)
    executor = EventsExecutor(context=context)
    recorder = RecorderNode(
        context=context, parameter_overrides=[Parameter("recorder.bag_path", value=str(bag))]
    )
    executor.add_node(recorder)
    sim = start_sim(2000.0, duration_s, 0.0, 0)
    first = last = None  # (wall s, messages written) at the first and the latest write seen
    end = None
    while end is None or time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)
        count = recorder.writer.message_count
        if count and first is None:
            first = (time.monotonic(), count)
        if first is not None and (last is None or count > last[1]):
            last = (time.monotonic(), count)
        if end is None and sim.poll() is not None:
            end = time.monotonic() + 1.0
    recorder.close()
    executor.shutdown()
    recorder.destroy_node()
    rclpy.try_shutdown(context=context)
    data = read_sensors(bag, required=("jack_pressure", "imu"))
    count = recorder.writer.message_count
    expected = sum(
        int(round(s.max() * 2000.0)) + 1 for s in (data.pressure_stamp_s, data.imu_stamp_s)
    )
    got = data.pressure_stamp_s.size + data.imu_stamp_s.size
    rate = (last[1] - first[1]) / (last[0] - first[0]) if first and last[0] > first[0] else 0.0
    return {"msgs_per_s": rate, "written": float(count), "lost": float(expected - got)}


def run_writer(count: int = 50_000) -> float:
    """The recorder's writer alone: serialized messages written per second (no middleware)."""
    from tail_beam_sim import topics
    from tail_beam_sim.bags import records as bagio
    from tail_beam_sim.bags.write import SegmentedBagWriter

    stamps = np.arange(1) / 2000.0
    record = next(bagio.pressure_msgs(stamps, np.full(1, 20e6), 1e8))
    data = bytes(bagio.TYPESTORE.serialize_cdr(record[2], topics.MSG_TYPES[topics.JACK_PRESSURE]))
    writer = SegmentedBagWriter(Path(tempfile.mkdtemp()) / "writer")
    started = time.perf_counter()
    for index in range(count):
        writer.write(topics.JACK_PRESSURE, index * 500_000, data)
    writer.close()
    return count / (time.perf_counter() - started)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--rates", type=float, nargs="+", default=[2000.0, 5000.0, 10000.0])
    parser.add_argument(
        "--duration", type=float, default=6.0, help="simulated (= wall) seconds per run"
    )
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print(
        f"ROS_DOMAIN_ID {os.environ['ROS_DOMAIN_ID']}, {os.cpu_count()} cores, {args.repeats} "
        f"repeats, {args.duration:g} s each"
    )
    print(
        f"{'rate Hz':>8} {'msgs/s':>8} {'lost':>6} {'realtime':>9} {'latency ms':>11} "
        f"{'labelled':>9}"
    )
    for rate in args.rates:
        runs = [run_identification(rate, args.duration) for _ in range(args.repeats)]
        med = {k: statistics.median(r[k] for r in runs) for k in runs[0] if k != "error"}
        # A run whose identifier failed stopped counting there: its loss means nothing.
        worst = max(r["lost"] for r in runs) if not any(r["error"] for r in runs) else float("nan")
        print(
            f"{rate:8.0f} {2 * rate:8.0f} {worst:6.0f} {med['ratio']:9.3f} "
            f"{med['latency_ms']:11.1f} {med['labelled']:4.0f}/{med['impacts']:<4.0f}",
            flush=True,
        )
        for error in sorted({r["error"] for r in runs if r["error"]}):
            print(f"         {error}", flush=True)
    runs = [run_recorder(args.duration) for _ in range(args.repeats)]
    print(
        f"recorder: {statistics.median(r['msgs_per_s'] for r in runs):.0f} messages/s written "
        "(median) from sim_node running "
        "as fast as it can (2 kHz + 2 kHz; the simulator is the limit), lost at most "
        f"{max(r['lost'] for r in runs):.0f} "
        f"of {runs[0]['written']:.0f}"
    )
    print(
        f"recorder's writer alone (serialized bytes to mcap segments): "
        f"{statistics.median(run_writer() for _ in range(args.repeats)):.0f} messages/s (median)"
    )


if __name__ == "__main__":
    main()
