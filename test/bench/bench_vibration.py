"""Benchmark of the vibration pipeline as deployed; prints figures, asserts nothing.

sim_node -> id_node -> bag_recorder, each its own process (console scripts), sim_node at
realtime_factor 1 on a generated caving stream, at each vibration rate asked for. Reported per
run, from the recorded bag and /proc:

* real-time ratio: simulation time the vibration's stamps span over the recorder's log (wall)
  time of the same messages;
* loss: vibration samples missing from the running index (bag), pressure and IMU samples
  missing from their k / rate grids (bag), id_node's gap warnings, the recorder's own count;
* CPU share of each process over the steady part of the run (utime + stime from
  /proc/<pid>/stat, one core = 100 %);
* bag size per minute of the support (the run's bag, scaled), with the compression asked for;
* identification: live labels against the truths (missed and extra count), R >= 50 mm apart,
  the wall latency of each label after its contact end's data and after the last data it
  needed, and whether `tail-beam identify` on the bag gives the same labels.

Usage: python test/bench/bench_vibration.py [--rates 25600 51200 76800 100000] [--duration 20]
       [--compression zstd none]
The machine is shared: say so when quoting figures.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

BIN = Path(sys.executable).parent
TICK_S = os.sysconf("SC_CLK_TCK")
os.environ.setdefault("ROS_DOMAIN_ID", str(74 + os.getpid() % 20))


def cpu_s(pid: int) -> float | None:
    """CPU seconds (user + system) of a process so far, or None once it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / TICK_S


def ros_args(params: dict[str, object]) -> list[str]:
    return ["--ros-args"] + [a for k, v in params.items() for a in ("-p", f"{k}:={v}")]


def run(
    rate_hz: float,
    duration_s: float,
    compression: str,
    workdir: Path,
    sim_params: dict[str, str] | None = None,
    id_params: dict[str, str] | None = None,
) -> dict[str, object]:
    from tail_beam_sim.bags.read import read_sensors

    bag = workdir / f"bag_{int(rate_hz)}_{compression}"
    log = workdir / f"id_{int(rate_hz)}_{compression}.log"
    sim_log = workdir / f"sim_{int(rate_hz)}_{compression}.log"
    sensors = {"sensors.vibration_rate_hz": rate_hz}
    id_err, sim_err = (
        log.open("w"),
        sim_log.open("w"),
    )  # the nodes' logs, closed once they are done
    recorder = subprocess.Popen(
        [
            str(BIN / "bag_recorder"),
            *ros_args({"recorder.bag_path": str(bag), "recorder.compression": compression}),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    ident = subprocess.Popen(
        [
            str(BIN / "id_node"),
            *ros_args({"id_node.flush_after_idle_s": 1.0, **sensors, **(id_params or {})}),
        ],
        stdout=subprocess.DEVNULL,
        stderr=id_err,
    )
    sim = subprocess.Popen(
        [
            str(BIN / "sim_node"),
            *ros_args(
                {
                    **sensors,
                    "sim_node.wait_for_subscribers": 2,
                    "sim_node.exit_after_idle_s": 0.5,
                    "scenario.source": "generated",
                    "scenario.count": max(1, int(duration_s / 0.55)),
                    "scenario.start_s": 0.5,
                    **(sim_params or {}),
                }
            ),
        ],
        stdout=subprocess.DEVNULL,
        stderr=sim_err,
    )
    procs = {"sim_node": sim, "id_node": ident, "bag_recorder": recorder}
    samples: list[tuple[float, dict[str, float | None]]] = []
    while sim.poll() is None:
        samples.append((time.monotonic(), {name: cpu_s(p.pid) for name, p in procs.items()}))
        time.sleep(0.5)
    time.sleep(1.5)
    for p in (ident, recorder):
        p.send_signal(signal.SIGINT)
    _, recorder_err = recorder.communicate(timeout=60)
    ident.wait(timeout=60)
    id_err.close()
    sim_err.close()
    # Steady part: from 4 s after start (start-up and the 2 s subscriber settle) to the last
    # sample.
    steady = [
        s
        for s in samples
        if s[0] >= samples[0][0] + 4.0 and all(v is not None for v in s[1].values())
    ]
    share = {}
    if len(steady) >= 2:
        (t0, c0), (t1, c1) = steady[0], steady[-1]
        share = {name: 100.0 * (c1[name] - c0[name]) / (t1 - t0) for name in procs}
    if (
        sim.returncode != 0
    ):  # refused its parameters (a rate out of range, ...): nothing to measure
        lines = sim_log.read_text().strip().splitlines()
        raise RuntimeError(
            f"sim_node exited with status {sim.returncode}: {lines[-1] if lines else 'no output'}"
        )
    data = read_sensors(bag, required=())
    blocks = data.vibration
    stamps = blocks.sample_stamps_s()
    from rosbags.highlevel import AnyReader

    from tail_beam_sim.bags.records import TYPESTORE

    with AnyReader(
        [bag], default_typestore=TYPESTORE
    ) as reader:  # the vibration's own log times (labels come later)
        vib = [c for c in reader.connections if c.topic.endswith("/vibration")]
        times = [ns for _, ns, _ in reader.messages(connections=vib)]
        log_span_s = (max(times) - min(times)) * 1e-9 if times else 0.0
        label_times = [
            ns
            for _, ns, _ in reader.messages(
                connections=[c for c in reader.connections if c.topic.endswith("/label")]
            )
        ]
    stamp_span_s = float(stamps[-1] - stamps[0]) if stamps.size else 0.0
    pressure_missing = (
        int(round((data.pressure_stamp_s[-1] - data.pressure_stamp_s[0]) * 2000.0))
        + 1
        - data.pressure_stamp_s.size
    )
    imu_missing = (
        int(round((data.imu_stamp_s[-1] - data.imu_stamp_s[0]) * 2000.0))
        + 1
        - data.imu_stamp_s.size
    )
    size = sum(f.stat().st_size for f in bag.iterdir() if f.is_file())
    gap_warnings = sum(
        1 for line in log.read_text().splitlines() if "vibration:" in line and "lost" in line
    )
    scores = identification_scores(
        bag,
        data,
        np.asarray(times, dtype=float) * 1e-9,
        np.asarray(label_times, dtype=float) * 1e-9,
    )
    return {
        **scores,
        "rate_hz": rate_hz,
        "compression": compression,
        "sim_s": stamp_span_s,
        "realtime": stamp_span_s / log_span_s if log_span_s else float("nan"),
        "vib_lost": data.vibration_lost_samples,
        "pressure_lost": pressure_missing,
        "imu_lost": imu_missing,
        "id_gap_warnings": gap_warnings,
        "recorder_line": recorder_err.strip().splitlines()[-1] if recorder_err.strip() else "",
        "cpu": share,
        "mb_per_min": size / 1e6 / stamp_span_s * 60.0 if stamp_span_s else float("nan"),
        "labels": len(data.json_topics.get("label", [])),
    }


def identification_scores(
    bag: Path, data, block_log_s: np.ndarray, label_log_s: np.ndarray
) -> dict[str, object]:
    """The live labels in the bag against its truths (tail_beam_id.stream.label.match): correct of
    matched, for all and for R >= 50 mm, extra labels, live = offline (`tail-beam identify`
    on the bag), and the wall latency of each label after the data of its contact's end: the
    recorder's log time of the label less that of the vibration block holding the contact end."""
    from tail_beam_id.cli.identify_cmd import identify_bag
    from tail_beam_id.stream.label import Label, match, match_tolerance_s
    from tail_beam_sim.config import load_parameters

    truths = data.json_topics.get("impact_truth", [])
    labels = [Label.from_dict(obj) for obj in data.json_topics.get("label", [])]
    matching = match(truths, labels, match_tolerance_s(load_parameters()["identification"]))
    right = [
        (truths[i]["radius_m"], labels[j].material == truths[i]["label"])
        for i, j in matching.pairs
    ]
    blocks = data.vibration
    block_end_s = blocks.stamp_s + blocks.lengths * blocks.period_s
    latency_ms, after_data_ms = [], []
    for i, j in matching.pairs:
        k = int(np.searchsorted(block_end_s, truths[i]["final_separation_stamp"]))
        if k < block_log_s.size and j < label_log_s.size:
            latency_ms.append((label_log_s[j] - block_log_s[k]) * 1e3)
        # The block holding the last sample the decision needed (impact stamp + data latency).
        horizon_s = labels[j].impact_stamp_s + (labels[j].data_latency_ms or 0.0) / 1e3
        h = int(np.searchsorted(block_end_s, horizon_s))
        if h < block_log_s.size and j < label_log_s.size:
            after_data_ms.append((label_log_s[j] - block_log_s[h]) * 1e3)
    offline = identify_bag(str(bag), calibrate=False)  # id_node as run here does not calibrate
    return {
        "impacts": len(truths),
        "correct": sum(ok for _, ok in right),
        "missed": len(matching.missed),
        "extra": len(matching.extra),
        "big": sum(1 for r, _ in right if r >= 0.05)
        + sum(1 for i in matching.missed if truths[i]["radius_m"] >= 0.05),
        "big_correct": sum(ok for r, ok in right if r >= 0.05),
        "latency_ms": (float(np.median(latency_ms)), float(np.max(latency_ms)))
        if latency_ms
        else (float("nan"),) * 2,
        "after_data_ms": (float(np.median(after_data_ms)), float(np.max(after_data_ms)))
        if after_data_ms
        else (float("nan"),) * 2,
        "same_offline": [x.decision() for x in labels] == [x.decision() for x in offline],
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", type=float, nargs="+", default=[25600.0])
    parser.add_argument("--duration", type=float, default=20.0, help="simulated seconds per run")
    parser.add_argument("--compression", nargs="+", default=["zstd"], choices=["zstd", "none"])
    parser.add_argument(
        "--sim-param",
        action="append",
        default=[],
        metavar="NAME:=VALUE",
        help="a sim_node parameter (repeatable)",
    )
    parser.add_argument(
        "--id-param",
        action="append",
        default=[],
        metavar="NAME:=VALUE",
        help="an id_node parameter (repeatable)",
    )
    parser.add_argument(
        "--keep",
        type=Path,
        default=None,
        metavar="DIR",
        help="write the bags and id_node's logs here and keep them "
        "(default: a temporary directory)",
    )
    args = parser.parse_args()
    sim_params = dict(item.split(":=", 1) for item in args.sim_param)
    id_params = dict(item.split(":=", 1) for item in args.id_param)
    print(
        f"load average before: {os.getloadavg()[0]:.2f} (shared machine, {os.cpu_count()} cores)",
        flush=True,
    )
    print(
        "| vibration rate | compression | real-time ratio | lost (vibration / pressure / IMU "
        "samples) | id_node gap warnings "
        "| CPU sim / id / recorder | bag MB per min | labels |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    if args.keep is not None:
        args.keep.mkdir(parents=True, exist_ok=True)
    with (
        contextlib.nullcontext(str(args.keep))
        if args.keep is not None
        else tempfile.TemporaryDirectory(prefix="bench_vibration_")
    ) as tmp:
        for rate in args.rates:
            for compression in args.compression:
                try:
                    r = run(rate, args.duration, compression, Path(tmp), sim_params, id_params)
                except RuntimeError as exc:
                    print(
                        f"| {rate / 1000:g} kHz | {compression} | not run: {exc} | | | | | |",
                        flush=True,
                    )
                    continue
                cpu = r["cpu"]
                cpu_text = (
                    " / ".join(f"{cpu[n]:.0f} %" for n in ("sim_node", "id_node", "bag_recorder"))
                    if cpu
                    else "n/a"
                )
                print(
                    f"| {rate / 1000:g} kHz | {compression} | {r['realtime']:.3f} | "
                    f"{r['vib_lost']} / {r['pressure_lost']} / {r['imu_lost']} "
                    f"| {r['id_gap_warnings']} | {cpu_text} | {r['mb_per_min']:.1f} | "
                    f"{r['labels']} |",
                    flush=True,
                )
                print(f"    recorder: {r['recorder_line']}", file=sys.stderr)
                print(
                    f"    identification: {r['correct']}/{r['impacts']} correct ({r['missed']} "
                    f"missed, {r['extra']} extra), "
                    f"R >= 50 mm {r['big_correct']}/{r['big']}; label after the contact end's "
                    "data: median "
                    f"{r['latency_ms'][0]:.1f} ms, max {r['latency_ms'][1]:.1f} ms (wall); after "
                    "the block holding the last "
                    f"sample it needed: median {r['after_data_ms'][0]:.1f} ms, max "
                    f"{r['after_data_ms'][1]:.1f} ms; "
                    f"live labels = offline: {r['same_offline']}",
                    flush=True,
                )
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
