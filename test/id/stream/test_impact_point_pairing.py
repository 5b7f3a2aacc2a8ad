"""The identifier's impact points: paired with the rebound of their stamp in either order,
refused by name when they are no point on the plate, set aside when no rebound comes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tail_beam_id.stream.impact_point import NO_REBOUND, ImpactPoints
from tail_beam_sim import topics

PLATE = (1.6, 1.5)  # length, width of the shipped plate, m


def points() -> ImpactPoints:
    return ImpactPoints(lambda: PLATE, timeout_s=0.03)


@pytest.mark.parametrize("point_first", [True, False])
def test_a_point_is_its_rebounds_whichever_comes_first(point_first):
    """A point and a rebound of one stamp pair whichever comes first; the next frame's does not."""
    p = points()
    if point_first:
        assert p.add(1.0, np.array([0.7, 0.1, 0.0]), topics.FRAME_PLATE) is None
        p.add_rebound(1.0 + 1e-9)
    else:
        p.add_rebound(1.0)
        assert p.add(1.0, np.array([0.7, 0.1, 0.0]), topics.FRAME_PLATE) is None
    assert p.point_of(1.0) == (0.7, 0.1)
    assert p.point_of(1.0002) is None  # the next camera frame is another impact's
    assert p.expire(5.0) == 0 and p.refused == {}


def test_a_point_without_a_rebound_is_set_aside_once_the_streams_pass_it():
    """A point with no rebound is kept for the camera timeout, then set aside and counted."""
    p = points()
    p.add(1.0, np.array([0.7, 0.0, 0.0]), topics.FRAME_PLATE)
    assert p.expire(1.02) == 0  # still within the camera timeout
    assert p.expire(1.04) == 1
    assert p.refused == {NO_REBOUND: 1} and p.point_of(1.0) is None
    p.add(2.0, np.array([0.7, 0.0, 0.0]), topics.FRAME_PLATE)
    assert p.flush() == 1 and p.refused_count == 2


@pytest.mark.parametrize(
    "xyz, frame, field",
    [
        ((math.nan, 0.0, 0.0), topics.FRAME_PLATE, "impact_point.point.x"),
        ((0.5, -math.inf, 0.0), topics.FRAME_PLATE, "impact_point.point.y"),
        ((0.5, 0.0, math.nan), topics.FRAME_PLATE, "impact_point.point.z"),
        ((0.5, 0.0, 0.01), topics.FRAME_PLATE, "impact_point.point.z"),
        ((-0.01, 0.0, 0.0), topics.FRAME_PLATE, "impact_point.point.x"),
        ((1.61, 0.0, 0.0), topics.FRAME_PLATE, "impact_point.point.x"),
        ((0.5, 0.76, 0.0), topics.FRAME_PLATE, "impact_point.point.y"),
        ((0.5, 0.0, 0.0), "tail_beam_imu", "impact_point.header.frame_id"),
        ((0.5, 0.0, 0.0), "", "impact_point.header.frame_id"),
    ],
)
def test_what_is_no_point_on_the_plate_is_refused_by_name(xyz, frame, field):
    """NaN, infinite, z not 0, off the plate's length or width, another frame: refused naming
    the field, counted by field and rule."""
    p = points()
    p.add_rebound(1.0)
    why = p.add(1.0, np.array(xyz), frame)
    assert why is not None and why.startswith(f"{field} = ")
    (reason,) = p.refused
    assert reason.startswith(f"{field}: ") and p.refused[reason] == 1
    assert p.point_of(1.0) is None


def test_the_plate_edges_are_on_it_and_the_bounds_follow_the_support():
    """The plate's edges are on it; a smaller plate refuses what the shipped one takes."""
    p = points()
    for x, y in ((0.0, 0.75), (1.6, -0.75)):
        assert p.add(float(x + 1), np.array([x, y, 0.0]), topics.FRAME_PLATE) is None
    narrow = ImpactPoints(lambda: (1.0, 0.4), timeout_s=0.03)
    assert narrow.add(1.0, np.array([1.2, 0.0, 0.0]), topics.FRAME_PLATE) is not None
    assert narrow.add(1.0, np.array([0.5, 0.3, 0.0]), topics.FRAME_PLATE) is not None
    assert narrow.refused_count == 2


def test_a_flood_of_bad_values_is_a_few_counts():
    """A thousand bad values of one field are one reason with its count (bounded memory)."""
    p = points()
    for k in range(1000):
        p.add(float(k), np.array([2.0 + k, 0.0, 0.0]), topics.FRAME_PLATE)
    assert list(p.refused.values()) == [1000]
