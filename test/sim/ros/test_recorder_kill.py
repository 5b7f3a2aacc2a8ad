"""A recorder killed with SIGKILL mid-segment, as a crash would: the open segment is on disk up to
its last flush and `tail-beam bag repair` salvages it, to within a second of the kill."""

from __future__ import annotations

import subprocess
import time

import numpy as np
import pytest
from test_nodes_processes import BIN, Processes, short_scenario

from tail_beam_sim import topics
from tail_beam_sim.bags.read import raw_messages, read_sensors
from tail_beam_sim.bags.write import PARTIAL_DIR
from tail_beam_sim.config import load_parameters

pytestmark = [pytest.mark.ros, pytest.mark.slow]
SEGMENT_S = 4.0  # long segments, so that the kill lands with seconds of data in the open one


@pytest.fixture
def procs(tmp_path):
    manager = Processes(tmp_path)
    yield manager
    manager.close()


def wait_for(condition, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.05)
    return condition()


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_killed_recorder_is_salvaged_to_within_a_second_of_the_kill(tmp_path, procs, storage):
    """SIGKILL 2 s into an open 4 s segment: the segment is not empty, repair salvages it, the
    bag reads with no hole up to < 1 s before the kill (was: 0 bytes, 0 salvaged)."""
    bag = tmp_path / "killed"
    # A namespace of its own: the killed recorder's endpoints linger in discovery for a while, and
    # must not count as a subscriber for another test's simulator.
    ns = f"/kill_{storage}"
    recorder = procs.start(
        "bag_recorder",
        f"recorder.bag_path:={bag}",
        f"recorder.storage:={storage}",
        f"recorder.segment_s:={SEGMENT_S}",
        ns=ns,
    )
    sim = procs.start("sim_node", *short_scenario(60, "sim_node.wait_for_subscribers:=1"), ns=ns)
    suffix = ".mcap" if storage == "mcap" else ".db3"
    assert wait_for(lambda: bag.exists() and any(bag.glob(f"*{suffix}")), 60), procs.log(recorder)[
        -2000:
    ]
    time.sleep(SEGMENT_S / 2)  # well inside the second segment
    killed_ns = time.time_ns()
    recorder.kill()
    recorder.wait()
    procs.stop(sim)
    open_files = [p for p in (bag / PARTIAL_DIR).rglob(f"*{suffix}")]
    assert open_files and all(p.stat().st_size > 0 for p in open_files), (
        "the open segment is empty on disk"
    )
    closed = sum(1 for _ in raw_messages(bag))

    result = subprocess.run(
        [str(BIN / "tail-beam"), "bag", "repair", str(bag)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    assert "the bag reads" in result.stdout
    messages = list(raw_messages(bag))
    assert len(messages) > closed, f"nothing salvaged: {result.stdout}"
    last_ns = max(m.log_time_ns for m in messages)
    assert 0 <= killed_ns - last_ns < 1e9, (
        f"lost {(killed_ns - last_ns) * 1e-9:.2f} s before the kill"
    )
    data = read_sensors(bag, required=(topics.JACK_PRESSURE, topics.IMU))
    assert not data.partial
    rate = load_parameters()["sensors"]["pressure_rate_hz"]
    np.testing.assert_allclose(
        np.diff(data.pressure_stamp_s), 1.0 / rate, atol=1e-9
    )  # no hole, no duplicate
    assert data.pressure_stamp_s.size > 1.5 * rate  # both the closed and the salvaged seconds
