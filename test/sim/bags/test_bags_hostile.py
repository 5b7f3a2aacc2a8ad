"""Hostile and careless bags and paths, driven as a user would: bags cut anywhere, a bag without
the contract's topics, dangling and planted symbolic links, `bag repair` on what cannot be
repaired. A bad bag is reported in one line (exit 2), never half-read; nothing outside the named
paths is ever deleted or written through a link."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from bag_helpers import records, write_segments
from rosbags.rosbag2 import Writer

from tail_beam_sim import topics
from tail_beam_sim.bags.read import open_segments_note, raw_messages
from tail_beam_sim.bags.records import STORAGES, TYPESTORE
from tail_beam_sim.bags.write import PARTIAL_DIR, SegmentedBagWriter
from tail_beam_sim.errors import InputError

BIN = Path(sys.executable).parent
SUFFIX = {"mcap": ".mcap", "sqlite3": ".db3"}


def run(*args: str, timeout_s: float = 90) -> subprocess.CompletedProcess:
    """One installed executable, as a user runs it."""
    return subprocess.run(
        [str(BIN / args[0]), *args[1:]], capture_output=True, text=True, timeout=timeout_s
    )


def assert_one_line_error(result: subprocess.CompletedProcess, *needles: str) -> str:
    """Exit 2, no traceback, one line on stderr naming every needle."""
    assert result.returncode == 2, (result.returncode, result.stderr[-2000:])
    assert "Traceback" not in result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


def flushed_bag(path: Path, storage: str, flushes: int = 10, per_flush: int = 150) -> int:
    """A one-file bag written in ``flushes`` on-disk steps (mcap: one chunk each); returns the
    count."""
    data = records(flushes * per_flush)
    writer = SegmentedBagWriter(path, storage)
    for index, (topic, ns, raw) in enumerate(data):
        writer.write(topic, ns, raw)
        if (index + 1) % (2 * per_flush) == 0:
            writer.flush()
    writer.close()
    return len(data)


def storage_file(bag: Path) -> Path:
    return next(p for p in bag.iterdir() if p.suffix in (".mcap", ".db3"))


def cut(bag: Path, size: int) -> None:
    """Cut the bag's (single) storage file to its first ``size`` bytes."""
    path = storage_file(bag)
    path.write_bytes(path.read_bytes()[:size])


def sampled_offsets(size: int, count: int = 45) -> list[int]:
    """Offsets spread over the whole file, and its edges (empty, the 8-byte magic, one byte
    short)."""
    return sorted({0, 1, 8, 9, 64, size - 8, size - 1, *range(0, size, max(1, size // count))})


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_bag_cut_anywhere_reads_whole_or_is_one_clear_error(tmp_path, storage):
    """A storage file cut at any sampled offset gives every message or an InputError, never
    another exception or fewer messages."""
    source = tmp_path / "source"
    total = flushed_bag(source, storage)
    data = storage_file(source).read_bytes()
    outcomes = {"whole": 0, "refused": 0}
    for offset in sampled_offsets(len(data)):
        bag = tmp_path / f"cut_{offset}"
        write_segments(
            bag, [records(1)], storage
        )  # a bag of the same storage, its file replaced below
        os.remove(storage_file(bag))
        (bag / storage_file(source).name).write_bytes(data[:offset])
        (bag / "metadata.yaml").write_text((source / "metadata.yaml").read_text())
        try:
            count = sum(1 for _ in raw_messages(bag))
        except InputError as exc:
            assert exc.field == "bag" and "\n" not in str(exc)
            outcomes["refused"] += 1
            continue
        assert count == total, (
            f"cut at {offset} of {len(data)} bytes read {count} of {total} messages"
        )
        outcomes["whole"] += 1
    assert outcomes["refused"] >= 40  # nearly every cut is noticed, the rest read whole


@pytest.mark.parametrize("storage, size", [("mcap", 8), ("mcap", None), ("sqlite3", None)])
def test_identify_and_bag_info_on_a_cut_bag_say_one_line_and_exit_2(tmp_path, storage, size):
    """tail-beam identify and bag info on a file cut to its magic or in the middle: one line,
    exit 2."""
    bag = tmp_path / "bag"
    flushed_bag(bag, storage)
    cut(bag, size if size is not None else storage_file(bag).stat().st_size // 2)
    for command in (["identify", str(bag)], ["bag", "info", str(bag)]):
        assert_one_line_error(run("tail-beam", *command), "bag = ", "bag repair")


def foreign_bag(path: Path) -> None:
    """A valid rosbag2 bag whose only topic is none of the contract's."""
    with Writer(path, version=9, storage_plugin=STORAGES["mcap"]) as writer:
        connection = writer.add_connection("/chatter", "std_msgs/msg/String", typestore=TYPESTORE)
        for i in range(5):
            writer.write(
                connection,
                i,
                TYPESTORE.serialize_cdr(
                    TYPESTORE.types["std_msgs/msg/String"](data=f"{i}"), "std_msgs/msg/String"
                ),
            )


@pytest.mark.ros
@pytest.mark.parametrize(
    "make, needle",
    [
        (lambda bag: (flushed_bag(bag, "mcap"), cut(bag, 8)), "bag repair"),
        (
            foreign_bag,
            "holds no messages on impact_point, imu, jack_pressure, rebound_velocity, "
            "vibration; "
            "it has: chatter",
        ),
        (lambda bag: bag.symlink_to(bag.parent / "nowhere"), "dangling symbolic link"),
    ],
    ids=["cut-to-magic", "no-contract-topic", "dangling-link"],
)
def test_bag_replay_on_a_bad_bag_exits_with_one_line(tmp_path, make, needle):
    """bag_replay on a bag cut to its magic, without a contract topic, or a
    dangling link: one line, exit 2."""
    bag = tmp_path / "bag"
    make(bag)
    assert_one_line_error(run("bag_replay", "--ros-args", "-p", f"replay.bag_path:={bag}"), needle)


def test_a_bag_of_foreign_topics_is_refused_by_name_not_read_as_all(tmp_path):
    """An empty selection of topics is refused, where the reader would have read it as 'every
    topic'."""
    foreign_bag(tmp_path / "bag")
    with pytest.raises(InputError, match="holds no messages on imu; it has: chatter"):
        next(raw_messages(tmp_path / "bag", [topics.IMU]))


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_repair_of_a_cut_bag_gives_a_bag_that_reads_or_says_it_could_not(tmp_path, storage):
    """bag repair on a closed file cut short: the complete part reads back in order, or exit 2
    'could not repair'; never a bag that does not read."""
    source = tmp_path / "source"
    total = flushed_bag(source, storage)
    size = storage_file(source).stat().st_size
    whole = [(m.topic, m.log_time_ns) for m in raw_messages(source)]
    repaired = failed = 0
    for fraction in (0.0, 0.3, 0.55, 0.8):
        bag = tmp_path / f"cut_{fraction}"
        write_segments(bag, [records(1)], storage)
        os.remove(storage_file(bag))
        (bag / storage_file(source).name).write_bytes(
            storage_file(source).read_bytes()[: int(size * fraction)]
        )
        (bag / "metadata.yaml").write_text((source / "metadata.yaml").read_text())
        result = run("tail-beam", "bag", "repair", str(bag))
        assert "Traceback" not in result.stderr
        if result.returncode == 0:
            got = [(m.topic, m.log_time_ns) for m in raw_messages(bag)]
            assert 0 < len(got) < total and f"the bag reads: {len(got)} messages" in result.stdout
            assert got == whole[: len(got)], (
                "salvaged messages are not the file's first ones, in order"
            )
            assert (
                bag / (storage_file(source).name + ".damaged")
            ).is_file()  # the original is kept aside
            repaired += 1
        else:
            assert_one_line_error(result, "could not repair")
            failed += 1
    assert failed >= 1  # a file cut to nothing cannot be repaired, and says so
    if storage == "mcap":
        assert repaired >= 2  # complete chunks are salvaged


def outside_tree(root: Path) -> dict[str, bytes]:
    """A folder outside the bag with a nested file; returns its contents to compare after."""
    (root / "segment_00000").mkdir(parents=True)
    (root / "segment_00000" / "segment_00000.mcap").write_bytes(b"not yours")
    (root / "precious.txt").write_bytes(b"keep me")
    return snapshot(root)


def snapshot(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
    }


@pytest.mark.parametrize("plant", [".partial", ".partial/segment", "file", "metadata.yaml.tmp"])
def test_bag_repair_never_follows_or_deletes_through_a_link(tmp_path, plant):
    """Links planted in a bag (.partial, a segment, a storage file, the metadata's temp file)
    are left alone; the outside folder is untouched."""
    outside = tmp_path / "outside"
    before = outside_tree(outside)
    bag = tmp_path / "bag"
    write_segments(bag, [records(50)])
    if plant == ".partial":
        (bag / PARTIAL_DIR).symlink_to(outside, target_is_directory=True)
    elif plant == ".partial/segment":
        (bag / PARTIAL_DIR).mkdir()
        (bag / PARTIAL_DIR / "bag_00009").symlink_to(
            outside / "segment_00000", target_is_directory=True
        )
    elif plant == "file":
        (bag / "bag_00009.mcap").symlink_to(outside / "segment_00000" / "segment_00000.mcap")
    else:
        (bag / "metadata.yaml.tmp").symlink_to(outside / "precious.txt")
    result = run("tail-beam", "bag", "repair", str(bag))
    assert result.returncode == 0, result.stderr
    assert snapshot(outside) == before
    assert sum(1 for _ in raw_messages(bag)) == 100
    if plant != "metadata.yaml.tmp":
        assert "left alone symbolic link" in result.stdout
    if plant in (
        ".partial",
        "file",
    ):  # the link itself is still there (a link inside .partial goes with it, unfollowed)
        assert os.path.islink(bag / {".partial": PARTIAL_DIR, "file": "bag_00009.mcap"}[plant])


def test_bag_repair_refuses_a_bag_that_is_a_link(tmp_path):
    """A link as the bag itself is refused in one line; the linked directory is untouched."""
    outside = tmp_path / "outside"
    before = outside_tree(outside)
    (tmp_path / "bag").symlink_to(outside, target_is_directory=True)
    assert_one_line_error(
        run("tail-beam", "bag", "repair", str(tmp_path / "bag")), "symbolic link"
    )
    assert snapshot(outside) == before


def test_simulate_refuses_to_write_through_links(tmp_path):
    """simulate --plot onto a link and --bag onto a dangling or live link: one line, exit 2,
    target untouched."""
    target = tmp_path / "target.png"
    target.write_bytes(b"keep me")
    (tmp_path / "figure.png").symlink_to(target)
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere")
    (tmp_path / "dirlink").symlink_to(tmp_path / "outside", target_is_directory=True)
    (tmp_path / "outside").mkdir()
    assert_one_line_error(
        run("tail-beam", "simulate", "--plot", str(tmp_path / "figure.png")),
        "--plot",
        "symbolic link",
    )
    assert target.read_bytes() == b"keep me"
    for link in ("dangling", "dirlink"):
        assert_one_line_error(
            run("tail-beam", "simulate", "--bag", str(tmp_path / link)), "--bag", "symbolic link"
        )
    assert not (tmp_path / "nowhere").exists() and not any((tmp_path / "outside").iterdir())


def test_identify_and_demo_on_dangling_links_say_one_line(tmp_path):
    """A dangling link as the bag to read or to create: one line, exit 2."""
    link = tmp_path / "bag"
    link.symlink_to(tmp_path / "nowhere")
    assert_one_line_error(run("tail-beam", "identify", str(link)), "dangling symbolic link")
    assert_one_line_error(run("tail-beam", "bag", "info", str(link)), "dangling symbolic link")
    assert_one_line_error(run("tail-beam", "demo", "--bag", str(link)), "--bag", "symbolic link")
    assert not (tmp_path / "nowhere").exists()


@pytest.mark.ros
def test_recorder_on_a_dangling_link_exits_with_one_line(tmp_path):
    """bag_recorder with recorder.bag_path a dangling link: one line, exit 2, nothing created
    at the link's target."""
    link = tmp_path / "bag"
    link.symlink_to(tmp_path / "nowhere")
    result = run("bag_recorder", "--ros-args", "-p", f"recorder.bag_path:={link}")
    assert_one_line_error(result, "recorder.bag_path", "symbolic link")
    assert not (tmp_path / "nowhere").exists()


def test_evaluate_refuses_a_linked_summary_before_the_work(tmp_path):
    """evaluate --out with summary.json a link: refused at once, the link's target untouched."""
    target = tmp_path / "target.json"
    target.write_text("keep me")
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "summary.json").symlink_to(target)
    assert_one_line_error(
        run("tail-beam", "evaluate", "--out", str(tmp_path / "out"), "--count", "1"),
        "--out",
        "symbolic link",
    )
    assert target.read_text() == "keep me"


def test_a_chart_is_never_written_through_a_link(tmp_path):
    """save_figure (simulate, evaluate and bench charts) refuses a link, and the target keeps
    its bytes."""
    from tail_beam_sim.plotting import pyplot, save_figure

    target = tmp_path / "target.png"
    target.write_bytes(b"keep me")
    (tmp_path / "chart.png").symlink_to(target)
    figure = pyplot().figure()
    with pytest.raises(InputError, match="symbolic link"):
        save_figure(figure, tmp_path / "chart.png", 50, "--out")
    assert target.read_bytes() == b"keep me"
    save_figure(pyplot().figure(), tmp_path / "real.png", 50)
    assert (tmp_path / "real.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


class _Planted:
    """A pickle that would create a file when loaded."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (Path.write_text, (self.marker, "code ran"))


def test_a_tampered_training_cache_runs_no_code(tmp_path):
    """python -m tail_beam_id.study.training --cache on a planted pickle: refused with one
    line, the planted code never runs."""
    marker = tmp_path / "marker"
    cache = tmp_path / "cache.json"
    cache.write_bytes(pickle.dumps(_Planted(marker)))
    result = subprocess.run(
        [sys.executable, "-m", "tail_beam_id.study.training", "--cache", str(cache)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert (
        result.returncode != 0
        and "cannot be read" in result.stderr
        and "Traceback" not in result.stderr
    )
    assert not marker.exists()


def test_the_training_cache_round_trips_as_json(tmp_path):
    """save_cache/load_cache give back equal records from a JSON file."""
    from tail_beam_id.stream.label import Label
    from tail_beam_id.study.runs import Record
    from tail_beam_id.study.training import load_cache, save_cache

    label = Label(
        1.2501,
        "coal",
        0.93,
        "threshold",
        latency_ms=0.7,
        data_latency_ms=12.0,
        signals=("imu",),
        features={"rebound_speed_mps": 5.6},
        outside_training=("pressure_noise_pa",),
    )
    record = Record(
        "stream",
        "nominal/x1",
        "threshold",
        0.012,
        3,
        "coal",
        True,
        0.031,
        1.25,
        2.1e-4,
        label,
        0,
        0.002,
    )
    save_cache(tmp_path / "cache.json", [record], [])
    assert load_cache(tmp_path / "cache.json") == ([record], [])
    assert (tmp_path / "cache.json").read_text().startswith("{")


def test_json_topics_holding_anything_read_as_unparsed_and_identify_goes_on(tmp_path):
    """Text on impact_cmd, label and impact_truth that is no JSON object (not JSON, a list, a
    number, nested 100 000 deep) reads back under _unparsed; `tail-beam identify` still labels the
    bag's sensor data, exit 0 and no traceback."""
    from tail_beam_sim.bags import records as bagio
    from tail_beam_sim.bags.read import read_sensors

    texts = ["not json", "[1, 2]", "42", "[" * 100_000, '{"label": "coal"}']
    strings = [
        (
            topic,
            1_000_000 * (k + 1),
            bytes(TYPESTORE.serialize_cdr(bagio.string_msg(text), "std_msgs/msg/String")),
        )
        for k, text in enumerate(texts)
        for topic in (topics.IMPACT_CMD, topics.LABEL, topics.IMPACT_TRUTH)
    ]
    topic, ns, msg = bagio.rebound_msg(0.2, np.array([0.0, 0.0, 1.0]))
    rebound = [(topic, ns, bytes(TYPESTORE.serialize_cdr(msg, topics.MSG_TYPES[topic])))]
    write_segments(tmp_path / "bag", [records(2000) + strings + rebound])
    data = read_sensors(tmp_path / "bag")
    for name in (topics.IMPACT_CMD, topics.LABEL, topics.IMPACT_TRUTH):
        assert [item.get("_unparsed", item) for item in data.json_topics[name]][:4] == texts[:4]
        assert data.json_topics[name][4] == {"label": "coal"}
    result = run("tail-beam", "identify", str(tmp_path / "bag"), "--no-calibrate")
    assert result.returncode == 0 and "Traceback" not in result.stderr, result.stderr


def test_bag_repair_of_metadata_whose_storage_is_no_name_repairs_from_the_files(tmp_path):
    """A metadata.yaml whose storage_identifier is a list (``[1, 2]``): `bag repair` tells the
    storage from the files, as for a bag without metadata, and the repaired bag reads; no
    traceback."""
    bag = tmp_path / "bag"
    write_segments(bag, [records(50)])
    meta = bag / "metadata.yaml"
    text = meta.read_text()
    assert "storage_identifier: mcap" in text
    meta.write_text(text.replace("storage_identifier: mcap", "storage_identifier: [1, 2]"))
    result = run("tail-beam", "bag", "repair", str(bag))
    assert "Traceback" not in result.stderr, result.stderr
    assert (
        result.returncode == 0 and "the bag reads: 100 messages" in result.stdout + result.stderr
    ), result.stdout + result.stderr


@pytest.mark.ros
def test_a_killed_recorders_open_segment_is_said_by_every_reader(tmp_path):
    """bag info, identify and bag_replay on a bag whose recorder was killed read the closed
    segments and say on stderr that the open one (.partial) is left out and how to salvage it;
    after repair there is nothing to say."""
    data = records(600)
    bag = tmp_path / "bag"
    write_segments(
        bag, [data[:400], data[400:800], data[800:]], close=False
    )  # killed with the third segment open
    commands = {
        "bag info": ["tail-beam", "bag", "info", str(bag)],
        "identify": ["tail-beam", "identify", str(bag), "--no-calibrate"],
        "bag_replay": [
            "bag_replay",
            "--ros-args",
            "-p",
            f"replay.bag_path:={bag}",
            "-p",
            "replay.rate:=100.0",
        ],
    }
    for name, command in commands.items():
        result = run(*command)
        assert result.returncode == 0 and "Traceback" not in result.stderr, (
            name,
            result.stderr[-2000:],
        )
        said = [line for line in result.stderr.splitlines() if PARTIAL_DIR in line]
        assert (
            len(said) == 1 and "not read" in said[0] and f"tail-beam bag repair {bag}" in said[0]
        ), (name, result.stderr)
        if name == "bag info":
            assert "800 messages" in result.stdout  # the closed segments, read as they are
    assert run("tail-beam", "bag", "repair", str(bag)).returncode == 0
    # Each reader said it through open_segments_note, which now has nothing to say; bag info
    # reads the repaired bag without a word of it.
    assert open_segments_note(bag) is None
    result = run(*commands["bag info"])
    assert result.returncode == 0 and PARTIAL_DIR not in result.stderr, result.stderr[-2000:]


@pytest.mark.ros
def test_a_recorder_killed_before_its_first_segment_closed_is_not_called_empty(tmp_path):
    """A recorder killed within its first segment leaves metadata.yaml with no messages and the
    open segment in .partial: bag info, identify and bag_replay say in one line that it holds
    no messages, that .partial holds segments not read and to run bag repair, which recovers
    them."""
    bag = tmp_path / "bag"
    writer = write_segments(bag, [records(300)], close=False)
    writer.flush()
    for command in (
        ["tail-beam", "bag", "info", str(bag)],
        ["tail-beam", "identify", str(bag)],
        ["bag_replay", "--ros-args", "-p", f"replay.bag_path:={bag}"],
    ):
        assert_one_line_error(
            run(*command), "holds no messages", PARTIAL_DIR, "tail-beam bag repair"
        )
    assert "the bag reads: 600 messages" in run("tail-beam", "bag", "repair", str(bag)).stdout


def contract_bag_with_a_foreign_type(path: Path, topic: str, msgtype: str, msg) -> None:
    """A bag of pressure and IMU samples plus one message on the contract topic ``topic``
    recorded as ``msgtype`` (not the contract's type)."""
    with Writer(path, version=9, storage_plugin=STORAGES["mcap"]) as writer:
        connections = {}
        for name, ns, raw in records(200):
            if name not in connections:
                connections[name] = writer.add_connection(
                    f"/{name}", topics.MSG_TYPES[name], typestore=TYPESTORE
                )
            writer.write(connections[name], ns, raw)
        connection = writer.add_connection(f"/{topic}", msgtype, typestore=TYPESTORE)
        writer.write(connection, 10**8, TYPESTORE.serialize_cdr(msg, msgtype))


@pytest.mark.ros
@pytest.mark.parametrize(
    "topic, msgtype",
    [(topics.REBOUND_VELOCITY, "std_msgs/msg/String"), (topics.LABEL, "sensor_msgs/msg/Imu")],
)
def test_a_contract_topic_recorded_with_another_type_is_refused_by_name(tmp_path, topic, msgtype):
    """identify, calibrate and bag_replay on a bag holding /rebound_velocity as a String or
    /label as an Imu: one line naming the topic and both types, exit 2; bag info still
    lists it."""
    bag = tmp_path / "bag"
    msg = (
        TYPESTORE.types[msgtype](data="hi")
        if msgtype.endswith("String")
        else TYPESTORE.deserialize_cdr(
            dict((t, raw) for t, _, raw in records(1))[topics.IMU], msgtype
        )
    )
    contract_bag_with_a_foreign_type(bag, topic, msgtype, msg)
    for command in (
        ["tail-beam", "identify", str(bag)],
        ["tail-beam", "calibrate", str(bag)],
        [
            "bag_replay",
            "--ros-args",
            "-p",
            f"replay.bag_path:={bag}",
            "-p",
            "replay.topics:=[imu, rebound_velocity, label]",
        ],
    ):
        assert_one_line_error(run(*command), f"'/{topic}'", msgtype, topics.MSG_TYPES[topic])
    info = run("tail-beam", "bag", "info", str(bag))
    assert info.returncode == 0 and msgtype in info.stdout, info.stderr
