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
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from tail_beam_sim import topics
from tail_beam_sim.errors import InputError

TYPESTORE = get_typestore(Stores.ROS2_KILTED)
STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}

_T = TYPESTORE.types
_Time = _T["builtin_interfaces/msg/Time"]
_Header = _T["std_msgs/msg/Header"]
_String = _T["std_msgs/msg/String"]
_FluidPressure = _T["sensor_msgs/msg/FluidPressure"]
_Imu = _T["sensor_msgs/msg/Imu"]
_TwistStamped = _T["geometry_msgs/msg/TwistStamped"]
_Twist = _T["geometry_msgs/msg/Twist"]
_Vector3 = _T["geometry_msgs/msg/Vector3"]
_Quaternion = _T["geometry_msgs/msg/Quaternion"]

BagRecord = tuple[str, int, Any]  # (topic, log time ns, rosbags message)


def header(stamp_s: float, frame_id: str) -> Any:
    """A std_msgs/Header at ``stamp_s`` seconds of simulation time."""
    ns = topics.stamp_ns(stamp_s)
    return _Header(stamp=_Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id=frame_id)


def string_msg(payload: dict[str, Any] | str) -> Any:
    """A std_msgs/String holding ``payload`` (a dict is JSON-encoded)."""
    return _String(data=payload if isinstance(payload, str) else json.dumps(payload))


def pressure_msgs(stamp_s: np.ndarray, pressure_pa: np.ndarray, variance_pa2: float) -> Iterator[BagRecord]:
    """jack_pressure messages, one per sample."""
    for stamp, value in zip(stamp_s.tolist(), pressure_pa.tolist()):
        msg = _FluidPressure(header=header(stamp, topics.FRAME_JACK), fluid_pressure=value, variance=variance_pa2)
        yield topics.JACK_PRESSURE, topics.stamp_ns(stamp), msg


def imu_msgs(
    stamp_s: np.ndarray, gyro_radps: np.ndarray, accel_mps2: np.ndarray, gyro_variance: float, accel_variance: float
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


def rebound_msg(stamp_s: float, velocity_mps: np.ndarray) -> BagRecord:
    """The rebound_velocity message of one impact (plate frame, m/s)."""
    v = [float(x) for x in velocity_mps]
    twist = _Twist(linear=_Vector3(x=v[0], y=v[1], z=v[2]), angular=_Vector3(x=0.0, y=0.0, z=0.0))
    msg = _TwistStamped(header=header(stamp_s, topics.FRAME_PLATE), twist=twist)
    return topics.REBOUND_VELOCITY, topics.stamp_ns(stamp_s), msg


def write_bag(path: str | Path, records: Iterable[BagRecord], storage: str = "mcap") -> int:
    """Write ``records`` (any order) to a new rosbag2 bag at ``path``; returns the count.

    Every contract topic gets a connection, even one with no message, so that a reader
    finds the full set of topics with their types.
    """
    if storage not in STORAGES:
        raise InputError("storage", storage, f"must be one of {', '.join(STORAGES)}")
    bag_path = Path(path)
    if bag_path.exists():
        raise InputError("bag", str(bag_path), "must not exist yet (rosbag2 writers create a new bag)")
    ordered = sorted(records, key=lambda r: r[1])
    with Writer(bag_path, version=9, storage_plugin=STORAGES[storage]) as writer:
        connections = {
            topic: writer.add_connection(topic, msgtype, typestore=TYPESTORE) for topic, msgtype in topics.MSG_TYPES.items()
        }
        for topic, time_ns, msg in ordered:
            writer.write(connections[topic], time_ns, TYPESTORE.serialize_cdr(msg, topics.MSG_TYPES[topic]))
    return len(ordered)


def result_records(result: Any, command: dict[str, Any] | None = None) -> list[BagRecord]:
    """All bag records of one simulated impact: command, sensor streams, rebound, truth.

    ``result`` is a :class:`tail_beam_sim.simulate.SimulationResult`; ``command`` the
    ``impact_cmd`` JSON that asked for it (logged at the start of the recording).
    """
    records: list[BagRecord] = []
    if command is not None:
        records.append((topics.IMPACT_CMD, 0, string_msg(command)))
    records.extend(pressure_msgs(result.pressure.stamp_s, result.pressure.pressure_pa, result.pressure.variance_pa2))
    imu = result.imu
    records.extend(imu_msgs(imu.stamp_s, imu.angular_velocity_radps, imu.linear_acceleration_mps2, imu.gyro_variance, imu.accel_variance))
    records.append(rebound_msg(result.rebound.stamp_s, result.rebound.velocity_mps))
    end_stamp = result.contact_stamp_s + result.scene.window_s
    records.append((topics.IMPACT_TRUTH, topics.stamp_ns(end_stamp), string_msg(result.truth())))
    return records
