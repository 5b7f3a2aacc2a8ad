"""Stray and hostile messages inside an otherwise good recording, driven as a user would with
`tail-beam identify` (the command), `calibrate` and `bag info` (their main, in this process): a
message no reader can take is set aside, counted and named in a warning, and the rest of the
recording is read and labelled as the clean recording is."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
from bag_helpers import serialized, shifted, string_record
from id_helpers import impact

from tail_beam_sim import topics
from tail_beam_sim.bags import records as bagio
from tail_beam_sim.bags.read import read_runs, read_sensors
from tail_beam_sim.bags.write import SegmentedBagWriter

BIN = Path(sys.executable).parent
HUGE_INT = "9" * 5000  # past Python's 4300-digit limit for int from text


def run(*args: str, timeout_s: float = 120) -> subprocess.CompletedProcess:
    """`tail-beam` as a user runs it."""
    return subprocess.run(
        [str(BIN / "tail-beam"), *args], capture_output=True, text=True, timeout=timeout_s
    )


def run_here(capsys, *args: str) -> tuple[int, str]:
    """`tail-beam ARGS` run in this process (tail_beam_sim.cli.main, what the command calls):
    its exit status and standard error. For the verbs whose output is only checked to be a
    success; a traceback would be an exception here."""
    from tail_beam_sim.cli import main

    capsys.readouterr()
    code = main(list(args))
    return code, capsys.readouterr().err


def labels_of(result: subprocess.CompletedProcess) -> list[dict]:
    """The labels a successful `tail-beam identify` printed."""
    assert result.returncode == 0 and "Traceback" not in result.stderr, (
        result.returncode,
        result.stderr[-3000:],
    )
    return [json.loads(line) for line in result.stdout.splitlines() if line.strip()]


def kept(labels: list[dict]) -> list[tuple]:
    """What a label decides (stamp to 0.1 ms, label), without wall-clock figures."""
    return [(round(label["impact_stamp"], 4), label["label"]) for label in labels]


def write(path: Path, records) -> Path:
    """Serialized records as a bag (every contract topic listed, as the recorder does), in the
    order given (log times as given)."""
    writer = SegmentedBagWriter(path)
    for topic, ns, data in records:
        writer.write(topic, ns, data)
    writer.close()
    return path


@pytest.fixture(scope="module")
def coal_records(params):
    """One 25 mm coal impact's serialized records 100 s into the simulation (pressure, IMU,
    accelerometer, rebound, truth), in log-time order."""
    result = impact(params, material="coal", radius_m=0.025, seed=7)
    records = shifted(serialized(bagio.result_records(result)), 100.0)
    return sorted(records, key=lambda r: r[1])


@pytest.fixture(scope="module")
def clean_labels(coal_records, tmp_path_factory):
    """What `identify --no-calibrate` says of the clean recording."""
    bag = write(tmp_path_factory.mktemp("clean") / "bag", coal_records)
    labels = kept(labels_of(run("identify", str(bag), "--no-calibrate")))
    assert [label for _, label in labels] == ["coal"]
    return labels


def test_an_integer_past_the_digit_limit_on_a_json_topic_costs_that_message(
    tmp_path, coal_records, clean_labels, capsys
):
    """A >4300-digit integer in an impact_cmd and an impact_truth: the two messages are set aside
    and named in a warning; identify and calibrate read the rest, exit 0, same labels."""
    stray = [
        string_record(topics.IMPACT_CMD, coal_records[0][1], '{"radius_m": %s}' % HUGE_INT),
        string_record(topics.IMPACT_TRUTH, coal_records[5][1], '{"id": %s}' % HUGE_INT),
        string_record(topics.IMPACT_TRUTH, coal_records[6][1], '{"label": "coal"}'),
    ]
    bag = write(tmp_path / "bag", sorted(coal_records + stray, key=lambda r: r[1]))
    data = read_sensors(bag)
    assert {"label": "coal"} in data.json_topics[topics.IMPACT_TRUTH]
    assert len(data.json_topics[topics.IMPACT_TRUTH]) == 2  # the clean one's, and the good one
    assert sum(data.set_aside.values()) == 2
    result = run("identify", str(bag), "--no-calibrate")
    assert kept(labels_of(result)) == clean_labels
    for name in (topics.IMPACT_CMD, topics.IMPACT_TRUTH):
        assert any(name in line and "set aside" in line for line in result.stderr.splitlines())
    code, err = run_here(capsys, "calibrate", str(bag))
    assert code == 0 and "set aside" in err, err


def old_events(log_ns: int, count: int = 50) -> list:
    """What a recorder started late receives from transient-local publishers at ``log_ns``:
    ``count`` rebounds and truths of impacts the simulator ran 20 to 90 s before."""
    out = []
    for k in range(count):
        stamp = 20.0 + 70.0 * k / count
        topic, _, msg = bagio.rebound_msg(stamp + 0.005, [0.0, 0.3, 5.9])
        out.append((topic, log_ns + 2 * k, serialized([(topic, 0, msg)])[0][2]))
        truth = {"impact_id": f"old-{k}", "label": "gangue", "contact_start_stamp": stamp}
        out.append(string_record(topics.IMPACT_TRUTH, log_ns + 2 * k + 1, json.dumps(truth)))
    return out


def test_events_from_before_a_late_recorder_started_are_set_aside_not_a_new_run(
    tmp_path, coal_records, clean_labels
):
    """A recorder started while the simulator ran: 50 rebounds and 50 truths stamped 20 to 90 s,
    delivered after the first sensor samples and the live impact's rebound, are set aside and
    counted (not 'stamps go back', not a second run); the live impact is labelled once, as in
    the clean recording, and no camera-only label comes from before the sensor data."""
    rebound_log = next(ns for topic, ns, _ in coal_records if topic == topics.REBOUND_VELOCITY)
    bag = write(
        tmp_path / "bag", sorted(coal_records + old_events(rebound_log + 1), key=lambda r: r[1])
    )
    runs = read_runs(bag, required=(), any_of=(topics.JACK_PRESSURE,))
    assert len(runs) == 1 and not runs[0].time_jumps
    assert len(runs[0].rebounds) == 1 and len(runs[0].json_topics[topics.IMPACT_TRUTH]) == 1
    assert sum(runs[0].set_aside.values()) == 100
    result = run("identify", str(bag), "--no-calibrate")
    assert kept(labels_of(result)) == clean_labels
    assert "stamps go back" not in result.stderr
    said = [line for line in result.stderr.splitlines() if "set aside" in line]
    assert {line.split(": ")[1] for line in said} >= {"/ rebound_velocity", "/ impact_truth"}
    assert "50 message(s)" in said[0], said


def one_shifted(records, topic: str, shift_s: float, nth: int = 20) -> tuple:
    """The ``nth`` record of ``topic`` stamped ``shift_s`` later, logged where it was."""
    record = [r for r in records if r[0] == topic][nth]
    (_, _, data), log_ns = shifted([record], shift_s)[0], record[1]
    return topic, log_ns + 1, data


@pytest.mark.parametrize(
    "topic, shift_s",
    [
        (topics.JACK_PRESSURE, 1e5),
        (topics.VIBRATION, 1e6),
        (topics.IMU, 2.0**31 - 102.0),
    ],
    ids=["pressure+1e5s", "vibration+1e6s", "imu-at-2^31s"],
)
def test_one_message_stamped_far_ahead_is_set_aside_in_bounded_time(
    tmp_path, coal_records, clean_labels, topic, shift_s
):
    """One message stamped far ahead among the recording's (a clock gone wrong): set aside and
    counted as id_node does; identify ends well within 60 s, not in time that grows with the
    span of the stamps, with the clean labels."""
    stray = one_shifted(coal_records, topic, shift_s)
    bag = write(tmp_path / "bag", sorted(coal_records + [stray], key=lambda r: r[1]))
    started = time.monotonic()
    result = run("identify", str(bag), "--no-calibrate", timeout_s=60)
    assert time.monotonic() - started < 60
    assert kept(labels_of(result)) == clean_labels
    said = [line for line in result.stderr.splitlines() if "set aside" in line]
    assert len(said) == 1 and topic in said[0] and "ahead" in said[0], result.stderr


def test_epoch_stamped_data_after_sim_time_data_is_a_new_run_in_bounded_time(
    tmp_path, coal_records, clean_labels
):
    """The same support recorded on, stamped by the epoch clock (1.7e9 s) after sim-time data:
    every stream jumps ahead, a new time base, each run taken alone in bounded time; both
    impacts labelled coal, once."""
    epoch = shifted(coal_records, 1.7e9)
    bag = write(tmp_path / "bag", coal_records + epoch)
    started = time.monotonic()
    result = run("identify", str(bag), "--no-calibrate", timeout_s=60)
    assert time.monotonic() - started < 60
    labels = kept(labels_of(result))
    assert labels[0] == clean_labels[0] and [label for _, label in labels] == ["coal", "coal"]
    assert labels[1][0] - labels[0][0] == pytest.approx(1.7e9, abs=1e-3)
    assert "jump ahead" in result.stderr and "2 runs" in result.stderr, result.stderr


def test_replay_goes_straight_across_an_empty_stretch(params):
    """replay() given two impacts 1e6 s apart on every stream: it goes from the last chunk with
    data to the next, not through the 1e8 empty chunks between, and labels both impacts as
    each alone."""
    import dataclasses

    import numpy as np

    from tail_beam_id.stream.identifier import StreamIdentifier
    from tail_beam_id.stream.replay import replay
    from tail_beam_sim.physics.sensors import VibrationBlocks

    gap = 1e6
    r = impact(params, material="coal", radius_m=0.025, seed=7)
    pressure = dataclasses.replace(
        r.pressure,
        stamp_s=np.concatenate([r.pressure.stamp_s, r.pressure.stamp_s + gap]),
        pressure_pa=np.concatenate([r.pressure.pressure_pa] * 2),
    )
    imu = dataclasses.replace(
        r.imu,
        stamp_s=np.concatenate([r.imu.stamp_s, r.imu.stamp_s + gap]),
        angular_velocity_radps=np.concatenate([r.imu.angular_velocity_radps] * 2),
        linear_acceleration_mps2=np.concatenate([r.imu.linear_acceleration_mps2] * 2),
    )
    v = r.vibration
    later = dataclasses.replace(
        v, first_index=v.first_index + int(round(gap / v.period_s)), stamp_s=v.stamp_s + gap
    )
    rebounds = [r.rebound, dataclasses.replace(r.rebound, stamp_s=r.rebound.stamp_s + gap)]
    identifier = StreamIdentifier("statistical", params["identification"], params)
    started = time.monotonic()
    labels = replay(
        identifier, pressure, imu, rebounds, vibration=VibrationBlocks.concatenate([v, later])
    )
    assert time.monotonic() - started < 30
    alone = replay(
        StreamIdentifier("statistical", params["identification"], params),
        r.pressure,
        r.imu,
        [r.rebound],
        vibration=v,
    )
    assert [label.material for label in labels] == ["coal", "coal"]
    assert labels[0].impact_stamp_s == alone[0].impact_stamp_s
    assert labels[1].impact_stamp_s == pytest.approx(alone[0].impact_stamp_s + gap, abs=1e-6)


def vibration_variant(coal_records, case: str) -> list:
    """The coal recording with one vibration message spoiled as ``case`` says."""
    records = list(coal_records)
    at = [k for k, r in enumerate(records) if r[0] == topics.VIBRATION]
    vibration = topics.MSG_TYPES[topics.VIBRATION]

    def decode(k):
        return bagio.TYPESTORE.deserialize_cdr(records[k][2], vibration)

    def encode(msg):
        return bytes(bagio.TYPESTORE.serialize_cdr(msg, vibration))

    if case == "malformed":
        msg = decode(at[3])
        msg.angle_min = float("nan")
        records[at[3]] = (topics.VIBRATION, records[at[3]][1], encode(msg))
    elif case == "stale":  # block 2 sent again, stamped when block 8 was
        msg, later = decode(at[2]), decode(at[8])
        msg.header.stamp = later.header.stamp
        records.insert(at[8] + 1, (topics.VIBRATION, records[at[8]][1] + 1, encode(msg)))
    elif case == "duplicate-index":  # block 5 claims block 4's running index
        msg, before = decode(at[5]), decode(at[4])
        msg.angle_min, msg.angle_max = before.angle_min, before.angle_max
        records[at[5]] = (topics.VIBRATION, records[at[5]][1], encode(msg))
    elif case == "other-period":
        msg = decode(at[6])
        msg.time_increment *= 2.0
        records[at[6]] = (topics.VIBRATION, records[at[6]][1], encode(msg))
    elif case == "period-rounding":
        for k in at[::2]:
            msg = decode(k)
            msg.time_increment *= 1.0 + 1e-7
            records[k] = (topics.VIBRATION, records[k][1], encode(msg))
    return records


@pytest.mark.parametrize(
    "case", ["malformed", "stale", "duplicate-index", "other-period", "period-rounding"]
)
def test_one_bad_vibration_message_costs_that_message_not_the_recording(
    tmp_path, coal_records, clean_labels, case, capsys
):
    """One malformed, stale, duplicate-index or other-period vibration message: set aside,
    counted and named; identify (the clean labels), calibrate and bag info read the rest, exit
    0. Periods within 1e-6 relative are one period:
    nothing is set aside."""
    bag = write(tmp_path / "bag", vibration_variant(coal_records, case))
    data = read_sensors(bag)
    assert sum(data.set_aside.values()) == (0 if case == "period-rounding" else 1), data.set_aside
    result = run("identify", str(bag), "--no-calibrate")
    assert kept(labels_of(result)) == clean_labels
    said = [line for line in result.stderr.splitlines() if "set aside" in line]
    assert len(said) == (0 if case == "period-rounding" else 1), result.stderr
    assert all("vibration" in line for line in said)
    for verb in (["calibrate", str(bag)], ["bag", "info", str(bag)]):
        code, err = run_here(capsys, *verb)
        assert code == 0, err[-2000:]
