"""Shared helpers of the bag tests: synthetic contract records and a segmented bag writer run."""

from __future__ import annotations

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
