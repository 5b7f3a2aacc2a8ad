"""Benchmark of sim_node running a flow live (scenario.source flow); prints figures, asserts
nothing.

For each flow rate: sim_node (realtime_factor 1, the shipped layout: pressure and IMU at 2 kHz,
accelerometer at 25.6 kHz in blocks of 128) with its window opened at start-up for
``--seconds`` of simulation time, and bag_recorder subscribed to every topic, each its own
process (console scripts). Reported per rate, from /proc and the recorded bag:

* CPU share of sim_node and of the recorder over the steady part (utime + stime, one core =
  100 %; the machine's load average alongside, as the machine is shared), and sim_node's CPU
  seconds per second of simulation (share / real-time ratio: what real time would take);
* real-time ratio: simulation time the vibration stamps span over the recorder's log (wall)
  time of the same messages (1.0: real time kept);
* loss: vibration samples missing from the running index, pressure and IMU samples missing from
  their k / rate grids, lumps without a truth or a rebound in the bag;
* with ``--identify``, id_node (config/'s parameters, as shipped) runs beside them: its CPU share,
  the labels it published against the lumps, and each label's lag, from the moment the
  recorder logged the vibration at the label's impact stamp to the moment it logged the label
  (median, 95th percentile, and the median over the first and the last quarter of the run:
  growing when id_node falls behind).

Usage: python test/bench/bench_flow_node.py [--rates 5 50 200] [--seconds 20] [--identify]
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from rosbags.highlevel import AnyReader

BIN = Path(sys.executable).parent
TICK_S = os.sysconf("SC_CLK_TCK")
os.environ.setdefault("ROS_DOMAIN_ID", str(94 + os.getpid() % 5))


def cpu_s(pid: int) -> float | None:
    """CPU seconds (user + system) of a process so far, or None once it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / TICK_S


def ros_args(params: dict[str, object]) -> list[str]:
    return ["--ros-args"] + [a for k, v in params.items() for a in ("-p", f"{k}:={v}")]


def label_lags_s(bag: Path) -> list[tuple[float, float]]:
    """(log time s, lag s) of every label in ``bag``: the recorder's log time of the label less
    its log time of the vibration block holding the label's impact stamp (interpolated)."""
    import json

    import numpy as np

    from tail_beam_id.stream.label import LABEL_STAMP
    from tail_beam_sim.bags.records import TYPESTORE

    with AnyReader([bag], default_typestore=TYPESTORE) as reader:
        vib = [c for c in reader.connections if c.topic.endswith("/vibration")]
        blocks = [
            (m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec, ns * 1e-9)
            for c, ns, raw in reader.messages(connections=vib)
            for m in [reader.deserialize(raw, c.msgtype)]
        ]
        lab = [c for c in reader.connections if c.topic.endswith("/label")]
        labels = [
            (ns * 1e-9, json.loads(reader.deserialize(raw, c.msgtype).data))
            for c, ns, raw in reader.messages(connections=lab)
        ]
    if not blocks:
        return []
    stamps, logged = (np.array(v) for v in zip(*sorted(blocks)))
    return [
        (t, t - float(np.interp(float(label[LABEL_STAMP]), stamps, logged)))
        for t, label in labels
        if LABEL_STAMP in label
    ]


def run(rate: float, seconds: float, workdir: Path, identify: bool) -> dict[str, object]:
    from tail_beam_sim.bags.read import read_sensors
    from tail_beam_sim.bags.records import TYPESTORE

    bag = workdir / f"flow_{rate:g}"
    recorder = subprocess.Popen(
        [str(BIN / "bag_recorder"), *ros_args({"recorder.bag_path": str(bag)})],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    sim_log = (workdir / f"sim_{rate:g}.log").open("w")
    sim = subprocess.Popen(
        [
            str(BIN / "sim_node"),
            *ros_args(
                {
                    "scenario.source": "flow",
                    "flow.lumps_per_s": rate,
                    "flow.open_at_s": 0.5,
                    "flow.duration_s": seconds,
                    "sim_node.wait_for_subscribers": 1,
                }
            ),
        ],
        stdout=subprocess.DEVNULL,
        stderr=sim_log,
    )
    procs = {"sim_node": sim, "bag_recorder": recorder}
    if identify:
        id_log = (workdir / f"id_{rate:g}.log").open("w")
        procs["id_node"] = subprocess.Popen(
            [str(BIN / "id_node")], stdout=subprocess.DEVNULL, stderr=id_log
        )
    samples = []
    while sim.poll() is None:
        samples.append((time.monotonic(), {n: cpu_s(p.pid) for n, p in procs.items()}))
        time.sleep(0.5)
    time.sleep(3.0 if identify else 1.0)  # the last impacts' labels
    for name in ("id_node", "bag_recorder"):
        if name in procs:
            procs[name].send_signal(signal.SIGINT)
            procs[name].communicate(timeout=60)
    sim_log.close()
    if identify:
        id_log.close()
    steady = [
        s
        for s in samples
        if s[0] >= samples[0][0] + 5.0 and all(v is not None for v in s[1].values())
    ]
    share = {}
    if len(steady) >= 2:
        (t0, c0), (t1, c1) = steady[0], steady[-1]
        share = {n: 100.0 * (c1[n] - c0[n]) / (t1 - t0) for n in procs}
    data = read_sensors(bag, required=())
    stamps = data.vibration.sample_stamps_s()
    with AnyReader([bag], default_typestore=TYPESTORE) as reader:
        vib = [c for c in reader.connections if c.topic.endswith("/vibration")]
        times = [ns for _, ns, _ in reader.messages(connections=vib)]
    log_span = (max(times) - min(times)) * 1e-9 if times else float("nan")
    span = float(stamps[-1] - stamps[0]) if stamps.size else 0.0
    grid = {
        "pressure": data.pressure_stamp_s,
        "imu": data.imu_stamp_s,
    }
    missing = {name: int(round((s[-1] - s[0]) * 2000.0)) + 1 - s.size for name, s in grid.items()}
    truths = data.json_topics["impact_truth"]
    log = (workdir / f"sim_{rate:g}.log").read_text().splitlines()
    lumps = next((line for line in log if "flow:" in line and "lumps simulated" in line), "")
    return {
        "rate": rate,
        "cpu": share,
        "realtime": span / log_span if log_span else float("nan"),
        "vib_lost": data.vibration_lost_samples,
        **{f"{k}_lost": v for k, v in missing.items()},
        "truths": len(truths),
        "rebounds": len(data.rebounds),
        "shares": len(data.json_topics["gangue_share_truth"]),
        "sim_line": lumps.split("]: ")[-1],
        "exit": sim.returncode,
        "lags": label_lags_s(bag) if identify else [],
    }


def identify_line(r: dict[str, object], cpu: dict[str, float]) -> str:
    """id_node's figures of one run: CPU share, labels against lumps, lag."""
    import numpy as np

    lags = r["lags"]
    if not lags:
        return f"id_node {cpu.get('id_node', float('nan')):5.1f} % CPU, no label recorded"
    t, lag = (np.array(v) for v in zip(*lags))
    quarter = (t.max() - t.min()) / 4.0
    first = np.median(lag[t <= t.min() + quarter])
    last = np.median(lag[t >= t.max() - quarter])
    return (
        f"id_node {cpu.get('id_node', float('nan')):5.1f} % CPU, {lag.size} labels for "
        f"{r['truths']} lumps, lag median {1e3 * np.median(lag):.0f} ms, p95 "
        f"{1e3 * np.percentile(lag, 95):.0f} ms (first quarter {1e3 * first:.0f} ms, last "
        f"{1e3 * last:.0f} ms)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", nargs="+", type=float, default=[5.0, 50.0, 200.0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--identify", action="store_true", help="run id_node beside them")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for rate in args.rates:
            load = os.getloadavg()[0]
            r = run(rate, args.seconds, Path(tmp), args.identify)
            cpu = r["cpu"]
            per_sim_s = cpu.get("sim_node", float("nan")) / 100.0 / r["realtime"]
            print(
                f"{rate:5g} lumps/s: sim_node {cpu.get('sim_node', float('nan')):5.1f} % CPU "
                f"({per_sim_s:.2f} CPU s per s of simulation), "
                f"recorder {cpu.get('bag_recorder', float('nan')):5.1f} %, real-time ratio "
                f"{r['realtime']:.3f}, lost: vibration {r['vib_lost']}, pressure "
                f"{r['pressure_lost']}, IMU {r['imu_lost']}; {r['truths']} truths, "
                f"{r['rebounds']} rebounds, {r['shares']} share intervals ({r['sim_line']}); "
                f"load average {load:.1f}, exit {r['exit']}",
                flush=True,
            )
            if args.identify:
                print(f"      {identify_line(r, cpu)}", flush=True)


if __name__ == "__main__":
    main()
