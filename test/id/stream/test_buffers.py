"""Series buffers: joined into stores with room, they show exactly the samples a plain
concatenation would, and a view handed out keeps its contents while more samples arrive, the
buffer is trimmed or its store grows."""

from __future__ import annotations

import numpy as np

from tail_beam_id.stream.buffers import Series


def test_joined_buffer_is_the_concatenation_and_old_views_keep_their_contents():
    """After appends, joins and trims the buffer shows the concatenation of what was kept, and
    every view handed out still shows what it showed."""
    rng = np.random.default_rng(7)
    series = Series()
    stamps, values, handed_out = [], [], []
    t = 0.0
    for step in range(300):
        n = int(rng.integers(1, 40))
        chunk_t = t + np.arange(1, n + 1) * 1e-3
        t = float(chunk_t[-1])
        chunk_v = rng.standard_normal((n, 6))
        series.append(chunk_t, chunk_v)
        stamps.append(chunk_t)
        values.append(chunk_v)
        if step % 3 == 0:
            series.join()
            handed_out.append(
                (series.stamp_s, series.values, series.stamp_s.copy(), series.values.copy())
            )
        if step % 50 == 49:  # forget the older half
            series.join()
            series.trim_before(float(series.stamp_s[series.stamp_s.size // 2]))
    series.join()
    everything_t, everything_v = np.concatenate(stamps), np.concatenate(values)
    kept = everything_t >= series.stamp_s[0]
    np.testing.assert_array_equal(series.stamp_s, everything_t[kept])
    np.testing.assert_array_equal(series.values, everything_v[kept])
    assert series.base_index == int(np.count_nonzero(~kept))
    for stamp_view, value_view, stamp_copy, value_copy in handed_out:
        np.testing.assert_array_equal(stamp_view, stamp_copy)
        np.testing.assert_array_equal(value_view, value_copy)


def test_repeated_stamps_are_dropped_across_joins():
    """A stamp not after the latest one, across a join or within a chunk, is dropped."""
    series = Series()
    series.append(np.array([1.0, 2.0]), np.array([[1.0], [2.0]]))
    series.join()
    series.append(np.array([2.0, 3.0, 3.0, 4.0]), np.array([[9.0], [3.0], [9.0], [4.0]]))
    series.join()
    np.testing.assert_array_equal(series.stamp_s, [1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(series.values[:, 0], [1.0, 2.0, 3.0, 4.0])
