"""Writing the contract's messages to rosbag2 bags with ``rosbags`` (no ROS installation needed).

Messages are built as ``rosbags`` dataclasses of the ROS 2 Kilted type store, so a bag holds
the exact contract types and reads back with ``rosbags.highlevel.AnyReader`` or any other
rosbag2 reader. The log time of each message is its ``header.stamp`` (simulation time).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer, WriterError
from rosbags.typesys import Stores, get_typestore

from tail_beam_sim import topics
from tail_beam_sim.errors import InputError, require_new_path
from tail_beam_sim.physics.sensors import VibrationBlocks

TYPESTORE = get_typestore(Stores.ROS2_KILTED)
STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
COMPRESSIONS = (
    "zstd",
    "none",
)  # mcap chunk compression (rosbag2's zstd storage presets); sqlite3 files are never compressed


def open_writer(path: Path, storage: str, compression: str = "zstd") -> Writer:
    """A rosbags Writer of a new bag: with ``zstd`` on mcap, each chunk is zstd-compressed
    inside the file (MCAP chunk compression, as rosbag2's ``zstd_fast`` preset does), so the
    file stays a plain ``.mcap`` that every MCAP reader opens (a file-level ``.mcap.zstd`` would
    not). Not yet opened."""
    if compression not in COMPRESSIONS:
        raise InputError("compression", compression, f"must be one of {', '.join(COMPRESSIONS)}")
    writer = Writer(path, version=9, storage_plugin=STORAGES[storage])
    if compression == "zstd" and storage == "mcap":
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    return writer


_T = TYPESTORE.types
_Time = _T["builtin_interfaces/msg/Time"]
_Header = _T["std_msgs/msg/Header"]
_String = _T["std_msgs/msg/String"]
_FluidPressure = _T["sensor_msgs/msg/FluidPressure"]
_Imu = _T["sensor_msgs/msg/Imu"]
_LaserScan = _T["sensor_msgs/msg/LaserScan"]
_TwistStamped = _T["geometry_msgs/msg/TwistStamped"]
_Twist = _T["geometry_msgs/msg/Twist"]
_Vector3 = _T["geometry_msgs/msg/Vector3"]
_Quaternion = _T["geometry_msgs/msg/Quaternion"]
_PointStamped = _T["geometry_msgs/msg/PointStamped"]
_Point = _T["geometry_msgs/msg/Point"]

BagRecord = tuple[str, int, Any]  # (topic, log time ns, rosbags message)


def header(stamp_s: float, frame_id: str) -> Any:
    """A std_msgs/Header at ``stamp_s`` seconds of simulation time."""
    ns = topics.stamp_ns(stamp_s)
    return _Header(
        stamp=_Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id=frame_id
    )


def string_msg(payload: dict[str, Any] | str) -> Any:
    """A std_msgs/String holding ``payload`` (a dict is JSON-encoded)."""
    return _String(data=payload if isinstance(payload, str) else json.dumps(payload))


def pressure_msgs(
    stamp_s: np.ndarray, pressure_pa: np.ndarray, variance_pa2: float
) -> Iterator[BagRecord]:
    """jack_pressure messages, one per sample."""
    for stamp, value in zip(stamp_s.tolist(), pressure_pa.tolist()):
        msg = _FluidPressure(
            header=header(stamp, topics.FRAME_JACK), fluid_pressure=value, variance=variance_pa2
        )
        yield topics.JACK_PRESSURE, topics.stamp_ns(stamp), msg


def imu_msgs(
    stamp_s: np.ndarray,
    gyro_radps: np.ndarray,
    accel_mps2: np.ndarray,
    gyro_variance: float,
    accel_variance: float,
) -> Iterator[BagRecord]:
    """imu messages, one per sample; no orientation estimate (covariance[0] = -1, REP 145)."""
    no_orientation = np.zeros(9)
    no_orientation[0] = -1.0
    gyro_cov = np.diag([gyro_variance] * 3).ravel()
    accel_cov = np.diag([accel_variance] * 3).ravel()
    for stamp, w, a in zip(stamp_s.tolist(), gyro_radps.tolist(), accel_mps2.tolist()):
        msg = _Imu(
            header=header(stamp, topics.FRAME_IMU),
            orientation=_Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=no_orientation,
            angular_velocity=_Vector3(x=w[0], y=w[1], z=w[2]),
            angular_velocity_covariance=gyro_cov,
            linear_acceleration=_Vector3(x=a[0], y=a[1], z=a[2]),
            linear_acceleration_covariance=accel_cov,
        )
        yield topics.IMU, topics.stamp_ns(stamp), msg


def vibration_msgs(blocks: VibrationBlocks) -> Iterator[BagRecord]:
    """vibration messages, one per block of a
    :class:`tail_beam_sim.physics.sensors.VibrationBlocks`
    (sensor_msgs/LaserScan as docs/interface.md lays it out; log time = the first sample's
    stamp)."""
    edges = blocks.offsets()
    period = float(blocks.period_s)
    empty = np.empty(0, dtype=np.float32)
    for b in range(blocks.count):
        high, low = topics.index_words(int(blocks.first_index[b]))
        stamp = float(blocks.stamp_s[b])
        length = int(blocks.lengths[b])
        msg = _LaserScan(
            header=header(stamp, topics.FRAME_ACCELEROMETER),
            angle_min=high,
            angle_max=low,
            angle_increment=0.0,
            time_increment=period,
            scan_time=period * length,
            range_min=-float(blocks.range_mps2),
            range_max=float(blocks.range_mps2),
            ranges=np.asarray(blocks.accel_mps2[edges[b] : edges[b + 1]], dtype=np.float32),
            intensities=empty,
        )
        yield topics.VIBRATION, topics.stamp_ns(stamp), msg


def vibration_fields(msg: Any) -> tuple[int, float, np.ndarray, float, float]:
    """A decoded (rosbags) vibration message: (first sample index, stamp s, samples m/s^2
    float32, sample period s, measuring range m/s^2); InputError naming the field of a message
    that carries no block (tail_beam_sim.topics)."""
    stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
    samples = np.asarray(msg.ranges, dtype=np.float32)
    index, period, range_mps2 = topics.block_header(
        msg.angle_min, msg.angle_max, msg.time_increment, msg.range_max, samples.size
    )
    return index, stamp, samples, period, range_mps2


def rebound_msg(stamp_s: float, velocity_mps: np.ndarray) -> BagRecord:
    """The rebound_velocity message of one impact (plate frame, m/s)."""
    v = [float(x) for x in velocity_mps]
    twist = _Twist(linear=_Vector3(x=v[0], y=v[1], z=v[2]), angular=_Vector3(x=0.0, y=0.0, z=0.0))
    msg = _TwistStamped(header=header(stamp_s, topics.FRAME_PLATE), twist=twist)
    return topics.REBOUND_VELOCITY, topics.stamp_ns(stamp_s), msg


def point_msg(stamp_s: float, point_m: np.ndarray) -> BagRecord:
    """The impact_point message of one impact (plate frame, m; stamped as its rebound)."""
    p = [float(x) for x in point_m]
    msg = _PointStamped(
        header=header(stamp_s, topics.FRAME_PLATE), point=_Point(x=p[0], y=p[1], z=p[2])
    )
    return topics.IMPACT_POINT, topics.stamp_ns(stamp_s), msg


def write_bag(
    path: str | Path,
    records: Iterable[BagRecord],
    storage: str = "mcap",
    compression: str = "zstd",
    namespace: str = "/",
) -> int:
    """Write ``records`` (any order) to a new rosbag2 bag at ``path``; returns the count.

    Every contract topic gets a connection, even one with no message, so that a reader
    finds the full set of topics with their types; an optional one (``topics.OPTIONAL_TOPICS``:
    ``impact_point``) only when ``records`` hold its messages. Topics are stored fully
    qualified in ``namespace`` (``/imu``), as rosbag2 stores them.
    """
    if not isinstance(storage, str) or storage not in STORAGES:
        raise InputError("storage", storage, f"must be one of {', '.join(STORAGES)}")
    bag_path = require_new_path("bag", path)
    ordered = sorted(records, key=lambda r: r[1])
    present = {r[0] for r in ordered}
    writer = open_writer(bag_path, storage, compression)
    try:
        writer.open()
    except (OSError, WriterError) as exc:
        raise InputError(
            "bag", str(bag_path), f"cannot be created ({getattr(exc, 'strerror', None) or exc})"
        ) from None
    try:
        connections = {
            topic: writer.add_connection(
                topics.qualified(namespace, topic), msgtype, typestore=TYPESTORE
            )
            for topic, msgtype in topics.MSG_TYPES.items()
            if topic not in topics.OPTIONAL_TOPICS or topic in present
        }
        for topic, time_ns, msg in ordered:
            writer.write(
                connections[topic], time_ns, TYPESTORE.serialize_cdr(msg, topics.MSG_TYPES[topic])
            )
    except BaseException:
        writer.abort()
        raise
    writer.close()
    return len(ordered)


def stream_records(pressure: Any, imu: Any, vibration: Any) -> list[BagRecord]:
    """The bag records of the sensor streams (a PressureStream, an ImuStream and
    VibrationBlocks of tail_beam_sim.physics.sensors): every sample and block."""
    return [
        *pressure_msgs(pressure.stamp_s, pressure.pressure_pa, pressure.variance_pa2),
        *imu_msgs(
            imu.stamp_s,
            imu.angular_velocity_radps,
            imu.linear_acceleration_mps2,
            imu.gyro_variance,
            imu.accel_variance,
        ),
        *vibration_msgs(vibration),
    ]


def result_records(result: Any, command: dict[str, Any] | None = None) -> list[BagRecord]:
    """All bag records of one simulated impact: command, sensor streams, rebound (and impact
    point, when the camera reports it), truth.

    ``result`` is a :class:`tail_beam_sim.physics.simulate.SimulationResult`; ``command`` the
    ``impact_cmd`` JSON that asked for it (logged at the start of the recording).
    """
    records: list[BagRecord] = []
    if command is not None:
        records.append((topics.IMPACT_CMD, 0, string_msg(command)))
    records.extend(stream_records(result.pressure, result.imu, result.vibration))
    records.append(rebound_msg(result.rebound.stamp_s, result.rebound.velocity_mps))
    if getattr(result, "point", None) is not None:
        records.append(point_msg(result.point.stamp_s, result.point.point_m))
    end_stamp = result.contact_stamp_s + result.scene.window_s
    records.append((topics.IMPACT_TRUTH, topics.stamp_ns(end_stamp), string_msg(result.truth())))
    return records
