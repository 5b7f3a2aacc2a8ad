"""Samples missing from a stamp grid, counted from the stamps alone (tail_beam_sim.ros.grid_gaps):
what id_node and bag_recorder count when a reader's history overflows without a DDS event."""

from __future__ import annotations

import numpy as np
from rclpy.serialization import serialize_message
from sensor_msgs.msg import FluidPressure

from tail_beam_sim.ros import messages as ros_messages
from tail_beam_sim.ros.grid_gaps import GridGaps, cdr_stamp_s


def grid(rate_hz: float, count: int, missing: set[int], start_s: float = 0.0) -> list[float]:
    return [start_s + k / rate_hz for k in range(count) if k not in missing]


def test_every_missing_sample_is_counted_at_any_rate_in_any_batching():
    """Samples k taken out of a k / rate grid are counted exactly, each gap with the stamps
    either side of it, however the stamps are batched; the period comes from the stamps."""
    rng = np.random.default_rng(3)
    for rate in (800.0, 2000.0, 64000.0):
        missing = {int(k) for k in rng.choice(np.arange(40, 3000), 60, replace=False)}
        stamps = grid(rate, 3000, missing)
        gaps = GridGaps()
        found = []
        cuts = np.sort(rng.choice(np.arange(1, len(stamps)), 20, replace=False))
        for part in np.split(np.array(stamps), cuts):
            found += gaps.add(part.tolist())
        assert gaps.lost_samples == len(missing)
        assert sum(n for *_, n in found) == len(missing)
        assert gaps.period_s == 1.0 / rate or abs(gaps.period_s * rate - 1.0) < 1e-9
        for before, after, n in found:
            assert round((after - before) * rate) == n + 1


def test_repeats_restarts_and_jumps_are_not_losses():
    """A repeated stamp, stamps going back (a restarted simulator) and a jump ahead by more
    than jump_s (a looped replay) start nothing lost; a gap after them still counts."""
    gaps = GridGaps(jump_s=1.0)
    gaps.add(grid(2000.0, 100, set()))
    gaps.add([99 / 2000.0])  # repeated
    gaps.add(grid(2000.0, 100, set()))  # back to 0
    gaps.add(grid(2000.0, 100, {50}, start_s=30.0))  # 30 s ahead, one sample missing
    assert gaps.lost_samples == 1 and gaps.gap_count == 1


def test_the_stamp_is_read_from_the_serialized_header():
    """bag_recorder reads the stamp of a raw pressure message without decoding the message."""
    msg = FluidPressure(header=ros_messages.header(12.3455, "tail_beam_jack"))
    assert abs(cdr_stamp_s(serialize_message(msg)) - 12.3455) < 1e-9
    assert cdr_stamp_s(b"\x00\x01") is None
