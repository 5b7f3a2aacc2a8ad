"""A simulated flow (:class:`tail_beam_sim.physics.flow.FlowRecord`) as a rosbag2 bag: the sensor
topics, ``rebound_velocity``, ``impact_point`` (when the camera reports it), ``impact_truth``,
``gangue_share_truth`` and ``window_cmd``, stamped as sim_node publishes them, so a bag of an
offline flow reads like a recorded one."""

from __future__ import annotations

import os
from typing import Any

from tail_beam_sim import topics
from tail_beam_sim.bags.records import (
    BagRecord,
    point_msg,
    rebound_msg,
    stream_records,
    string_msg,
    write_bag,
)
from tail_beam_sim.physics.flow import FlowRecord


def flow_records(record: FlowRecord) -> list[BagRecord]:
    """Every bag record of ``record``: a window command at its stamp, a share interval at its
    end, a truth at its publishing stamp, a rebound and its impact point at its camera frame."""
    out: list[BagRecord] = []
    out.extend(stream_records(record.pressure, record.imu, record.vibration))
    out.extend(rebound_msg(r.stamp_s, r.velocity_mps) for _, r in record.rebounds)
    out.extend(point_msg(p.stamp_s, p.point_m) for _, p in record.points)
    out.extend(
        (topics.IMPACT_TRUTH, topics.stamp_ns(stamp), string_msg(truth))
        for stamp, truth in record.truths
    )
    out.extend(
        (topics.GANGUE_SHARE_TRUTH, topics.stamp_ns(s.end_stamp_s), string_msg(s.to_json()))
        for s in record.shares
    )
    out.extend(
        (topics.WINDOW_CMD, topics.stamp_ns(stamp), string_msg(window_json(action, stamp)))
        for stamp, action in record.windows
    )
    return out


def window_json(action: str, stamp_s: float) -> dict[str, Any]:
    """A window command as a bag of an offline flow holds it (its stamp, s, added)."""
    return {"action": action, "stamp_s": stamp_s}


def write_flow_bag(
    record: FlowRecord,
    path: str | os.PathLike[str],
    storage: str = "mcap",
    compression: str = "zstd",
    namespace: str = "/",
) -> int:
    """Write ``record`` as a new rosbag2 bag at ``path``; returns the message count."""
    return write_bag(path, flow_records(record), storage, compression, namespace)
