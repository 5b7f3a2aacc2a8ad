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
  their k / rate grids, lumps without a truth or a rebound in the bag.

Usage: python test/bench/bench_flow_node.py [--rates 5 50 200] [--seconds 20]
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


def run(rate: float, seconds: float, workdir: Path) -> dict[str, object]:
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
    samples = []
    while sim.poll() is None:
        samples.append((time.monotonic(), {n: cpu_s(p.pid) for n, p in procs.items()}))
        time.sleep(0.5)
    time.sleep(1.0)
    recorder.send_signal(signal.SIGINT)
    recorder.communicate(timeout=60)
    sim_log.close()
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
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", nargs="+", type=float, default=[5.0, 50.0, 200.0])
    parser.add_argument("--seconds", type=float, default=20.0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for rate in args.rates:
            load = os.getloadavg()[0]
            r = run(rate, args.seconds, Path(tmp))
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


if __name__ == "__main__":
    main()
