"""The installed executables as subprocesses (what ``ros2 run`` starts), in this run's own
ROS_DOMAIN_ID (set by conftest, inherited by the children): record (closed by SIGTERM), replay,
identify offline; a recorder killed with SIGKILL; two supports in one domain."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from rosprobe import Probe, Processes, ros_context, spin_for, spin_until
from std_msgs.msg import String

from tail_beam_id.cli.identify_cmd import identify_bag
from tail_beam_id.methods import available_methods
from tail_beam_id.stream.label import Label, match, match_tolerance_s
from tail_beam_sim import topics
from tail_beam_sim.bags.read import raw_messages, read_sensors
from tail_beam_sim.bags.write import PARTIAL_DIR
from tail_beam_sim.config import load_parameters

pytestmark = [pytest.mark.ros, pytest.mark.slow]
BIN = Path(sys.executable).parent


def method() -> str:
    """The configured identification method if registered, else the first registered one."""
    configured = load_parameters()["identification"]["method"]
    return configured if configured in available_methods() else available_methods()[0]


@pytest.fixture
def procs(tmp_path):
    manager = Processes(tmp_path)
    yield manager
    manager.close()


def short_scenario(count: int, *extra: str) -> list[str]:
    return [
        "scenario.source:=generated",
        f"scenario.count:={count}",
        "sim_node.exit_after_idle_s:=0.5",
        *extra,
    ]


def assert_same_labels(got: list[Label], expected: list[Label]) -> None:
    """Same impacts, labels, method and confidences (docs/interface.md: live and offline agree):
    id_node hands its identifier the streams in stamp order (tail_beam_id/ros/arrival), so its
    decisions cannot depend on how the middleware interleaved them."""
    assert [g.decision() for g in got] == [e.decision() for e in expected]


def test_record_then_replay_into_id_node_gives_the_offline_labels(tmp_path, procs):
    """Real processes: the recorded live labels, the offline labels of the recorded bag and a
    fresh id_node's labels on its replay all agree, and no sample was lost. The recorder writes
    sqlite3 and is stopped by SIGTERM: that closes a valid bag with its metadata, holding every
    impact's truth and rebound (SIGINT and mcap: test_slow_readers, test_soak_short)."""
    bag = tmp_path / "live"
    with ros_context() as (context, executor):
        watcher = Probe(context, {topics.LABEL: String}, name="watcher")
        executor.add_node(watcher)
        recorder = procs.start(
            "bag_recorder", f"recorder.bag_path:={bag}", "recorder.storage:=sqlite3"
        )
        ident = procs.start("id_node", f"method:={method()}", "id_node.flush_after_idle_s:=0.5")
        # The id_node that will hear the replay, started now (its start-up beside the others'),
        # under a namespace of its own: it hears nothing of the live run.
        ident2 = procs.start(
            "id_node", f"method:={method()}", "id_node.flush_after_idle_s:=0.5", ns="/replayed"
        )
        label_topic = watcher.resolve_topic_name(topics.LABEL)
        assert spin_until(
            executor,
            lambda: (
                watcher.count_publishers(label_topic) >= 1
                and watcher.count_subscribers(label_topic) >= 2
            ),
        )
        spin_for(executor, 1.0)  # the label topic, id_node -> recorder, is up
        sim = procs.start("sim_node", *short_scenario(4, "sim_node.wait_for_subscribers:=2"))
        assert (
            spin_until(executor, lambda: sim.poll() is not None, timeout_s=60)
            and sim.returncode == 0
        )
        # id_node may still work through its backlog on a busy machine: wait until its labels stop.
        spin_until(executor, lambda: len(watcher.messages[topics.LABEL]) >= 4, timeout_s=30)
        settled = -1
        while settled != len(watcher.messages[topics.LABEL]):
            settled = len(watcher.messages[topics.LABEL])
            spin_for(executor, 2.0)
    assert procs.stop(ident) == 0
    assert procs.stop(recorder, signal.SIGTERM) == 0
    assert not (bag / PARTIAL_DIR).exists()
    assert sorted(p.suffix for p in bag.iterdir() if p.is_file()) == [".db3"] * (
        len(list(bag.glob("*.db3")))
    ) + [".yaml"]
    recorded = read_sensors(bag)
    offline = identify_bag(
        str(bag), method(), calibrate=False
    )  # id_node does not calibrate by default
    live = [Label.from_dict(obj) for obj in recorded.json_topics[topics.LABEL]]
    assert len(recorded.json_topics[topics.IMPACT_TRUTH]) == 4 and len(recorded.rebounds) == 4
    assert len(offline) >= 1
    assert_same_labels(live, offline)
    # Every sample from stamp 0 on reached the recorder: consecutive stamps, none missing.
    rate = load_parameters()["sensors"]["pressure_rate_hz"]
    assert recorded.pressure_stamp_s[0] == 0.0
    np.testing.assert_allclose(np.diff(recorded.pressure_stamp_s), 1.0 / rate, atol=1e-9)

    # Replay the sensor topics (not the recorded labels) into the fresh id_node.
    with ros_context() as (context, executor):
        probe = Probe(context, {topics.LABEL: String}, namespace="/replayed")
        executor.add_node(probe)
        # Start the replay once the probe has discovered the new id_node's label publisher.
        assert spin_until(
            executor,
            lambda: probe.count_publishers(probe.resolve_topic_name(topics.LABEL)) >= 1,
            timeout_s=30,
        )
        spin_for(executor, 0.5)
        replay = procs.start(
            "bag_replay",
            f"replay.bag_path:={bag}",
            "replay.rate:=1.0",
            "replay.wait_for_subscribers:=1",
            "replay.topics:=[jack_pressure, imu, vibration, rebound_velocity]",
            ns="/replayed",
        )
        assert (
            spin_until(executor, lambda: replay.poll() is not None, timeout_s=60)
            and replay.returncode == 0
        )
        spin_until(
            executor, lambda: len(probe.messages[topics.LABEL]) >= len(offline), timeout_s=30
        )
        replayed = probe.labels(topics.LABEL)
        procs.stop(ident2)
    assert len(replayed) == len(offline), (
        f"id_node on the replay said: {procs.log(ident2)[-2000:]}"
    )
    assert_same_labels(replayed, offline)


def test_recorder_killed_with_sigkill_leaves_all_but_the_last_seconds_readable(tmp_path, procs):
    """A recorder killed by SIGKILL loses at most its last 2 s; what is left reads without
    holes, and `tail-beam bag repair` completes it."""
    bag = tmp_path / "killed"
    recorder = procs.start("bag_recorder", f"recorder.bag_path:={bag}", "recorder.segment_s:=0.5")
    sim = procs.start("sim_node", *short_scenario(30, "sim_node.wait_for_subscribers:=1"))
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and not (bag.exists() and any(bag.glob("*.mcap"))):
        time.sleep(0.1)  # until the first segment is closed: the data flows
    time.sleep(3.5)  # a few more segments of real-time data
    killed_ns = time.time_ns()
    recorder.kill()
    recorder.wait()
    procs.stop(sim)
    log_times = [raw.log_time_ns for raw in raw_messages(bag, [topics.JACK_PRESSURE])]
    assert killed_ns - log_times[-1] < 2e9, "more than the last 2 s was lost"
    data = read_sensors(bag, required=(topics.JACK_PRESSURE, topics.IMU))
    rate = load_parameters()["sensors"]["pressure_rate_hz"]
    assert data.pressure_stamp_s.size > 1.0 * rate  # seconds of data, not a stub
    np.testing.assert_allclose(
        np.diff(data.pressure_stamp_s), 1.0 / rate, atol=1e-9
    )  # no hole in what is there
    result = subprocess.run(
        [str(BIN / "tail-beam"), "bag", "repair", str(bag)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stderr
    repaired = read_sensors(bag, required=(topics.JACK_PRESSURE,))
    assert repaired.pressure_stamp_s.size >= data.pressure_stamp_s.size and not repaired.partial


def test_two_supports_in_one_domain_do_not_mix(procs):
    # The first impacts come 2 s into each stream: the sim_nodes wait only for their id_node, and
    # on a loaded machine the probe may take a second or two to be discovered.
    """Two supports under their own namespaces in one domain each get only their own truths and
    labels."""
    supports = {"/support_01": ("2.5", 2), "/support_02": ("2.8", 3)}
    watched = {
        f"{ns}/{topic}": String for ns in supports for topic in (topics.IMPACT_TRUTH, topics.LABEL)
    }
    with ros_context() as (context, executor):
        probe = Probe(context, watched)
        executor.add_node(probe)
        for ns, (start, count) in supports.items():
            procs.start("id_node", f"method:={method()}", "id_node.flush_after_idle_s:=0.5", ns=ns)
            procs.start(
                "sim_node",
                *short_scenario(
                    count, f"scenario.start_s:={start}", "sim_node.wait_for_subscribers:=1"
                ),
                ns=ns,
            )
        total = sum(count for _, count in supports.values())
        assert spin_until(
            executor,
            lambda: (
                sum(len(probe.messages[f"{ns}/{topics.IMPACT_TRUTH}"]) for ns in supports) == total
            ),
            60,
        )
        spin_until(
            executor,
            lambda: sum(len(probe.messages[f"{ns}/{topics.LABEL}"]) for ns in supports) >= total,
            15,
        )
        for ns, (start, count) in supports.items():
            truths = probe.json(f"{ns}/{topics.IMPACT_TRUTH}")
            assert len(truths) == count
            assert truths[0]["contact_start_stamp"] == pytest.approx(float(start))
            labels = probe.labels(f"{ns}/{topics.LABEL}")
            assert labels, f"no label in {ns}"
            # Every label is of this support's own impacts (the other's are >= 0.2 s away).
            extra = match(
                truths, labels, match_tolerance_s(load_parameters()["identification"])
            ).extra
            assert not extra, (
                ns,
                [labels[j].impact_stamp_s for j in extra],
                [t["contact_start_stamp"] for t in truths],
            )
