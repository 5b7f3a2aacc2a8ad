"""Shared helpers of the bag tests: synthetic contract records and a segmented bag writer run."""

from __future__ import annotations

import json

import numpy as np

from tail_beam_sim import topics
from tail_beam_sim.bags import records as bagio
from tail_beam_sim.bags.write import SegmentedBagWriter
from tail_beam_sim.physics.sensors import ImuStream, PressureStream

RATE_HZ = 1000.0


def records(n: int, start_s: float = 0.0):
    """n pressure and n IMU samples as bag records (topic, log ns, CDR bytes), stamp order."""
    stamps = start_s + np.arange(n) / RATE_HZ
    pressure = PressureStream(stamps, 20e6 + np.arange(n), 1e8)
    imu = ImuStream(stamps, np.zeros((n, 3)), np.tile([0.0, 0.0, 9.81], (n, 1)), 1e-6, 1e-4)
    out = list(bagio.pressure_msgs(pressure.stamp_s, pressure.pressure_pa, pressure.variance_pa2))
    out += list(
        bagio.imu_msgs(
            imu.stamp_s, imu.angular_velocity_radps, imu.linear_acceleration_mps2, 1e-6, 1e-4
        )
    )
    out.sort(key=lambda r: r[1])
    return [
        (topic, ns, bytes(bagio.TYPESTORE.serialize_cdr(msg, topics.MSG_TYPES[topic])))
        for topic, ns, msg in out
    ]


def write_segments(
    path, segments: list[list], storage: str = "mcap", close: bool = True
) -> SegmentedBagWriter:
    """Write records as segments of one bag (the last left open unless ``close``)."""
    writer = SegmentedBagWriter(path, storage)
    for index, segment in enumerate(segments):
        for topic, ns, data in segment:
            writer.write(topic, ns, data)
        if close or index < len(segments) - 1:
            writer.close_segment()
    if close:
        writer.close()
    return writer


def serialized(records_: list) -> list:
    """Bag records (topic, log ns, rosbags message) as (topic, log ns, CDR bytes)."""
    return [
        (topic, ns, bytes(bagio.TYPESTORE.serialize_cdr(msg, topics.MSG_TYPES[topic])))
        for topic, ns, msg in records_
    ]


def shifted(records_: list, shift_s: float) -> list:
    """Serialized records with every stamp (header, impact_truth) and log time ``shift_s``
    later."""
    out = []
    for topic, ns, data in records_:
        msg = bagio.TYPESTORE.deserialize_cdr(data, topics.MSG_TYPES[topic])
        if hasattr(msg, "header"):
            stamp = topics.stamp_ns(
                msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 + shift_s
            )
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
        elif topic == topics.IMPACT_TRUTH:
            truth = json.loads(msg.data)
            for key, value in truth.items():
                if key.endswith("_stamp") and isinstance(value, float):
                    truth[key] = value + shift_s
            msg = bagio.string_msg(truth)
        out.append(
            (
                topic,
                ns + int(round(shift_s * 1e9)),
                bytes(bagio.TYPESTORE.serialize_cdr(msg, topics.MSG_TYPES[topic])),
            )
        )
    return out


def string_record(topic: str, log_ns: int, text: str) -> tuple:
    """One serialized std_msgs/String record holding ``text``."""
    msg = bagio.string_msg(text)
    return topic, log_ns, bytes(bagio.TYPESTORE.serialize_cdr(msg, "std_msgs/msg/String"))
