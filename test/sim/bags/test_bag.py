"""Segmented bag writing, reading with clear errors, repair; read back by two readers."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from bag_helpers import RATE_HZ, records, write_segments
from rosbags.highlevel import AnyReader

from tail_beam_sim import topics
from tail_beam_sim.bags import records as bagio
from tail_beam_sim.bags.read import read_sensors
from tail_beam_sim.bags.write import PARTIAL_DIR, repair
from tail_beam_sim.errors import InputError

TAIL_BEAM = str(Path(sys.executable).parent / "tail-beam")  # the installed console script


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_segments_make_one_bag_that_any_reader_reads_whole(tmp_path, storage):
    """Three closed segments read as one bag, by rosbags' AnyReader and our reader: every
    message once, in order, with the contract's topic types."""
    data = records(300)
    write_segments(tmp_path / "bag", [data[:200], data[200:450], data[450:]], storage)
    assert not (tmp_path / "bag" / PARTIAL_DIR).exists()
    with AnyReader([tmp_path / "bag"], default_typestore=bagio.TYPESTORE) as reader:
        got = [(c.topic, ns) for c, ns, _ in reader.messages()]
        assert reader.message_count == 600
        assert {c.topic: c.msgtype for c in reader.connections} == topics.MSG_TYPES
    assert got == [(t, ns) for t, ns, _ in data]
    sensors = read_sensors(tmp_path / "bag", required=(topics.JACK_PRESSURE, topics.IMU))
    np.testing.assert_array_equal(sensors.pressure_pa, 20e6 + np.arange(300))
    np.testing.assert_allclose(np.diff(sensors.imu_stamp_s), 1.0 / RATE_HZ)


def test_an_independent_mcap_reader_decodes_every_segment(tmp_path):
    """The mcap library's own reader, not rosbags, decodes every pressure value across both
    segments."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    data = records(100)
    write_segments(tmp_path / "bag", [data[:120], data[120:]])
    values = []
    for path in sorted((tmp_path / "bag").glob("*.mcap")):
        with path.open("rb") as stream:
            for _, channel, _, msg in make_reader(
                stream, decoder_factories=[DecoderFactory()]
            ).iter_decoded_messages():
                if channel.topic == topics.JACK_PRESSURE:
                    values.append(msg.fluid_pressure)
    assert values == list(20e6 + np.arange(100))


def test_a_killed_writer_leaves_the_closed_segments_readable_and_repair_adds_the_rest(tmp_path):
    """A writer that dies mid-segment leaves its closed segments readable (flagged partial);
    repair adds what the open one salvaged, keeping the rest as it was."""
    data = records(2000)
    bag = tmp_path / "bag"
    write_segments(bag, [data[:1000], data[1000:2000], data[2000:]], close=False)
    # The process dies here, with the third segment open (whatever rosbags has flushed of it).
    closed = read_sensors(bag, required=(topics.JACK_PRESSURE,))
    assert closed.partial
    assert closed.pressure_stamp_s.size == 1000  # both closed segments, nothing else
    salvaged = repair(bag).salvaged_messages
    after = read_sensors(bag, required=(topics.JACK_PRESSURE,))
    assert not after.partial
    assert after.pressure_stamp_s.size + after.imu_stamp_s.size == 2000 + salvaged
    np.testing.assert_array_equal(after.pressure_stamp_s[:1000], closed.pressure_stamp_s)


def test_repair_rebuilds_a_bag_whose_metadata_is_missing(tmp_path):
    """A bag without metadata.yaml is refused with a hint to repair; repair rebuilds it and
    every message reads back."""
    data = records(100)
    write_segments(tmp_path / "bag", [data])
    (tmp_path / "bag" / "metadata.yaml").unlink()
    with pytest.raises(InputError, match="bag repair"):
        read_sensors(tmp_path / "bag")
    report = repair(tmp_path / "bag")
    assert (report.rewritten, report.salvaged_messages, report.lost) == (1, 200, [])
    assert read_sensors(tmp_path / "bag", required=(topics.IMU,)).imu_stamp_s.size == 100


def bag_without_messages(path):
    write_segments(path, [])


def truncated_bag(path):
    write_segments(path, [records(3000)])
    storage = next(path.glob("*.mcap"))
    storage.write_bytes(storage.read_bytes()[: storage.stat().st_size // 2])


def pressure_only_bag(path):
    write_segments(path, [[r for r in records(50) if r[0] == topics.JACK_PRESSURE]])


@pytest.mark.parametrize(
    "make, message",
    [
        (None, "does not exist"),
        (lambda p: p.mkdir(), "not a rosbag2 bag"),
        (lambda p: p.write_text("x"), "not a rosbag2 bag directory"),
        (bag_without_messages, "holds no messages"),
        (truncated_bag, "truncated or damaged"),
    ],
)
def test_a_bad_bag_is_one_clear_error(tmp_path, make, message):
    """Each kind of bad bag is an InputError on field 'bag' saying what is wrong, and
    `tail-beam identify` on it exits 2 with that one line."""
    path = tmp_path / "bag"
    if make is not None:
        make(path)
    with pytest.raises(InputError, match=message) as info:
        read_sensors(path)
    assert info.value.field == "bag"
    result = subprocess.run(
        [TAIL_BEAM, "identify", str(path)], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert (
        len(lines) == 1 and message.split("'")[0] in lines[0] and "Traceback" not in result.stderr
    )


def test_bag_info_lists_topics_and_counts(tmp_path):
    """`tail-beam bag info` prints the total and one row per topic with its message count."""
    write_segments(tmp_path / "bag", [records(40)])
    result = subprocess.run(
        [TAIL_BEAM, "bag", "info", str(tmp_path / "bag")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0
    assert "80 messages" in result.stdout
    rows = {line.split()[0]: int(line.split()[-1]) for line in result.stdout.splitlines()[1:]}
    assert rows == {topics.IMU: 40, topics.JACK_PRESSURE: 40}
    shutil.rmtree(tmp_path / "bag")


def test_a_pressure_only_bag_lacks_a_topic_for_read_sensors_but_is_identified(tmp_path):
    """read_sensors' default asks for the three sensor topics and names the one missing; `tail-beam
    identify` asks for any sensor topic (id_node labels a support with the jack transducer only),
    so it reads the pressure-only bag: exit 0, no traceback, any label decided from the
    pressure."""
    pressure_only_bag(tmp_path / "bag")
    with pytest.raises(InputError, match="lacks messages on topic 'imu'"):
        read_sensors(tmp_path / "bag")
    result = subprocess.run(
        [TAIL_BEAM, "identify", str(tmp_path / "bag")], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0 and "Traceback" not in result.stderr, result.stderr
    assert all(
        json.loads(line)["signals"] == ["jack_pressure"] for line in result.stdout.splitlines()
    )


def test_metadata_text_is_the_mapping_yaml_gives_whatever_the_file_names(tmp_path):
    """The hand-rendered file list of metadata.yaml parses back to the same mapping, for names
    YAML would misread unquoted (a colon, a leading dash, 'null', digits, quotes, non-ASCII),
    and a bag of many segments with such a name reads whole."""
    import yaml

    from tail_beam_sim.bags.write import empty_info, metadata_text

    info = empty_info("mcap")
    assert yaml.safe_load(metadata_text(info)) == {"rosbag2_bagfile_information": info}
    names = ["a: b", "it's", "null", "123", "- x", 'ü"\\', "#x", "on"]
    info["files"] = [
        {
            "path": f"{name}_{i:05d}.mcap",
            "starting_time": {"nanoseconds_since_epoch": i * 10**9},
            "duration": {"nanoseconds": 10**9 - i},
            "message_count": i,
        }
        for i, name in enumerate(names)
    ]
    info["relative_file_paths"] = [entry["path"] for entry in info["files"]]
    assert yaml.safe_load(metadata_text(info)) == {"rosbag2_bagfile_information": info}

    data = records(120)
    bag = tmp_path / "on: null"
    write_segments(bag, [data[i : i + 20] for i in range(0, 240, 20)])
    with AnyReader([bag], default_typestore=bagio.TYPESTORE) as reader:
        assert [(c.topic, ns) for c, ns, _ in reader.messages()] == [(t, ns) for t, ns, _ in data]
