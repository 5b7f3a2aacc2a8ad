"""Soak: sim_node, id_node and bag_recorder as processes on a long generated stream at
``realtime_factor:=0``; prints the resident memory (RSS) of each every few seconds, then checks
the bag: impacts (truths) = rebounds = the count asked for, each impact has its label by the
suite's one matching rule (tail_beam_id.stream.label.match) with no label left over, and the live
labels are those `tail-beam identify` gives on the bag.

    python test/bench/soak_nodes.py --impacts 1000          # about 8 minutes on a loaded 2-core
    machine

Not part of the pytest suite (too long); test/sim/ros/test_soak_short.py runs the same with 20
impacts.
Exit status 0 when the counts match and the bag reads, 1 otherwise.
"""

from __future__ import annotations

import argparse
import re
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

BIN = Path(sys.executable).parent
NODES = ("sim_node", "id_node", "bag_recorder")


def rss_mb(pid: int) -> float:
    """Resident set size of a process, MB (from /proc; NaN once it is gone)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


@dataclass
class SoakResult:
    """Counts found in the bag and the RSS samples of each node (wall s, MB); ``matched``: truths
    paired with a label, ``extra``: labels paired with none (tail_beam_id.stream.label.match)."""

    asked: int
    truths: int = 0
    labels: int = 0
    offline_labels: int = 0  # tail-beam identify on the bag's sensor topics
    live_matches_offline: bool = False  # same stamps, labels, methods and confidences
    matched: int = 0
    extra: int = 0
    rebounds: int = 0
    messages: int = 0
    wall_s: float = 0.0
    rss: dict[str, list[tuple[float, float]]] = field(default_factory=dict)
    logs: dict[str, str] = field(default_factory=dict)

    @property
    def counts_match(self) -> bool:
        return (
            self.asked == self.truths == self.matched == self.rebounds
            and self.extra == 0
            and self.live_matches_offline
        )


def start(exe: str, params: list[str], log_dir: Path, namespace: str = "") -> subprocess.Popen:
    args = (
        [str(BIN / exe), "--ros-args"]
        + [a for p in params for a in ("-p", p)]
        + (["-r", f"__ns:={namespace}"] if namespace else [])
    )
    log = (log_dir / f"{exe}.log").open("w")
    return subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT)


def wait_for_labels(log: Path, count: int, quiet_s: float, timeout_s: float) -> float:
    """Wait until id_node's log holds ``count`` published labels ("impact at T s: coal ...")
    and has not grown for ``quiet_s``, or ``timeout_s`` passed; the seconds waited."""
    label_line = re.compile(r"\]: (?:revised: )?impact at \S+ s: ")
    began = time.monotonic()
    size, since = -1, began
    while time.monotonic() - began < timeout_s:
        text = log.read_text()
        if len(text) != size:
            size, since = len(text), time.monotonic()
        elif len(label_line.findall(text)) >= count and time.monotonic() - since >= quiet_s:
            break
        time.sleep(0.2)
    return time.monotonic() - began


def soak(
    impacts: int,
    work: Path,
    sample_s: float = 5.0,
    timeout_s: float = 3600.0,
    echo=print,
    recorder_params: tuple[str, ...] = (),
    namespace: str = "",
    id_params: tuple[str, ...] = (),
) -> SoakResult:
    """Run the three nodes on ``impacts`` generated impacts; return what the bag holds.
    ``recorder_params`` and ``id_params`` are extra ``name:=value`` overrides of the recorder
    and id_node (experiments); ``namespace`` puts the whole support under one."""
    from tail_beam_id.stream.label import Label, match, match_tolerance_s
    from tail_beam_sim import topics
    from tail_beam_sim.bags.read import read_sensors
    from tail_beam_sim.config import load_parameters

    bag = work / "soak_bag"
    procs = {
        "bag_recorder": start(
            "bag_recorder", [f"recorder.bag_path:={bag}", *recorder_params], work, namespace
        ),
        "id_node": start(
            "id_node", ["id_node.flush_after_idle_s:=2.0", *id_params], work, namespace
        ),
    }
    time.sleep(2.0)  # both are up before the simulator waits for its subscribers
    procs["sim_node"] = start(
        "sim_node",
        [
            "scenario.source:=generated",
            f"scenario.count:={impacts}",
            "sim_node.realtime_factor:=0.0",
            "sim_node.wait_for_subscribers:=2",
            "sim_node.exit_after_idle_s:=1.0",
        ],
        work,
        namespace,
    )
    result = SoakResult(impacts, rss={name: [] for name in NODES})
    began = time.monotonic()
    next_sample = began
    try:
        while procs["sim_node"].poll() is None and time.monotonic() - began < timeout_s:
            if time.monotonic() >= next_sample:
                now = time.monotonic() - began
                line = []
                for name in NODES:
                    mb = rss_mb(procs[name].pid)
                    result.rss[name].append((now, mb))
                    line.append(f"{name} {mb:6.1f}")
                echo(f"{now:7.1f} s  RSS MB: " + "  ".join(line), flush=True)
                next_sample += sample_s
            time.sleep(0.2)
        # id_node decides the last impacts after the data stops (its idle flush, 2 s): wait until
        # it has said as many labels as impacts asked and then nothing for 2 s (a label too many
        # would come in that time).
        said_all_s = wait_for_labels(work / "id_node.log", impacts, quiet_s=2.0, timeout_s=60.0)
        echo(f"id_node said its labels {said_all_s:.1f} s after the simulator ended", flush=True)
        for name in NODES:
            result.rss[name].append((time.monotonic() - began, rss_mb(procs[name].pid)))
    finally:
        for name in ("id_node", "bag_recorder", "sim_node"):
            if procs[name].poll() is None:
                procs[name].send_signal(signal.SIGINT)
                try:
                    procs[name].wait(timeout=30)
                except subprocess.TimeoutExpired:
                    procs[name].kill()
                    procs[name].wait()
        result.wall_s = time.monotonic() - began
        result.logs = {name: (work / f"{name}.log").read_text()[-3000:] for name in NODES}
    if procs["sim_node"].returncode != 0:
        raise RuntimeError(
            f"sim_node exited {procs['sim_node'].returncode}: {result.logs['sim_node'][-500:]}"
        )
    data = read_sensors(bag)
    result.truths = len(data.json_topics[topics.IMPACT_TRUTH])
    result.labels = len(data.json_topics[topics.LABEL])
    result.rebounds = len(data.rebounds)
    from tail_beam_id.cli.identify_cmd import identify_bag

    live = [Label.from_dict(obj) for obj in data.json_topics[topics.LABEL]]
    offline = identify_bag(str(bag), calibrate=False)  # id_node as run here does not calibrate
    result.offline_labels = len(offline)
    result.live_matches_offline = [lab.decision() for lab in live] == [
        lab.decision() for lab in offline
    ]
    matching = match(
        data.json_topics[topics.IMPACT_TRUTH],
        live,
        match_tolerance_s(load_parameters()["identification"]),
    )
    result.matched, result.extra = len(matching.pairs), len(matching.extra)
    result.messages = (
        data.pressure_stamp_s.size
        + data.imu_stamp_s.size
        + result.rebounds
        + result.truths
        + result.labels
    )
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description="soak sim_node, id_node and bag_recorder; print RSS; check the bag's counts"
    )
    parser.add_argument("--impacts", type=int, default=1000)
    parser.add_argument("--sample-s", type=float, default=5.0, help="RSS sampling period, s")
    parser.add_argument(
        "--keep", action="store_true", help="keep the bag and logs (their directory is printed)"
    )
    parser.add_argument(
        "--recorder-param",
        action="append",
        default=[],
        metavar="NAME:=VALUE",
        help="extra recorder parameter (repeatable)",
    )
    args = parser.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="tail_beam_soak_"))
    result = soak(args.impacts, work, args.sample_s, recorder_params=tuple(args.recorder_param))
    print(
        f"\n{args.impacts} impacts in {result.wall_s:.0f} s wall; bag: {result.messages} messages"
    )
    for name, samples in result.rss.items():
        values = [mb for _, mb in samples if mb == mb]
        if values:
            third = max(1, len(values) // 3)
            print(
                f"  {name:<13} RSS first {values[0]:6.1f} MB, max {max(values):6.1f} MB, last "
                f"{values[-1]:6.1f} MB; "
                f"mean of first third {sum(values[:third]) / third:6.1f}, of last third "
                f"{sum(values[-third:]) / third:6.1f}"
            )
    print(
        f"  truths {result.truths}, labels {result.labels} ({result.matched} matched, "
        f"{result.extra} extra; offline "
        f"{result.offline_labels}, "
        f"{'the same' if result.live_matches_offline else 'NOT the same'}), rebounds "
        f"{result.rebounds} "
        f"(asked {result.asked}): "
        f"{'match' if result.counts_match else 'MISMATCH'}"
    )
    if args.keep:
        print(f"  kept in {work}")
    else:
        import shutil

        shutil.rmtree(work, ignore_errors=True)
    return 0 if result.counts_match else 1


if __name__ == "__main__":
    sys.exit(main())
