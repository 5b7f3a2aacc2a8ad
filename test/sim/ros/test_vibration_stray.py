"""id_node and bag_recorder live, against vibration blocks of more than one source on the topic:
a stray block costs that block (set aside, counted, named), never the stream in use, the
recorder's lost-sample count or a restart of the time base; warnings are rate-limited."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tail_beam_sim import topics
from tail_beam_sim.physics.sensors import VibrationBlocks

pytestmark = [pytest.mark.ros]

RATE_HZ = 25600.0  # the accelerometer's sample rate
N = 128  # samples per block


def blocks(first_indices, stamp_s, period_s: float = 1.0 / RATE_HZ) -> VibrationBlocks:
    """Blocks of N samples at the given running indices and stamps (s)."""
    first = np.asarray(first_indices, dtype=np.int64)
    return VibrationBlocks(
        first,
        np.full(first.size, N, dtype=np.int64),
        np.asarray(stamp_s, dtype=float),
        np.full(first.size * N, 9.81, dtype=np.float32),
        period_s,
        2000.0,
    )


def real(k0: int, count: int) -> list:
    """``count`` blocks of the honest stream from block ``k0`` on (stamp = index / rate)."""
    from tail_beam_sim.ros import messages as ros_messages

    first = (k0 + np.arange(count)) * N
    return ros_messages.vibration_messages(blocks(first, first / RATE_HZ))


def warnings_of(honest, node: str, words: str) -> list[str]:
    return [x.msg for x in honest.messages["/rosout"] if x.name.endswith(node) and words in x.msg]


def test_stray_blocks_far_ahead_with_a_huge_index_cost_only_themselves(tmp_path):
    """Two blocks stamped about 3.9e7 s ahead with running indices near 1e12 after each honest
    block (400 of them among 200): id_node takes every honest sample (none refused as late or
    misindexed, none lost), sets the 400 aside by count and says so in at most a few lines;
    the recorder counts no sample lost and 400 blocks of another source."""
    from rosprobe import feeding_vibration, spin_for, spin_until

    from tail_beam_sim.ros import messages as ros_messages

    honest_blocks = real(0, 200)
    huge = 10**12 + np.arange(400) * N
    strays = ros_messages.vibration_messages(blocks(huge, huge / RATE_HZ))
    with feeding_vibration(tmp_path / "bag", intruder=True) as (
        executor,
        ident,
        recorder,
        honest,
        pub,
        stray,
    ):
        for k, msg in enumerate(honest_blocks):
            pub.publish(msg)
            stray.publish(strays[2 * k])
            stray.publish(strays[2 * k + 1])
        assert spin_until(
            executor,
            lambda: ident.received[topics.VIBRATION] == 600 and recorder.stray_blocks == 400,
        )
        assert spin_until(executor, lambda: ident.vibration_stray_blocks == 400)
        spin_for(executor, 0.3)
        said = warnings_of(honest, "tail_beam_id", "set aside")
        recorder.close()
    assert ident.gated.sequencer.accepted_samples == 200 * N
    assert ident.vibration_misindexed_blocks == 0 and ident.vibration_late_blocks == 0
    assert ident.vibration_lost_samples == 0 and ident.gated.time_jumps == 0
    assert 1 <= len(said) <= 3 and "not the stream in use" in said[0], said
    assert recorder.vibration_lost_samples == 0 and recorder.vibration.samples == 200 * N


def test_a_second_publishers_interleaved_stream_never_restarts_the_time_base(tmp_path):
    """A second publisher with its own running index 10 times as fast as its stamps, stamped
    on the wall clock (about 1.7e9 s), ten blocks after each honest one: id_node keeps the
    honest stream (every sample taken), restarts no time base, sets the intruder's blocks
    aside and warns in a few lines; no label is published (nothing struck)."""
    import time

    from rosprobe import feeding_vibration, spin_for, spin_until

    from tail_beam_sim.ros import messages as ros_messages

    honest_blocks = real(0, 100)
    index = np.arange(1000) * 10 * N
    stamps = time.time() + np.arange(1000) * N / RATE_HZ
    strays = ros_messages.vibration_messages(blocks(index, stamps))
    with feeding_vibration(tmp_path / "bag", intruder=True) as (
        executor,
        ident,
        recorder,
        honest,
        pub,
        stray,
    ):
        pub.publish(honest_blocks[0])
        assert spin_until(executor, lambda: ident.gated.sequencer.accepted_samples == N)
        for k, msg in enumerate(honest_blocks[1:]):
            for m in strays[10 * k : 10 * k + 10]:
                stray.publish(m)
            pub.publish(msg)
        assert spin_until(executor, lambda: ident.received[topics.VIBRATION] == 1090)
        assert spin_until(executor, lambda: ident.vibration_stray_blocks == 990)
        spin_for(executor, 0.6)
        said = warnings_of(honest, "tail_beam_id", "set aside")
        recorder.close()
    assert ident.gated.time_jumps == 0 and ident.published == 0
    assert ident.gated.sequencer.accepted_samples == 100 * N
    assert 1 <= len(said) <= 3, said
    assert recorder.vibration_lost_samples == 0 and recorder.stray_blocks == 990


def test_a_lone_block_of_another_sample_period_is_set_aside_live(tmp_path):
    """One block claiming 12.8 kHz, alone in its batch between honest 25.6 kHz blocks: id_node
    sets it aside (counted under its period, named in a warning) and the honest stream goes
    on with no gap; the recorder records it and warns that reading the bag sets it aside."""
    from rosprobe import feeding_vibration, spin_for, spin_until

    honest_blocks = real(0, 4)
    odd = real(2, 1)[0]
    odd.time_increment = 1.0 / 12800.0
    with feeding_vibration(tmp_path / "bag", intruder=True) as (
        executor,
        ident,
        recorder,
        honest,
        pub,
        stray,
    ):
        for msg in honest_blocks[:2]:
            pub.publish(msg)
        assert spin_until(executor, lambda: ident.gated.sequencer.accepted_samples == 2 * N)
        stray.publish(odd)
        assert spin_until(executor, lambda: ident.vibration_stray_blocks == 1)
        for msg in honest_blocks[2:]:
            pub.publish(msg)
        assert spin_until(executor, lambda: ident.gated.sequencer.accepted_samples == 4 * N)
        spin_for(executor, 0.3)
        ours = warnings_of(honest, "tail_beam_id", "sample period")
        theirs = warnings_of(honest, "tail_beam_recorder", "sample period")
        recorder.close()
    (why,) = ident.gated.stray_blocks
    assert "sample period 7.8125e-05 s" in why and ident.vibration_lost_samples == 0
    assert len(ours) == 1 and len(theirs) == 1 and recorder.other_period_blocks == 1, theirs
    assert recorder.vibration_lost_samples == 0


def test_id_node_rate_limits_its_warnings_on_refused_messages(tmp_path):
    """300 vibration messages that carry no block (index word NaN), in batches over 1.5 s:
    every one refused and counted, in at most two warning lines (the first at once, then a
    count every few seconds), not a line per batch."""
    from rosprobe import feeding_vibration, spin_for, spin_until

    garbage = real(0, 300)
    for msg in garbage:
        msg.angle_min = math.nan
    with feeding_vibration(tmp_path / "bag", intruder=True) as (
        executor,
        ident,
        recorder,
        honest,
        pub,
        stray,
    ):
        for k in range(0, 300, 10):
            for msg in garbage[k : k + 10]:
                stray.publish(msg)
            spin_for(executor, 0.05)
        assert spin_until(executor, lambda: ident.refused_blocks == 300)
        spin_for(executor, 0.3)
        said = warnings_of(honest, "tail_beam_id", "refused")
        recorder.close()
    assert 1 <= len(said) <= 2, said
