"""The tail-beam accelerometer and its `vibration` blocks: the sensor model (anti-alias filter,
noise, saturation), the two codecs (rclpy, rosbags), gap and late-block detection, bags read
per support, and sim_node/id_node over the real middleware."""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tail_beam_sim import topics
from tail_beam_sim.bags import records as bagio
from tail_beam_sim.bags.read import read_sensors
from tail_beam_sim.config import default_config_dir, load_parameters
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.sensors import (
    AntiAliasFilter,
    BlockSequencer,
    IndexSpan,
    VibrationBlocks,
)
from tail_beam_sim.physics.simulate import simulate
from tail_beam_sim.physics.stream import StreamSimulator

TAIL_BEAM = str(Path(sys.executable).parent / "tail-beam")
MARBLE = {"material": "marble", "radius_m": 0.1, "drop_height_m": 4.0, "position_m": 1.4}
COAL = {"material": "coal", "radius_m": 0.03, "drop_height_m": 3.0, "position_m": 1.0}


def stream(**sensors) -> StreamSimulator:
    params = load_parameters([default_config_dir() / "sim_node.yaml"])
    params["sensors"].update(sensors)
    return StreamSimulator.from_params(params)


def blocks_of(first_indices, n: int = 4, rate_hz: float = 1000.0) -> VibrationBlocks:
    """Blocks of n samples starting at ``first_indices``; sample values = their own index."""
    first = np.asarray(first_indices, dtype=np.int64)
    samples = (
        np.concatenate([np.arange(f, f + n) for f in first]).astype(np.float32)
        if first.size
        else np.empty(0, np.float32)
    )
    return VibrationBlocks(
        first,
        np.full(first.size, n, dtype=np.int64),
        first / rate_hz,
        samples,
        1.0 / rate_hz,
        100.0,
    )


# --- sensor model ----------------------------------------------------------------------------


def test_antialias_filter_passes_the_band_and_stops_what_would_alias():
    """Butterworth magnitude |H| = 1/sqrt(1 + (f/fc)^2n): a tone at 0.2 x rate passes (0.998), one
    at
    0.9 x rate, which would fold onto 0.1 x rate, is cut to under 0.04 of its amplitude."""
    rate, m = 25600.0, 4
    t = np.arange(200_000) / (m * rate)

    def gain(frequency_hz: float) -> float:
        out = AntiAliasFilter(rate, 4, 0.4, m)(np.sin(2 * np.pi * frequency_hz * t))[::m]
        return float(np.sqrt(2) * out[out.size // 2 :].std())

    assert gain(0.2 * rate) == pytest.approx(1 / math.sqrt(1 + 0.5**8), abs=0.01)
    assert gain(0.9 * rate) < 1 / math.sqrt(1 + (0.9 / 0.4) ** 8) + 0.005


def test_accelerometer_at_rest_reads_g_with_its_noise_density():
    """A plate at rest reads +g (specific force); the noise RMS is density x sqrt(cut-off)."""
    sim = stream(vibration_noise_density_mps2_rthz=0.004)
    blocks = sim.advance(0.5).vibration
    expected_rms = 0.004 * math.sqrt(0.4 * 25600.0)
    assert blocks.sample_count == 0.5 * 25600 // 128 * 128
    assert blocks.accel_mps2.mean() == pytest.approx(9.81, abs=0.01)
    assert blocks.accel_mps2.std() == pytest.approx(expected_rms, rel=0.05)


def test_vibration_is_the_same_however_time_is_chunked():
    """Dense response, filter state and noise are carried by sample index: two chunkings give
    bit-identical blocks, numbered without a gap."""

    def run(step: float) -> VibrationBlocks:
        sim = stream()
        sim.submit(MARBLE, 0.1)
        parts, t = [], 0.0
        while t < 0.4:
            t = min(0.4, t + step)
            parts.append(sim.advance(t).vibration)
        return VibrationBlocks.concatenate(parts)

    a, b = run(0.02), run(0.0071)
    assert a.count == b.count == int(0.4 * 25600) // 128
    np.testing.assert_array_equal(a.first_index, 128 * np.arange(a.count))
    np.testing.assert_array_equal(a.accel_mps2, b.accel_mps2)


def test_an_accelerometer_that_saturates_is_clipped_at_its_range_and_flagged():
    """A 100 mm marble lump at the tip peaks near 1.2 km/s^2: a 200 m/s^2 sensor clips there and
    the clipped samples read exactly its limit, on the wire too (range_min/range_max)."""
    sim = stream(vibration_range_mps2=200.0)
    sim.submit(MARBLE, 0.05)
    blocks = sim.advance(0.1).vibration
    saturated = blocks.saturated()
    assert saturated.sum() >= 3
    assert np.abs(blocks.accel_mps2).max() == np.float32(200.0)
    assert not saturated[blocks.sample_stamps_s() < 0.05].any()
    b = int(np.searchsorted(blocks.offsets(), np.flatnonzero(saturated)[0], side="right") - 1)
    (message,) = [
        m for _, _, m in bagio.vibration_msgs(blocks.select(np.arange(blocks.count) == b))
    ]
    index, _, samples, _, range_mps2 = bagio.vibration_fields(message)
    assert (
        range_mps2 == 200.0
        and message.range_min == -200.0
        and (np.abs(samples) >= range_mps2).any()
    )


def test_offline_simulate_carries_the_accelerometer_response_of_the_impact():
    """`simulate` gives whole blocks from stamp 0; the impact shows in them far above the noise."""
    params = load_parameters()
    result = simulate(Scene.from_params(params, {"material": "sandstone", "radius_m": 0.05}))
    blocks = result.vibration
    stamps = blocks.sample_stamps_s()
    assert blocks.first_index[0] == 0 and blocks.sample_count % 128 == 0
    np.testing.assert_allclose(np.diff(stamps), 1 / 25600.0, atol=1e-12)
    before = blocks.accel_mps2[stamps < result.contact_stamp_s]
    after = np.abs(blocks.accel_mps2[stamps >= result.contact_stamp_s] - 9.81)
    assert after.max() > 20 * before.std()


# --- codecs ------------------------------------------------------------------------------------


def test_rclpy_and_rosbags_codecs_carry_index_stamp_period_and_samples_exactly():
    """A block far into a run (index beyond 2**24 and 2**40) crosses rclpy serialization and the
    rosbags decoder with its exact index, stamp, float32 samples, period and range."""
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import LaserScan

    from tail_beam_sim.ros import messages as ros_messages

    first = [2**24 + 3 * 128, 2**40 + 5]
    blocks = VibrationBlocks(
        np.array(first, dtype=np.int64),
        np.array([128, 128]),
        np.array(first) / 25600.0,
        np.random.default_rng(1).normal(9.81, 3, 256).astype(np.float32),
        1 / 25600.0,
        2000.0,
    )
    wire = [serialize_message(m) for m in ros_messages.vibration_messages(blocks)]
    back = ros_messages.vibration_blocks([deserialize_message(w, LaserScan) for w in wire])
    np.testing.assert_array_equal(back.first_index, first)
    np.testing.assert_array_equal(back.accel_mps2, blocks.accel_mps2)
    np.testing.assert_allclose(back.stamp_s, blocks.stamp_s, atol=1e-9)
    assert back.period_s == pytest.approx(1 / 25600.0, rel=1e-7) and back.range_mps2 == 2000.0
    for data, (b_first, b_stamp, b_samples) in zip(wire, (blocks.block(0), blocks.block(1))):
        index, stamp, samples, period, _ = bagio.vibration_fields(
            bagio.TYPESTORE.deserialize_cdr(data, "sensor_msgs/msg/LaserScan")
        )
        assert index == b_first and stamp == pytest.approx(b_stamp, abs=1e-9)
        np.testing.assert_array_equal(samples, b_samples)


# --- gaps and late blocks ------------------------------------------------------------------------


def test_a_dropped_block_is_detected_from_the_index_and_counted():
    """Blocks 0, 4, 12 of 4 samples: block 8 is missing, 4 samples lost, one gap at index 8."""
    sequencer = BlockSequencer()
    report = sequencer.push(blocks_of([0, 4, 12]))
    assert report.gaps == [(8, 4)]
    assert sequencer.lost_samples == 4 and sequencer.gap_count == 1
    np.testing.assert_array_equal(report.accepted.first_index, [0, 4, 12])


def test_a_late_block_is_put_back_in_order_or_refused_with_a_count():
    """Within one delivery a late block is reordered (no gap); once a later block has been
    handed on, the late one (and a repeat) is refused and counted, never passed on out of order."""
    sequencer = BlockSequencer()
    report = sequencer.push(blocks_of([0, 8, 4]))
    assert report.gaps == [] and report.late == 0
    np.testing.assert_array_equal(report.accepted.accel_mps2, np.arange(12))
    report = sequencer.push(blocks_of([16]))
    assert report.gaps == [(12, 4)]
    report = sequencer.push(blocks_of([12, 16, 20]))
    assert report.late == 2 and sequencer.late_blocks == 2
    np.testing.assert_array_equal(report.accepted.first_index, [20])


def blocks_stamped(first_indices, n: int = 4, rate_hz: float = 1000.0) -> VibrationBlocks:
    """Blocks of n samples, block k stamped k n / rate_hz (one after another in time) whatever
    index ``first_indices`` gives it."""
    first = np.asarray(first_indices, dtype=np.int64)
    stamps = np.arange(first.size) * n / rate_hz
    return VibrationBlocks(
        first,
        np.full(first.size, n, dtype=np.int64),
        stamps,
        np.zeros(first.size * n, np.float32),
        1.0 / rate_hz,
        100.0,
    )


def test_an_index_that_does_not_count_samples_is_told_from_a_late_block():
    """Blocks one after another in time whose index stays 0 (a publisher that ignores the index
    words): the first is used, the others refused as misindexed, not as late, whether they come
    one at a time or together; a truly late block (its stamp where its index puts it) is late."""
    zeros = blocks_stamped([0, 0, 0, 0])
    one_by_one = BlockSequencer()
    for k in range(4):
        one_by_one.push(zeros.select(np.arange(4) == k))
    assert (
        one_by_one.misindexed_blocks == 3
        and one_by_one.late_blocks == 0
        and one_by_one.accepted_samples == 4
    )
    together = BlockSequencer()
    report = together.push(zeros)
    assert report.misindexed == 3 and report.late == 0 and report.accepted.count == 1
    late = BlockSequencer()
    late.push(blocks_stamped([0, 4, 8]).select(np.array([True, False, True])))
    report = late.push(blocks_stamped([0, 4, 8]).select(np.array([False, True, False])))
    assert report.late == 1 and report.misindexed == 0


@pytest.mark.parametrize(
    ("first", "conflict"),
    [([0, 0, 0], (0, 1)), ([0, 1, 2], (0, 1)), ([0, 4, 8], None), ([0, 4, 12], None)],
)
def test_blocks_whose_indices_overlap_while_their_stamps_do_not_are_a_conflict(first, conflict):
    """index_conflict: overlapping index spans at stamps one block apart (index 0 throughout, or
    a block count) are the first conflicting pair; a stream counting samples, gap or not, has
    none, and neither has every block given twice (same index, same stamp)."""
    assert blocks_stamped(first).index_conflict() == conflict
    twice = blocks_of([0, 4, 8, 0, 4, 8])
    assert twice.index_conflict() is None


def test_the_recorders_count_is_independent_of_arrival_order():
    """IndexSpan: blocks 8, 0, 12 (4 missing) count 4 lost samples in any order."""
    for order in ([8, 0, 12], [12, 8, 0], [0, 8, 12]):
        span = IndexSpan()
        for first in order:
            span.add(first, 4)
        assert span.lost_samples == 4 and span.samples == 12


# --- bags: gaps, missing topic, several supports ------------------------------------------------


def impact_records(command: dict, seed: int = 0) -> list:
    params = load_parameters()
    result = simulate(Scene.from_params(params, {**command, "seed": seed}))
    return bagio.result_records(result, command)


def test_a_bag_with_a_dropped_and_a_late_block_reads_back_in_order_with_the_gap(tmp_path):
    """A block missing from the bag is listed as a gap (tail-beam bag info says how many samples);
    one written out of order is read back in its place."""
    records = impact_records(COAL)
    vibration = [r for r in records if r[0] == topics.VIBRATION]
    dropped, late = vibration[3], vibration[5]
    kept = [r for r in records if r is not dropped and r is not late] + [
        (late[0], late[1] + 10**7, late[2])
    ]
    bagio.write_bag(tmp_path / "bag", kept)
    data = read_sensors(tmp_path / "bag")
    assert data.vibration_gaps == [(3 * 128, 128)] and data.vibration_lost_samples == 128
    assert (
        np.all(np.diff(data.vibration.first_index) > 0) and 5 * 128 in data.vibration.first_index
    )
    info = subprocess.run(
        [TAIL_BEAM, "bag", "info", str(tmp_path / "bag")],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "/vibration" in info and "128 samples lost" in info and "at 25600 Hz" in info


def test_a_block_of_another_sample_period_is_set_aside_by_name_and_the_rest_read(tmp_path):
    """One vibration message claiming another (valid) sample period among 25.6 kHz blocks: read
    with the stream's period its samples would sit at the wrong times, so that one message is set
    aside, counted under the period reason, and the rest of the stream is read at 25.6 kHz;
    `tail-beam identify` names it in one warning line and exits 0."""
    records = impact_records(COAL)
    index = next(i for i, r in enumerate(records) if r[0] == topics.VIBRATION) + 2
    topic, log_ns, msg = records[index]
    records[index] = (topic, log_ns, dataclasses.replace(msg, time_increment=1.0 / 12800.0))
    blocks_in_bag = sum(r[0] == topics.VIBRATION for r in records)
    bagio.write_bag(tmp_path / "bag", records)
    data = read_sensors(tmp_path / "bag")
    assert data.vibration.period_s == pytest.approx(1.0 / 25600.0, rel=1e-9)
    assert data.vibration.count == blocks_in_bag - 1
    (why,) = [w for w in data.set_aside if w.startswith(topics.VIBRATION)]
    assert "sample period" in why and data.set_aside[why] == 1, data.set_aside
    cli = subprocess.run(
        [TAIL_BEAM, "identify", str(tmp_path / "bag")], capture_output=True, text=True
    )
    said = [line for line in cli.stderr.splitlines() if "set aside" in line]
    assert cli.returncode == 0 and "Traceback" not in cli.stderr, cli.stderr
    assert len(said) == 1 and "sample period" in said[0] and "1 message(s)" in said[0], said


def test_without_the_vibration_topic_labels_still_come_from_the_other_signals(tmp_path):
    """A bag with no vibration at all is identified from IMU, pressure and camera."""
    from tail_beam_id.cli.identify_cmd import identify_bag

    bagio.write_bag(
        tmp_path / "bag", [r for r in impact_records(COAL) if r[0] != topics.VIBRATION]
    )
    assert read_sensors(tmp_path / "bag").vibration.count == 0
    (label,) = identify_bag(str(tmp_path / "bag"), "statistical")
    assert label.material == "coal" and "vibration" not in label.signals


def two_support_bag(path: Path) -> None:
    """Coal under /support_01 and marble under /support_07, one mcap bag (as one recorder per
    support writing side by side would give, merged)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        for namespace, command in (
            ("/support_01", COAL),
            ("/support_07", {**MARBLE, "radius_m": 0.05}),
        ):
            connections = {
                t: writer.add_connection(
                    topics.qualified(namespace, t), m, typestore=bagio.TYPESTORE
                )
                for t, m in topics.MSG_TYPES.items()
            }
            for topic, ns, msg in sorted(impact_records(command), key=lambda r: r[1]):
                writer.write(
                    connections[topic],
                    ns,
                    bagio.TYPESTORE.serialize_cdr(msg, topics.MSG_TYPES[topic]),
                )


def test_two_supports_in_one_bag_need_a_namespace_and_then_read_the_right_one(tmp_path):
    """Without --namespace: exit 2 and one line naming both supports; with it, each support's
    own impact (coal on 01, marble on 07)."""
    from tail_beam_id.cli.identify_cmd import identify_bag

    bag = tmp_path / "two"
    two_support_bag(bag)
    with pytest.raises(InputError, match="/support_01, /support_07"):
        read_sensors(bag)
    cli = subprocess.run([TAIL_BEAM, "identify", str(bag)], capture_output=True, text=True)
    assert cli.returncode == 2 and "--namespace" in cli.stderr and "Traceback" not in cli.stderr
    assert [lab.material for lab in identify_bag(str(bag), namespace="/support_01")] == ["coal"]
    assert [lab.material for lab in identify_bag(str(bag), namespace="support_07")] == ["gangue"]
    assert read_sensors(bag, namespace="/support_07").namespace == "/support_07"
    with pytest.raises(InputError, match="namespace = '/support_03'"):
        read_sensors(bag, namespace="/support_03")


def test_a_bag_with_relative_names_still_reads():
    """Bags recorded before the names were fully qualified (``imu``) read as the root namespace."""
    assert topics.namespace_of("imu") == topics.namespace_of("/imu") == "/"
    assert topics.namespace_of("/support_07/imu") == "/support_07"
    assert (
        topics.qualified("/support_07/", "imu") == "/support_07/imu"
        and topics.qualified("", "imu") == "/imu"
    )


# --- nodes over the middleware -----------------------------------------------------------------


@pytest.mark.ros
def test_sim_node_publishes_contiguous_numbered_blocks():
    """sim_node's blocks: consecutive indices from 0, stamp = index / rate, frame and range as
    documented."""
    from geometry_msgs.msg import TwistStamped
    from rclpy.parameter import Parameter
    from rosprobe import Probe, ros_context, spin_until
    from sensor_msgs.msg import FluidPressure, Imu, LaserScan

    from tail_beam_sim.ros import messages as ros_messages
    from tail_beam_sim.ros.sim_node import SimNode

    with ros_context() as (context, executor):
        sim = SimNode(
            context=context,
            parameter_overrides=[
                Parameter("sim_node.realtime_factor", value=0.0),
                Parameter("sim_node.wait_for_subscribers", value=1),
                Parameter("sim_node.subscriber_settle_s", value=0.3),
            ],
        )
        probe = Probe(
            context,
            {
                topics.VIBRATION: LaserScan,
                topics.JACK_PRESSURE: FluidPressure,
                topics.IMU: Imu,
                topics.REBOUND_VELOCITY: TwistStamped,
            },
        )  # the gate waits for all four
        executor.add_node(sim)
        executor.add_node(probe)
        assert spin_until(executor, lambda: len(probe.messages[topics.VIBRATION]) >= 100)
        blocks = ros_messages.vibration_blocks(probe.messages[topics.VIBRATION])
        np.testing.assert_array_equal(blocks.first_index, 128 * np.arange(blocks.count))
        np.testing.assert_allclose(blocks.stamp_s, blocks.first_index / 25600.0, atol=1e-9)
        assert {m.header.frame_id for m in probe.messages[topics.VIBRATION]} == {
            "tail_beam_accelerometer"
        }
        assert {(m.range_min, m.range_max) for m in probe.messages[topics.VIBRATION]} == {
            (-2000.0, 2000.0)
        }


@pytest.mark.ros
def test_id_node_reports_a_dropped_block_and_refuses_a_late_one():
    """id_node fed blocks 0, 1, 3 then 2 over the middleware: one gap of 128 samples, then block 2
    refused as late (it came after block 3 was handed on)."""
    from rclpy.parameter import Parameter
    from rosprobe import RELIABLE, Probe, ros_context, spin_until
    from sensor_msgs.msg import LaserScan

    from tail_beam_id.ros.id_node import IdNode
    from tail_beam_sim.ros import messages as ros_messages

    with ros_context() as (context, executor):
        ident = IdNode(
            context=context,
            namespace="/feed",
            parameter_overrides=[Parameter("id_node.poll_period_s", value=0.05)],
        )
        feeder = Probe(context, {}, namespace="/feed", name="feeder")
        pub = feeder.create_publisher(LaserScan, topics.VIBRATION, RELIABLE)
        executor.add_node(ident)
        executor.add_node(feeder)
        assert spin_until(executor, lambda: pub.get_subscription_count() >= 1)
        msgs = ros_messages.vibration_messages(
            blocks_of([0, 128, 256, 384], n=128, rate_hz=25600.0)
        )
        for msg in (msgs[0], msgs[1], msgs[3]):
            pub.publish(msg)
        assert spin_until(executor, lambda: ident.vibration_lost_samples == 128)
        pub.publish(msgs[2])
        assert spin_until(executor, lambda: ident.vibration_late_blocks == 1)
        assert ident.received[topics.VIBRATION] == 4 and ident.vibration_lost_samples == 128


@pytest.mark.ros
def test_id_node_and_the_recorder_say_when_a_publishers_index_does_not_count_samples(tmp_path):
    """A client whose blocks all carry index 0 while their stamps go on: id_node uses the first,
    refuses the others as misindexed (not late) and logs that the index must count samples; the
    recorder records them all and warns at once (not an hour later, when the bag is read);
    reading the bag is refused, naming the index words."""
    from rosprobe import feeding_vibration, spin_until

    from tail_beam_sim.ros import messages as ros_messages

    with feeding_vibration(tmp_path / "bag") as (executor, ident, recorder, feeder, pub, _):
        for msg in ros_messages.vibration_messages(
            blocks_stamped([0, 0, 0], n=128, rate_hz=25600.0)
        ):
            pub.publish(msg)
        assert spin_until(
            executor,
            lambda: ident.vibration_misindexed_blocks == 2 and recorder.misindexed_blocks == 2,
        )
        assert spin_until(
            executor,
            lambda: (
                sum(
                    "index must count the samples" in x.msg
                    or "(angle_min, angle_max) must count the samples" in x.msg
                    for x in feeder.messages["/rosout"]
                )
                >= 2
            ),
        )
        assert ident.vibration_late_blocks == 0
        recorder.close()
    with pytest.raises(InputError, match=r"vibration\.angle_min/angle_max"):
        read_sensors(tmp_path / "bag", required=(topics.VIBRATION,))


@pytest.mark.ros
def test_vibration_messages_that_carry_no_block_are_set_aside_by_name_and_the_rest_read(
    tmp_path,
):
    """A client publishes vibration messages whose index words, period or range are no block's
    (NaN, negative, fractional, zero period, zero range) between good ones: id_node refuses each
    with a line naming the field and keeps identifying the good blocks (the refused one's samples
    are a gap); the recorder records them all and goes on; reading that bag sets those messages
    aside, counted by reason, reads the two good blocks, and `tail-beam bag info` exits 0."""
    from rosprobe import feeding_vibration, spin_for, spin_until

    from tail_beam_sim.ros import messages as ros_messages

    spoilers = [
        ("angle_min", math.nan),
        ("angle_max", -1.0),
        ("angle_max", 3.5),
        ("time_increment", 0.0),
        ("range_max", 0.0),
    ]
    good = ros_messages.vibration_messages(
        blocks_of([k * 128 for k in range(len(spoilers) + 2)], n=128, rate_hz=25600.0)
    )
    bad = []
    for (field, value), msg in zip(spoilers, good[1:-1]):
        setattr(msg, field, value)
        bad.append(msg)
    with feeding_vibration(tmp_path / "bag") as (executor, ident, recorder, feeder, pub, _):
        for msg in good:
            pub.publish(msg)
        assert spin_until(
            executor,
            lambda: ident.refused_blocks == len(spoilers) and recorder.refused_blocks == 3,
        )
        spin_for(executor, 0.3)
        log = " | ".join(x.msg for x in feeder.messages["/rosout"])
        recorder.close()
    assert ident.received[topics.VIBRATION] == len(good)
    assert (
        ident.vibration_lost_samples == len(spoilers) * 128
    )  # the refused blocks' samples are a gap
    for field, _ in spoilers:
        assert f"vibration.{field} = " in log, log
    assert f"({len(spoilers)} refused in all)" in log and "recorded but not counted" in log
    data = read_sensors(tmp_path / "bag", required=(topics.VIBRATION,))
    assert sum(n for w, n in data.set_aside.items() if w.startswith(topics.VIBRATION)) == len(
        spoilers
    ), data.set_aside
    assert any("angle_min" in w for w in data.set_aside), data.set_aside
    np.testing.assert_array_equal(data.vibration.first_index, [0, (len(spoilers) + 1) * 128])
    info = subprocess.run(
        [TAIL_BEAM, "bag", "info", str(tmp_path / "bag")], capture_output=True, text=True
    )
    assert info.returncode == 0 and "Traceback" not in info.stderr, info.stderr


@pytest.mark.ros
def test_an_empty_vibration_block_is_refused_by_name_and_hides_no_samples(tmp_path):
    """A client publishes a vibration message with no samples (``ranges`` empty, a valid header)
    at the index of the next real block. It carries no block: id_node refuses it with a line
    naming ``vibration.ranges`` and goes on (alone in a tick's batch it raised ValueError out of
    the tick, which ends the node), and the real block at that index is used, no sample counted
    lost; the recorder records
    it and warns; reading the bag sets that message aside, counted under the field, and reads
    the three real blocks with no sample lost (the empty one never takes the real one's
    index)."""
    from rosprobe import feeding_vibration, spin_for, spin_until

    from tail_beam_sim.ros import messages as ros_messages

    good = ros_messages.vibration_messages(blocks_of([0, 128, 256], n=128, rate_hz=25600.0))
    empty = ros_messages.vibration_messages(blocks_of([128], n=128, rate_hz=25600.0))[0]
    empty.ranges = []
    empty.scan_time = 0.0
    with feeding_vibration(tmp_path / "bag") as (executor, ident, recorder, feeder, pub, _):
        for msg in (good[0], empty, good[1], good[2]):
            pub.publish(msg)
        assert spin_until(
            executor, lambda: ident.refused_blocks == 1 and recorder.refused_blocks == 1
        )
        assert ident.received[topics.VIBRATION] == 4
        spin_for(executor, 0.3)
        log = " | ".join(x.msg for x in feeder.messages["/rosout"])
        recorder.close()
    assert ident.vibration_lost_samples == 0 and ident.vibration_late_blocks == 0
    assert "vibration.ranges = " in log and "must hold at least one sample" in log, log
    assert "recorded but not counted" in log, log
    data = read_sensors(tmp_path / "bag", required=(topics.VIBRATION,))
    assert sum(n for w, n in data.set_aside.items() if "ranges" in w) == 1, data.set_aside
    np.testing.assert_array_equal(data.vibration.first_index, [0, 128, 256])
    assert data.vibration_lost_samples == 0
