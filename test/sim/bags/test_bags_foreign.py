"""Bags of other supports, recorded by another recorder or simulator, driven as a user would
with `tail-beam identify` (the command) and `calibrate` (its main, in this process): a topic
recorded twice, a support without the camera or without the jack transducer and IMU, two
supports in one bag. Each is labelled (or calibrated) as id_node would, exit 0 and no
traceback, or refused in one line naming what is missing."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from id_helpers import impact

from tail_beam_sim import topics
from tail_beam_sim.bags import records as bagio
from tail_beam_sim.bags.write import SegmentedBagWriter

BIN = Path(sys.executable).parent


def run(*args: str, timeout_s: float = 120) -> subprocess.CompletedProcess:
    """`tail-beam` as a user runs it."""
    return subprocess.run(
        [str(BIN / "tail-beam"), *args], capture_output=True, text=True, timeout=timeout_s
    )


def run_here(capsys, *args: str) -> subprocess.CompletedProcess:
    """`tail-beam ARGS` run in this process (tail_beam_sim.cli.main, what the command calls),
    its status and output as run() gives them: for `calibrate`, whose command is run as one
    elsewhere (test_calibration); a traceback would be an exception here."""
    from tail_beam_sim.cli import main

    capsys.readouterr()
    code = main(list(args))
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess(["tail-beam", *args], code, out, err)


def labels_of(result: subprocess.CompletedProcess) -> list[dict]:
    assert result.returncode == 0 and "Traceback" not in result.stderr, (
        result.returncode,
        result.stderr[-3000:],
    )
    return [json.loads(line) for line in result.stdout.splitlines() if line.strip()]


@pytest.fixture(scope="module")
def sandstone_records(params):
    """One 40 mm sandstone impact's serialized records (topic, log ns, CDR): pressure, IMU,
    accelerometer, rebound and truth."""
    result = impact(params, material="sandstone", radius_m=0.04, seed=31)
    return [
        (topic, ns, bytes(bagio.TYPESTORE.serialize_cdr(msg, topics.MSG_TYPES[topic])))
        for topic, ns, msg in bagio.result_records(result)
    ]


def write(path: Path, records, namespace: str = "/") -> Path:
    """The records as a bag of the support ``namespace`` (every contract topic listed, as the
    recorder does)."""
    name = {topic: topics.qualified(namespace, topic) for topic in topics.MSG_TYPES}
    writer = SegmentedBagWriter(path, msg_types={name[t]: m for t, m in topics.MSG_TYPES.items()})
    for topic, ns, data in sorted(records, key=lambda r: r[1]):
        writer.write(name[topic], ns, data)
    writer.close()
    return path


def test_a_bag_holding_every_sample_twice_is_identified_and_calibrated(
    tmp_path, sandstone_records, capsys
):
    """Every pressure and IMU message recorded twice (two recorders on one topic): identify and
    calibrate go on, exit 0, say on stderr how many repeated samples they left out, and the
    labels are those of the plain bag."""
    plain = write(tmp_path / "plain", sandstone_records)
    twice = sandstone_records + [
        r for r in sandstone_records if r[0] in (topics.JACK_PRESSURE, topics.IMU)
    ]
    doubled = write(tmp_path / "doubled", twice)
    expected = labels_of(run("identify", "--no-calibrate", str(plain)))
    result = run("identify", "--no-calibrate", str(doubled))
    got = labels_of(result)
    assert [(x["impact_stamp"], x["label"], x["confidence"]) for x in got] == [
        (x["impact_stamp"], x["label"], x["confidence"]) for x in expected
    ]
    assert "imu: " in result.stderr and "at a stamp already read left out" in result.stderr
    calibrated = run_here(capsys, "calibrate", str(doubled))
    assert calibrated.returncode == 0 and "Traceback" not in calibrated.stderr, calibrated.stderr[
        -3000:
    ]


@pytest.mark.parametrize(
    "kept, signals",
    [
        ((topics.JACK_PRESSURE, topics.IMU, topics.VIBRATION), ["jack_pressure", "vibration"]),
        ((topics.VIBRATION, topics.REBOUND_VELOCITY), ["vibration", "rebound_velocity"]),
    ],
    ids=["no-camera", "accelerometer-and-camera"],
)
def test_a_support_without_some_sensors_is_identified(tmp_path, sandstone_records, kept, signals):
    """A bag without the camera, or with only the accelerometer and the camera, is labelled
    from what it has, as id_node labels that support live (the label's signals say which)."""
    bag = write(
        tmp_path / "bag", [r for r in sandstone_records if r[0] in kept + (topics.IMPACT_TRUTH,)]
    )
    labels = labels_of(run("identify", str(bag)))
    assert [x["signals"] for x in labels] == [signals]
    assert labels[0]["label"] == "gangue"


def test_calibrate_needs_no_camera(tmp_path, sandstone_records, capsys):
    """calibrate reads the jack pressure and the IMU only: a bag without rebound_velocity is
    calibrated."""
    bag = write(
        tmp_path / "bag", [r for r in sandstone_records if r[0] != topics.REBOUND_VELOCITY]
    )
    result = run_here(capsys, "calibrate", str(bag))
    assert result.returncode == 0 and "Traceback" not in result.stderr, result.stderr[-3000:]
    assert "imu_mount_sign" in result.stdout


def test_a_bag_without_any_sensor_names_what_it_has(tmp_path, sandstone_records):
    """A bag with the truth only (every contract topic listed, none of the sensors with a
    message): one line, exit 2, naming the sensor topics wanted and only the topics that hold
    messages (a connection without messages is not listed as present)."""
    bag = write(tmp_path / "bag", [r for r in sandstone_records if r[0] == topics.IMPACT_TRUTH])
    for verb in ("identify", "calibrate"):
        result = run(verb, str(bag))
        assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
        lines = [line for line in result.stderr.splitlines() if line.strip()]
        assert (
            len(lines) == 1
            and "holds no messages on any of" in lines[0]
            and lines[0].endswith("it has: impact_truth")
        ), lines


def test_calibrate_chooses_one_support_of_several(tmp_path, sandstone_records, capsys):
    """A bag of two supports: calibrate, like identify, asks for --namespace and takes it."""
    bag = tmp_path / "bag"
    names = {
        f"{ns}/{t}": m
        for ns in ("/support_01", "/support_02")
        for t, m in topics.MSG_TYPES.items()
    }
    writer = SegmentedBagWriter(bag, msg_types=names)
    for topic, ns, data in sorted(sandstone_records, key=lambda r: r[1]):
        for support in ("/support_01", "/support_02"):
            writer.write(f"{support}/{topic}", ns, data)
    writer.close()
    refused = run_here(capsys, "calibrate", str(bag))
    assert (
        refused.returncode == 2
        and "--namespace" in refused.stderr
        and "Traceback" not in refused.stderr
    )
    chosen = run_here(capsys, "calibrate", str(bag), "--namespace", "/support_02")
    assert chosen.returncode == 0 and "imu_mount_sign" in chosen.stdout, chosen.stderr[-3000:]


def test_a_new_time_base_in_the_bag_is_said_and_each_run_taken_alone(
    tmp_path, sandstone_records, capsys
):
    """A bag holding two runs whose stamps both start at 0 (a simulator restarted while the
    recorder ran on): identify and calibrate say so on stderr, naming the topic, how far its
    stamps went back and the log time where they did, and take each run alone, as id_node
    starts afresh at a time jump: the sandstone impact of each run is labelled once, gangue, at
    its own stamp; calibrate says which run it used."""

    def later(records, shift_s):
        """The records with every header stamp and log time ``shift_s`` later."""
        out = []
        for topic, ns, data in records:
            msg = bagio.TYPESTORE.deserialize_cdr(data, topics.MSG_TYPES[topic])
            if hasattr(msg, "header"):
                stamp = topics.stamp_ns(
                    msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 + shift_s
                )
                msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            out.append(
                (
                    topic,
                    ns + int(shift_s * 1e9),
                    bytes(bagio.TYPESTORE.serialize_cdr(msg, topics.MSG_TYPES[topic])),
                )
            )
        return out

    first = later(sandstone_records, 3.0)  # the first run ran 3 s before the impact's window
    second = [
        (topic, ns + 4_000_000_000, data) for topic, ns, data in sandstone_records
    ]  # restarted: stamps from 0 again
    bag = write(tmp_path / "bag", first + second)
    for verb in ("identify", "calibrate"):
        result = run(verb, str(bag)) if verb == "identify" else run_here(capsys, verb, str(bag))
        assert result.returncode == 0 and "Traceback" not in result.stderr, result.stderr[-3000:]
        assert (
            "imu: stamps go back" in result.stderr and "2 runs, each taken alone" in result.stderr
        ), result.stderr
        if verb == "identify":
            labels = [json.loads(line) for line in result.stdout.splitlines()]
            assert [label["label"] for label in labels] == ["gangue", "gangue"], labels
            assert labels[0]["impact_stamp"] - labels[1]["impact_stamp"] == pytest.approx(
                3.0, abs=1e-3
            )
        else:
            assert "calibrated on run" in result.stderr


def _reindexed(records, index_of_block):
    """The records with each vibration block's index words set to ``index_of_block(k)`` (block
    k)."""
    out, k = [], 0
    for topic, ns, data in records:
        if topic == topics.VIBRATION:
            msg = bagio.TYPESTORE.deserialize_cdr(data, topics.MSG_TYPES[topic])
            index = index_of_block(k)
            msg.angle_min, msg.angle_max = float(index >> 24), float(index & (2**24 - 1))
            data = bytes(bagio.TYPESTORE.serialize_cdr(msg, topics.MSG_TYPES[topic]))
            k += 1
        out.append((topic, ns, data))
    return out


@pytest.mark.parametrize(
    ("name", "index_of_block"),
    [("every block index 0", lambda k: 0), ("a block count", lambda k: k)],
)
def test_a_bag_whose_block_index_does_not_count_samples_is_refused_by_name(
    tmp_path, sandstone_records, name, index_of_block, capsys
):
    """A recorder or simulator that does not count samples in the blocks' index words (every
    block index 0, or the block's number): identify and calibrate refuse the bag in one line
    naming the index fields (taken as they are, all blocks but one would be dropped as
    repeats); the same blocks rightly indexed, and every block recorded twice, read as they
    are."""
    bad = write(tmp_path / "bad", _reindexed(sandstone_records, index_of_block))
    for command in ("identify", "calibrate"):
        result = (
            run(command, str(bad))
            if command == "identify"
            else run_here(capsys, command, str(bad))
        )
        assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr[-2000:]
        assert (
            "vibration.angle_min/angle_max" in result.stderr
            and "running sample index" in result.stderr
        )
    twice = [r for r in sandstone_records] + [
        r for r in sandstone_records if r[0] == topics.VIBRATION
    ]
    labels = labels_of(run("identify", "--no-calibrate", str(write(tmp_path / "twice", twice))))
    assert len(labels) == 1 and "vibration" in labels[0]["signals"]
