"""What rosbag2 users rely on, in the suite's recorder and replay: split by duration and size,
zstd chunk compression, fully qualified topic names that an independent MCAP reader decodes,
a count of lost samples, and replay's namespace choice, start offset and loop."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from tail_beam_sim import topics
from tail_beam_sim.bags import records as bagio
from tail_beam_sim.bags.write import SegmentedBagWriter
from tail_beam_sim.physics.sensors import VibrationBlocks

NS = "/support_07"


def vibration_bytes(count: int, n: int = 128, rate_hz: float = 25600.0) -> list[tuple[int, bytes]]:
    """``count`` serialized vibration blocks (noise-like samples), with log time = block stamp
    (ns)."""
    first = n * np.arange(count, dtype=np.int64)
    samples = np.random.default_rng(3).normal(9.81, 0.2, count * n).astype(np.float32)
    blocks = VibrationBlocks(
        first, np.full(count, n), first / rate_hz, samples, 1 / rate_hz, 2000.0
    )
    return [
        (ns, bytes(bagio.TYPESTORE.serialize_cdr(msg, topics.MSG_TYPES[topics.VIBRATION])))
        for _, ns, msg in bagio.vibration_msgs(blocks)
    ]


def write(path: Path, records, **options) -> SegmentedBagWriter:
    writer = SegmentedBagWriter(
        path, "mcap", {f"{NS}/vibration": topics.MSG_TYPES[topics.VIBRATION]}, **options
    )
    for ns, data in records:
        writer.write(f"{NS}/vibration", ns, data)
    writer.close()
    return writer


def files_and_spans(path: Path) -> list[tuple[int, int, int]]:
    """(size bytes, first log ns, last log ns) of each mcap file of a bag, in name order."""
    from mcap.reader import make_reader

    out = []
    for file in sorted(path.glob("*.mcap")):
        with file.open("rb") as stream:
            stats = make_reader(stream).get_summary().statistics
        out.append((file.stat().st_size, stats.message_start_time, stats.message_end_time))
    return out


def test_split_by_duration_starts_a_new_file_every_span_of_log_time(tmp_path):
    """1 s of blocks split every 0.25 s of log time: 4 files, none spanning 0.25 s, all messages
    kept."""
    records = vibration_bytes(200)  # 200 x 5 ms = 1 s
    write(tmp_path / "bag", records, max_duration_s=0.25)
    spans = files_and_spans(tmp_path / "bag")
    assert len(spans) == 4
    assert all(last - first < 0.25e9 for _, first, last in spans)
    with AnyReader([tmp_path / "bag"], default_typestore=bagio.TYPESTORE) as reader:
        assert reader.message_count == 200


def test_split_by_size_keeps_every_file_near_the_limit(tmp_path):
    """Uncompressed, 200 blocks of ~560 bytes split at 20 kB: several files, each under the limit
    plus one chunk's bookkeeping, together holding every message."""
    records = vibration_bytes(200)
    limit = 20_000
    write(tmp_path / "bag", records, compression="none", max_size_bytes=limit)
    spans = files_and_spans(tmp_path / "bag")
    total = sum(len(d) for _, d in records)
    assert len(spans) >= total // limit
    assert all(
        size < limit + 4_000 for size, _, _ in spans
    )  # the summary, index and footer a file closes with
    with AnyReader([tmp_path / "bag"], default_typestore=bagio.TYPESTORE) as reader:
        assert reader.message_count == 200


def test_zstd_chunk_compression_is_on_by_default_and_the_file_stays_plain_mcap(tmp_path):
    """Default bags hold zstd-compressed chunks inside a plain .mcap (no .mcap.zstd), smaller than
    the same messages uncompressed; the independent mcap reader decodes them."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    records = vibration_bytes(400)
    write(tmp_path / "zstd", records)
    write(tmp_path / "none", records, compression="none")
    (compressed,), (plain,) = (
        list((tmp_path / "zstd").glob("*.mcap")),
        list((tmp_path / "none").glob("*.mcap")),
    )
    assert not list((tmp_path / "zstd").glob("*.zstd"))
    with compressed.open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        assert {c.compression for c in reader.get_summary().chunk_indexes} == {"zstd"}
        decoded = [(ch.topic, msg) for _, ch, _, msg in reader.iter_decoded_messages()]
    assert compressed.stat().st_size < 0.9 * plain.stat().st_size
    assert len(decoded) == 400 and {t for t, _ in decoded} == {f"{NS}/vibration"}
    assert topics.index_from_words(decoded[7][1].angle_min, decoded[7][1].angle_max) == 7 * 128


@pytest.mark.ros
def test_recorder_writes_fully_qualified_names_counts_no_loss_and_splits(tmp_path):
    """sim_node and bag_recorder in /support_07: the bag holds /support_07/<topic>, split into
    files of at most 1 s of log time (the least split allowed), zstd chunks, the independent
    mcap reader decodes every file, the vibration indices run without a gap and the recorder's
    count of lost samples is 0."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rclpy.parameter import Parameter
    from rosprobe import ros_context, spin_until

    from tail_beam_sim.bags.read import read_sensors
    from tail_beam_sim.ros.recorder_node import LOST_KEYS, RecorderNode
    from tail_beam_sim.ros.sim_node import SimNode

    bag = tmp_path / "bag"
    with ros_context() as (context, executor):
        recorder = RecorderNode(
            context=context,
            namespace=NS,
            parameter_overrides=[
                Parameter("recorder.bag_path", value=str(bag)),
                Parameter("recorder.max_bag_duration_s", value=1.0),
            ],
        )
        sim = SimNode(
            context=context,
            namespace=NS,
            parameter_overrides=[
                Parameter("sim_node.realtime_factor", value=1.0),
                Parameter("sim_node.wait_for_subscribers", value=1),
                Parameter("sim_node.subscriber_settle_s", value=0.3),
                Parameter("sim_node.exit_after_idle_s", value=3.2),
            ],
        )
        executor.add_node(recorder)
        executor.add_node(sim)
        assert spin_until(executor, lambda: sim.finished.done(), timeout_s=60)
        sim.close()
        assert spin_until(
            executor, lambda: recorder.vibration.blocks >= int(3.2 * 200) - 2, timeout_s=20
        )
        recorder.close()
    assert recorder.vibration.lost_samples == 0
    with AnyReader([bag], default_typestore=bagio.TYPESTORE) as reader:
        names = {c.topic for c in reader.connections}
    assert names == {f"{NS}/{t}" for t in topics.MSG_TYPES}
    files = sorted(bag.glob("*.mcap"))
    assert len(files) >= 3
    decoded = 0
    for file in files:
        with file.open("rb") as stream:
            reader = make_reader(stream, decoder_factories=[DecoderFactory()])
            assert {c.compression for c in reader.get_summary().chunk_indexes} <= {"zstd"}
            decoded += sum(
                1 for _, ch, _, _ in reader.iter_decoded_messages(topics=[f"{NS}/vibration"])
            )
    data = read_sensors(bag, required=(topics.VIBRATION,))
    assert data.namespace == NS and data.vibration.count == decoded and data.vibration_gaps == []
    metadata = (bag / "metadata.yaml").read_text()
    assert all(f"{key}: '0'" in metadata for key in LOST_KEYS), metadata


@pytest.mark.ros
def test_replay_chooses_a_namespace_and_honours_start_offset_and_loop(tmp_path):
    """A two-support bag: bag_replay refuses to guess (one line listing both namespaces); with
    replay.namespace it publishes that support's messages under its own namespace; start_offset_s
    skips the first 0.02 s of log time; loop plays the selection twice."""
    from rclpy.parameter import Parameter
    from rosprobe import Probe, ros_context, spin_until
    from sensor_msgs.msg import LaserScan
    from test_vibration import two_support_bag

    from tail_beam_sim.errors import InputError
    from tail_beam_sim.ros import messages as ros_messages
    from tail_beam_sim.ros.replay_node import ReplayNode

    bag = tmp_path / "two"
    two_support_bag(bag)

    def replay(context, **values):
        base = {
            "replay.bag_path": str(bag),
            "replay.rate": 5.0,
            "replay.topics": [topics.VIBRATION],
            "replay.wait_for_subscribers": 1,
            "replay.subscriber_settle_s": 0.3,
        }
        return ReplayNode(
            context=context,
            namespace="/live",
            parameter_overrides=[Parameter(k, value=v) for k, v in {**base, **values}.items()],
        )

    with ros_context() as (context, executor):
        with pytest.raises(InputError, match="/support_01, /support_07"):
            replay(context)
        node = replay(
            context,
            **{
                "replay.namespace": "/support_07",
                "replay.start_offset_s": 0.02,
                "replay.loop": True,
            },
        )
        probe = Probe(context, {topics.VIBRATION: LaserScan}, namespace="/live")
        executor.add_node(node)
        executor.add_node(probe)
        assert spin_until(
            executor,
            lambda: node.loops >= 1 and len(probe.messages[topics.VIBRATION]) >= 2 * 7 + 1,
        )
    blocks = ros_messages.vibration_blocks(probe.messages[topics.VIBRATION])
    per_pass = int(np.sum(blocks.first_index == blocks.first_index[0]))
    assert per_pass >= 2  # played again from the offset
    first_pass = blocks.first_index[
        : np.flatnonzero(blocks.first_index == blocks.first_index[0])[1]
    ]
    # 0.02 s at 25.6 kHz: blocks before index 512 are skipped; the rest come in order.
    assert first_pass[0] == 4 * 128 and np.all(np.diff(first_pass) == 128)


@pytest.mark.ros
def test_events_published_before_the_recorder_matched_are_in_the_bag_once(tmp_path):
    """id_node's labels are published transient-local: three labels published before bag_recorder
    even started are in its bag (a label published in the moment before the recorder matched
    id_node used to be lost), each once, with the two published after. A volatile publisher (a
    client of the contract) on another event topic is still recorded: the recorder follows
    what the publishers offer."""
    import json

    from rclpy.parameter import Parameter
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosprobe import ros_context, spin_for, spin_until
    from std_msgs.msg import String

    from tail_beam_sim.ros import messages as ros_messages
    from tail_beam_sim.ros.recorder_node import RecorderNode

    bag = tmp_path / "bag"
    with ros_context() as (context, executor):
        from rclpy.node import Node

        source = Node("label_source", namespace=NS, context=context)
        labels = source.create_publisher(String, topics.LABEL, ros_messages.EVENT_PUBLISHER_QOS)
        truths = source.create_publisher(
            String,
            topics.IMPACT_TRUTH,
            QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE),
        )
        executor.add_node(source)
        for k in range(3):
            labels.publish(
                String(
                    data=json.dumps(
                        {
                            "impact_stamp": float(k),
                            "label": "coal",
                            "confidence": 0.9,
                            "method": "x",
                        }
                    )
                )
            )
        spin_for(executor, 0.2)
        recorder = RecorderNode(
            context=context,
            namespace=NS,
            parameter_overrides=[Parameter("recorder.bag_path", value=str(bag))],
        )
        executor.add_node(recorder)
        assert spin_until(
            executor,
            lambda: truths.get_subscription_count() >= 1 and labels.get_subscription_count() >= 1,
            timeout_s=20,
        )
        spin_for(executor, 0.5)  # the recorder has looked at the publishers and re-subscribed
        for k in range(3, 5):
            labels.publish(
                String(
                    data=json.dumps(
                        {
                            "impact_stamp": float(k),
                            "label": "gangue",
                            "confidence": 0.9,
                            "method": "x",
                        }
                    )
                )
            )
        truths.publish(String(data=json.dumps({"impact_id": 1})))
        spin_for(executor, 1.0)
        recorder.close()
    with AnyReader([bag], default_typestore=bagio.TYPESTORE) as reader:
        stamps = [
            json.loads(reader.deserialize(raw, c.msgtype).data)["impact_stamp"]
            for c, _, raw in reader.messages()
            if c.topic == f"{NS}/label"
        ]
        truth_count = sum(1 for c, _, _ in reader.messages() if c.topic == f"{NS}/impact_truth")
    assert sorted(stamps) == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert truth_count == 1
