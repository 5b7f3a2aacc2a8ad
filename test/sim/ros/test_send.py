"""`tail-beam send` as a user runs it: the installed command as a subprocess, against a real
sim_node spun in this process (in this run's own ROS_DOMAIN_ID, inherited by the child):
every command of a YAML list simulated, refusals reported, bad input refused with nothing
sent, and a clear timeout when no simulator is there."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from rclpy.parameter import Parameter
from rosprobe import Probe, ros_context, spin_for, spin_until
from std_msgs.msg import String

from tail_beam_sim import topics
from tail_beam_sim.config import default_config_dir

pytestmark = [pytest.mark.ros, pytest.mark.slow]
TAIL_BEAM = str(Path(sys.executable).parent / "tail-beam")
IMPACTS = default_config_dir() / "impacts.yaml"
RUN_LIMIT_S = 90.0  # longest a send may take here before the test gives up on it, s


def sim_node(context, namespace: str = ""):
    """A real sim_node at real time (its default pacing), in ``namespace``."""
    from tail_beam_sim.ros.sim_node import SimNode

    return SimNode(
        context=context,
        namespace=namespace,
        parameter_overrides=[Parameter("sim_node.realtime_factor", value=1.0)],
    )


def send(executor, *argv: str) -> tuple[int, str, str, float]:
    """Run `tail-beam send ARGV` while spinning this process's nodes; (exit status, stdout,
    stderr, wall time s)."""
    start = time.monotonic()
    proc = subprocess.Popen(
        [TAIL_BEAM, "send", *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        finished = spin_until(executor, lambda: proc.poll() is not None, timeout_s=RUN_LIMIT_S)
    finally:
        if proc.poll() is None:
            proc.kill()
    out, err = proc.communicate()
    assert finished, f"tail-beam send still running after {RUN_LIMIT_S:g} s: {err}"
    return proc.returncode, out, err, time.monotonic() - start


def test_yaml_list_is_simulated_and_each_truth_printed():
    """`send --file config/impacts.yaml --wait-truth` to a support's namespace: sim_node takes
    all four commands, and one impact_truth per command comes back on stdout with its impact_id
    and the commanded values."""
    listed = yaml.safe_load(IMPACTS.read_text())["impacts"]
    with ros_context() as (context, executor):
        sim = sim_node(context, "/support_07")
        executor.add_node(sim)
        code, out, err, _ = send(
            executor, "--file", str(IMPACTS), "--namespace", "support_07", "--wait-truth"
        )
        assert code == 0, err
        assert (
            sim.commands.received == 4 and sim.commands.queued == 4 and sim.commands.refused == 0
        )
    truths = [json.loads(line) for line in out.splitlines()]
    assert [t["impact_id"] for t in truths] == [item["impact_id"] for item in listed]
    for truth, item in zip(truths, listed):
        assert truth["material"] == item["material"]
        assert truth["radius_m"] == item["radius_m"] and truth["position_m"] == item["position_m"]
        assert truth["contact_end_stamp"] > truth["contact_start_stamp"] > 0.0
    assert "4 command(s) simulated by /support_07/tail_beam_sim" in err


def test_one_command_from_options_then_its_id_again_is_reported_refused():
    """A command given as options is acknowledged and simulated; sent again, sim_node refuses
    the used impact_id and `--wait-truth` names it, exit 5."""
    with ros_context() as (context, executor):
        sim = sim_node(context)
        probe = Probe(context, {topics.IMPACT_TRUTH: String})
        executor.add_node(sim)
        executor.add_node(probe)
        option = [
            "--material",
            "marble",
            "--radius-m",
            "0.04",
            "--impact-speed-mps",
            "6.5",
            "--position-m",
            "0.8",
            "--impact-id",
            "opt-1",
        ]
        code, out, err, _ = send(executor, *option)
        assert code == 0, err
        assert out == "" and "1 command(s) acknowledged by /tail_beam_sim" in err
        assert spin_until(executor, lambda: len(probe.messages[topics.IMPACT_TRUTH]) == 1)
        (truth,) = probe.json(topics.IMPACT_TRUTH)
        assert (
            truth["impact_id"] == "opt-1"
            and truth["material"] == "marble"
            and truth["impact_speed_mps"] == 6.5
        )
        assert truth["drop_height_m"] is None  # a commanded speed, not a height

        code, out, err, _ = send(executor, *option, "--wait-truth", "--truth-timeout-s", "20")
        assert code == 5, err
        assert out == ""
        assert sim.commands.refused == 1 and sim.commands.queued == 1
        *refusals, summary = err.strip().splitlines()
        assert (
            len(refusals) == 1
            and "impact_id 'opt-1' refused by the simulator: "
            "impact_cmd rejected: impact_id = 'opt-1'"
            in refusals[0]
        )
        assert summary == "tail-beam send: error: 1 of 1 refused: impact_id 'opt-1'"


@pytest.mark.parametrize(
    "argv, field",
    [
        (
            [
                "--material",
                "coal",
                "--radius-m",
                "-0.02",
                "--drop-height-m",
                "3",
                "--position-m",
                "1.0",
            ],
            "radius_m = '-0.02': must be in [0.001, 0.5] m",
        ),
        (
            [
                "--material",
                "granite",
                "--radius-m",
                "0.02",
                "--drop-height-m",
                "3",
                "--position-m",
                "1.0",
            ],
            "material = 'granite': must be one of",
        ),
        (
            ["--material", "coal", "--radius-m", "0.02", "--position-m", "1.0"],
            "drop_height_m/impact_speed_mps",
        ),
        (["--file", "BAD_LIST"], "impacts[1].position_m = 3.0: must be"),
        (["--file", "BAD_LIST", "--material", "coal"], "--file"),
        (
            ["--file", str(IMPACTS), "--timeout-s", "-1"],
            "--timeout-s = '-1': must be in (0, 86400] s",
        ),
        (["--file", str(IMPACTS), "--namespace", "support 07"], "--namespace"),
    ],
)
def test_bad_input_exits_2_naming_the_field_with_nothing_sent(tmp_path, argv, field):
    """A bad field (options or an item of the YAML list), a bad timeout or namespace: exit 2
    with one line naming it, before any waiting, and sim_node receives nothing."""
    bad = tmp_path / "bad.yaml"
    listed = yaml.safe_load(IMPACTS.read_text())["impacts"]
    listed[1]["position_m"] = 3.0  # off the 1.6 m plate
    bad.write_text(yaml.safe_dump({"impacts": listed}))
    argv = [str(bad) if a == "BAD_LIST" else a for a in argv]
    with ros_context() as (context, executor):
        sim = sim_node(context)
        listener = Probe(context, {topics.IMPACT_CMD: String}, name="listener")
        executor.add_node(sim)
        executor.add_node(listener)
        code, out, err, elapsed = send(
            executor, *argv, *([] if "--timeout-s" in argv else ["--timeout-s", "30"])
        )
        spin_for(executor, 0.5)
        assert sim.commands.received == 0 and listener.messages[topics.IMPACT_CMD] == []
    assert code == 2
    assert (
        out == ""
        and len(err.strip().splitlines()) == 1
        and err.startswith("tail-beam send: error: ")
    )
    assert field in err
    assert elapsed < 30.0  # refused before waiting for the simulator, not after the timeout


def test_no_simulator_times_out_with_one_line():
    """With no simulator (only a node that listens on impact_cmd), `send --timeout-s 5` exits 4
    after the timeout, not much later, with one line naming the topic, the timeout and the
    listener that is no simulator. (5 s: with the whole suite on 2 cores, discovering the
    listener took the send process more than 3 s once.)"""
    with ros_context() as (context, executor):
        listener = Probe(context, {topics.IMPACT_CMD: String}, name="listener")
        executor.add_node(listener)
        code, out, err, elapsed = send(executor, "--file", str(IMPACTS), "--timeout-s", "5")
        assert listener.messages[topics.IMPACT_CMD] == []
    assert code == 4
    assert out == "" and len(err.strip().splitlines()) == 1
    assert err.startswith(
        "tail-beam send: error: no simulator subscribed to /impact_cmd within 5 s"
    )
    assert "/listener subscribes to it but publishes no impact_truth" in err
    # The wait is the timeout; the rest is starting Python and rclpy (about 1.5 s here, 3 s
    # loaded).
    assert 5.0 <= elapsed < 5.0 + 8.0


def test_a_foreign_publisher_on_impact_truth_is_ignored_whatever_it_sends():
    """While `send --wait-truth` waits, another participant publishes on impact_truth text that
    is no truth (not JSON, a list, nested 100 000 deep): send ignores it and prints only its own
    impact's truth, exit 0, no traceback."""
    junk = ["not json", "[1, 2]", "[" * 100_000]
    with ros_context() as (context, executor):
        sim = sim_node(context, "/support_07")
        other = Probe(context, {}, namespace="/support_07", name="foreign_truths")
        pub = other.create_publisher(String, topics.IMPACT_TRUTH, 10)
        sent = []

        def publish_junk() -> None:
            pub.publish(String(data=junk[len(sent) % len(junk)]))
            sent.append(1)

        other.create_timer(0.05, publish_junk)
        executor.add_node(sim)
        executor.add_node(other)
        code, out, err, _ = send(
            executor,
            "--material",
            "coal",
            "--radius-m",
            "0.05",
            "--drop-height-m",
            "1.5",
            "--position-m",
            "1.0",
            "--impact-id",
            "mine",
            "--namespace",
            "support_07",
            "--wait-truth",
        )
    assert code == 0 and "Traceback" not in err, err
    assert len(sent) >= len(junk)
    assert [json.loads(line)["impact_id"] for line in out.splitlines()] == ["mine"]
