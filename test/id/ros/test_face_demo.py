"""``tail-beam demo --face``: a group of supports drawn one after another by caving_node, live;
with ``--processes`` the supports spread over processes, talking over the middleware."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tail_beam_id.cli.face_hosts import HostLost, SupportHost, default_processes, split_supports
from tail_beam_sim.errors import InputError

TAIL_BEAM = str(Path(sys.executable).parent / "tail-beam")
# A flow that reaches gangue within a few seconds of each opening: the windows close soon.
QUICK_FLOW = """\
/**:
  ros__parameters:
    flow:
      lumps_per_s: 30.0
      share_drawn_mass_kg: [0.0, 4.0, 12.0]
      share_gangue: [0.0, 0.0, 0.8]
"""


def test_the_demos_process_keeps_the_fewest_supports_and_the_rest_split_evenly():
    """Three supports over two processes: one here (beside the controller and the recorders),
    two in the other; over three, one each; every support once, in order."""
    names = [f"/support_{k:03d}" for k in range(1, 6)]
    assert split_supports(names[:3], 1) == [names[:3]]
    assert split_supports(names[:3], 2) == [names[:1], names[1:3]]
    assert split_supports(names[:3], 3) == [[n] for n in names[:3]]
    blocks = split_supports(names, 3)
    assert [n for b in blocks for n in b] == names and [len(b) for b in blocks] == [1, 2, 2]


def test_one_process_per_core_by_default_and_never_more_than_supports():
    """The default spreads a face over the cores this process may use, one support at least
    per process."""
    cores = len(os.sched_getaffinity(0))
    assert default_processes(1) == 1
    assert default_processes(12) == min(12, cores)
    assert default_processes(2) == min(2, cores)


@pytest.mark.parametrize("processes", [0, 4])
def test_more_processes_than_supports_or_none_is_refused_by_name(processes):
    """--processes names itself and the range it may take."""
    with pytest.raises(InputError, match=r"--processes = .*must be in \[1, 3\]"):
        split_supports(["/a", "/b", "/c"], processes)


@pytest.mark.ros
@pytest.mark.slow
def test_two_supports_over_two_processes_close_as_offline_and_lose_nothing(tmp_path):
    """Each support in its own process: both windows close on the rule, nothing is lost by the
    recorders or the identifiers (the other process's, reported back), and each live decision
    is the one the rule gives on the bag identified offline."""
    config = tmp_path / "quick.yaml"
    config.write_text(QUICK_FLOW)
    result = subprocess.run(
        [
            TAIL_BEAM,
            "demo",
            "--face",
            "2",
            "--processes",
            "2",
            "--config",
            str(config),
            "--check-offline",
            "--bag",
            str(tmp_path / "bags"),
        ],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    out = result.stdout
    assert result.returncode == 0, (out[-3000:], result.stderr[-3000:])
    assert "Traceback" not in result.stderr, result.stderr[-3000:]
    assert "2 processes (1 + 1 supports" in out, out[-3000:]
    for ns in ("/support_001", "/support_002"):
        assert re.search(rf"^{ns} +\d+\.\d+s ", out, re.M), out[-3000:]  # its window closed
        assert re.search(
            rf"^{ns}: \d+\.\d s simulated; recorder lost 0 vibration samples, 0 messages; "
            r"identifier lost 0 samples",
            out,
            re.M,
        ), out[-3000:]
        assert re.search(rf"^{ns}: offline decision .*: same;", out, re.M), out[-3000:]
        assert (tmp_path / "bags" / ns.strip("/") / "metadata.yaml").exists()


@pytest.mark.ros
@pytest.mark.slow
def test_a_supports_process_killed_is_said_as_lost_not_waited_for(tmp_path):
    """The demo's side of a child process: ready once its nodes are built, then, killed,
    HostLost naming its supports at the next look (the demo then stops with one line)."""
    values = {
        "scenario.source": "flow",
        "flow.open_at_s": -1.0,
        "sim_node.exit_after_idle_s": 0.0,
        "sim_node.wait_for_subscribers": 1,
    }
    host = SupportHost(["/support_009"], [values], {}, 0.3)
    try:
        host.wait_ready()
        host.poll()
        os.kill(host.process.pid, signal.SIGKILL)
        host.process.join(10.0)
        with pytest.raises(HostLost, match="/support_009 exited"):
            for _ in range(100):
                host.poll()
                time.sleep(0.05)
    finally:
        assert host.stop() == []


@pytest.mark.ros
def test_a_parameter_a_supports_process_refuses_is_one_error_and_no_round(tmp_path):
    """A child whose support refuses a parameter says so once, as the InputError the demo prints
    in one line, and sends no summary of a round that never ran."""
    from multiprocessing import Pipe

    from tail_beam_id.cli.face_hosts import host_supports

    bad = {"scenario.source": "flow", "sim_node.realtime_factor": -1.0}
    ours, theirs = Pipe()
    host_supports(["/support_010"], [bad], {}, 0.3, theirs)
    said = []
    while ours.poll(0.5):
        said.append(ours.recv())
    assert [kind for kind, _ in said] == ["error"], said
    field, value, _ = said[0][1]
    assert field.endswith("realtime_factor") and value == -1.0
