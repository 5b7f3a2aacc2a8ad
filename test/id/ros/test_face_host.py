"""face_host: several supports' sim_node and id_node in one process, each under its namespace,
seen from another process as separate supports; a bad host parameter refused by name."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from rosprobe import Probe, Processes, ros_context, spin_until
from sensor_msgs.msg import FluidPressure
from std_msgs.msg import String

pytestmark = [pytest.mark.ros, pytest.mark.slow]
BIN = Path(sys.executable).parent
NAMESPACES = ("/support_001", "/support_002")


def host_command(*params: str) -> list[str]:
    """face_host with ``-p`` ``params``: the installed executable, else its entry point."""
    exe = BIN / "face_host"
    start = (
        [str(exe)]
        if exe.exists()
        else [
            sys.executable,
            "-c",
            "import sys; from tail_beam_id.ros.start import face_host; sys.exit(face_host())",
        ]
    )
    return start + ["--ros-args"] + [a for p in params for a in ("-p", p)]


def test_two_supports_in_one_process_publish_under_their_own_namespaces(tmp_path):
    """Each namespace gets its own pressure stream, labels and impact truths; the supports'
    scenarios differ (seeds derived per support), and the host exits 0 by itself once both
    simulators are done, each identifier saying what it lost."""
    procs = Processes(tmp_path)
    watched = {"jack_pressure": FluidPressure, "label": String, "impact_truth": String}
    try:
        with ros_context() as (context, executor):
            probes = {ns: Probe(context, watched, namespace=ns) for ns in NAMESPACES}
            for probe in probes.values():
                executor.add_node(probe)
            host = procs.command(
                "face_host",
                host_command(
                    "face_host.supports:=2",
                    "scenario.source:=generated",
                    "scenario.count:=2",
                    "id_node.poll_period_s:=0.02",
                ),
            )

            def everything_seen() -> bool:
                return all(
                    len(probe.messages[topic]) >= n
                    for probe in probes.values()
                    for topic, n in (("jack_pressure", 1), ("impact_truth", 2), ("label", 2))
                )

            assert spin_until(executor, everything_seen, timeout_s=90.0), (
                {ns: {t: len(m) for t, m in p.messages.items()} for ns, p in probes.items()},
                procs.log(host)[-2000:],
            )
            truths = [p.json("impact_truth") for p in probes.values()]
            assert truths[0] != truths[1]  # support 2 runs scenario.seed + 1
            for probe in probes.values():  # each label is of an impact of its own support
                starts = [t["contact_start_stamp"] for t in probe.json("impact_truth")]
                for label in probe.labels("label"):
                    assert min(abs(label.impact_stamp_s - s) for s in starts) < 0.01
            code = host.wait(timeout=60)
        log = procs.log(host)
        assert code == 0, log[-2000:]
        assert "Traceback" not in log
        for ns in NAMESPACES:  # each identifier's exit line names its support
            assert f"id_node {ns}: " in log and "samples lost:" in log, log[-2000:]
    finally:
        procs.close()


@pytest.mark.parametrize(
    "param, named",
    [
        ("face_host.supports:=0", "face_host.supports = 0"),
        ("face_host.supports:=65", "face_host.supports = 65"),
        ("face_host.namespaces:=[/support_001, /support_001]", "face_host.namespaces"),
        ("face_host.namespaces:=[support_001]", "face_host.namespaces[0]"),
        ("face_host.namespaces:=[/support_002, /left]", "face_host.namespaces"),
    ],
)
def test_a_bad_host_parameter_is_refused_by_name(param, named):
    """0 or too many supports, a namespace twice, a relative one, or two that would be the same
    support of the face: exit 2 before any node, one line naming the parameter."""
    proc = subprocess.run(host_command(param), capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr[-1500:]
    line = proc.stderr.strip().splitlines()[-1]
    assert line.startswith("face_host: error: ") and named in line, proc.stderr[-1500:]
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_stop_signal_stops_the_host_and_every_support(tmp_path, sig):
    """A stop signal while the supports run ends the process with status 0; each support's
    sim_node and id_node close (their exit lines)."""
    procs = Processes(tmp_path)
    try:
        with ros_context() as (context, executor):
            probes = [
                Probe(context, {"jack_pressure": FluidPressure}, namespace=ns) for ns in NAMESPACES
            ]
            for probe in probes:
                executor.add_node(probe)
            host = procs.command("face_host", host_command("face_host.supports:=2"))
            assert spin_until(
                executor, lambda: all(p.messages["jack_pressure"] for p in probes), timeout_s=60.0
            ), procs.log(host)[-2000:]
            code = procs.stop(host, sig)
        log = procs.log(host)
        assert code == 0, log[-2000:]
        assert "Traceback" not in log
        assert log.count("impact_cmd: ") == 2, log[-2000:]
        assert all(f"id_node {ns}: " in log for ns in NAMESPACES), log[-2000:]
    finally:
        procs.close()


def test_a_stop_signal_during_start_up_exits_0_quietly():
    """0.3 s in, the host is still importing: it ends at once, status 0, no traceback."""
    proc = subprocess.Popen(
        host_command("face_host.supports:=2"),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    time.sleep(0.3)
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 0, out[-1500:]
    assert "Traceback" not in out and "KeyboardInterrupt" not in out
