"""Numpy sensor chunks to rclpy messages and back: the one place that knows both.

Stamps are seconds of simulation time as floats on the numpy side and ``builtin_interfaces/Time``
(integer nanoseconds, :func:`tail_beam_sim.topics.stamp_ns`) on the message side. Frames and
covariance conventions follow docs/interface.md: no orientation estimate on the IMU
(``orientation_covariance[0] = -1``), diagonal noise covariances from the sensor's variance.
"""

from __future__ import annotations

import array
import importlib
import json
from collections.abc import Sequence
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PointStamped, Quaternion, TwistStamped, Vector3
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import FluidPressure, Imu, LaserScan
from std_msgs.msg import Header, String

from tail_beam_sim import topics
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.sensors import (
    ImpactPoint,
    ImuStream,
    PressureStream,
    Rebound,
    VibrationBlocks,
)

NO_ORIENTATION = [-1.0] + [0.0] * 8  # REP 145: element 0 = -1, the estimate is not provided


EVENT_QOS = QoSProfile(
    depth=100, reliability=ReliabilityPolicy.RELIABLE
)  # one message per impact or command
# What the nodes publish events (rebound_velocity, impact_truth, label) with: as EVENT_QOS, and
# transient-local, so that a subscriber asking for it (bag_recorder) also gets the last
# ``depth`` events published before it matched: a label published before the recorder had
# matched id_node was lost from the bag. Volatile subscribers (the contract's) match it too.
EVENT_PUBLISHER_QOS = QoSProfile(
    depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
EVENT_TOPICS = (
    topics.REBOUND_VELOCITY,
    topics.IMPACT_POINT,
    topics.IMPACT_TRUTH,
    topics.LABEL,
    topics.WINDOW_STATE,
    topics.CAVING_DECISION,
)
# impact_cmd as sim_node reads it: keep-all, so that a burst waits in the reader's history
# (reliable
# flow control slows the client) instead of keep-last overwriting what the node has not taken yet.
COMMAND_QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)


def stream_qos(depth: int) -> QoSProfile:
    """Reliable QoS of a sensor stream; ``depth`` 0 keeps all, so that a slow subscriber slows
    the publisher down (reliable flow control) instead of losing samples."""
    if depth == 0:
        return QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE)


SENSOR_TOPICS = (topics.JACK_PRESSURE, topics.IMU, topics.VIBRATION)


def sensor_writer_qos(depth: int, lossless: bool) -> QoSProfile:
    """QoS of a sensor topic's writer (SENSOR_TOPICS). Paced (``lossless`` False): best effort,
    as ROS sensor drivers publish (``qos_profile_sensor_data``), so that a slow reader loses
    only its own samples instead of holding the writer and every other reader up (reliable flow
    control). As fast as possible (``lossless``): reliable (:func:`stream_qos`), so that the
    writer waits for its readers and none loses a sample. ``depth`` 0 keeps all."""
    if lossless:
        return stream_qos(depth)
    if depth == 0:
        return QoSProfile(
            history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.BEST_EFFORT
        )
    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.BEST_EFFORT)


def sensor_reader_qos(depth: int, reliable: bool) -> QoSProfile:
    """QoS of a sensor topic's reader: reliable only against writers that all offer it (a
    reliable reader never matches a best-effort writer); ``depth`` 0 keeps all."""
    reliability = ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT
    if depth == 0:
        return QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=reliability)
    return QoSProfile(depth=depth, reliability=reliability)


def sensor_publisher(node: Any, msg_type: type, topic: str, depth: int, lossless: bool) -> Any:
    """A sensor topic's writer, with :func:`sensor_writer_qos`. A best-effort one leaves out
    rclpy's incompatible-QoS warning, said for every reliable reader on every topic, even
    those that switch to best effort at once (id_node, bag_recorder): the node warns of the
    readers that stay reliable instead (tail_beam_sim.ros.follow_qos.ReliableReaderWatch)."""
    qos = sensor_writer_qos(depth, lossless)
    if lossless:
        return node.create_publisher(msg_type, topic, qos)
    quiet = PublisherEventCallbacks(use_default_callbacks=False)
    return node.create_publisher(msg_type, topic, qos, event_callbacks=quiet)


def message_class(msgtype: str) -> type:
    """The rclpy class of a ``pkg/msg/Name`` type."""
    package, _, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def time_msg(stamp_s: float) -> Time:
    """builtin_interfaces/Time of ``stamp_s`` seconds of simulation time."""
    ns = topics.stamp_ns(stamp_s)
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def stamp_s(stamp: Time) -> float:
    """Seconds of a builtin_interfaces/Time."""
    return stamp.sec + stamp.nanosec * 1e-9


def header(stamp: float, frame_id: str) -> Header:
    return Header(stamp=time_msg(stamp), frame_id=frame_id)


def assemble(cls: type, **fields: Any) -> Any:
    """A message of ``cls`` with exactly ``fields``, built without its constructor.

    A generated rclpy message's constructor builds a default for every field, sub-messages
    included, even for the fields it is given, and checks each assignment: five times the cost
    of the message itself for an Imu, at thousands of messages a second. This fills the
    generated ``_<field>`` slots directly. Every field must be given, of the type the field
    takes (the values here come from numpy arrays of the right kinds); a test holds the result
    equal, serialised, to the constructor's."""
    expected = _FIELDS.get(cls)
    if expected is None:
        expected = _FIELDS[cls] = frozenset(s[1:] for s in cls.__slots__ if s != "_check_fields")
    if fields.keys() != expected:
        raise ValueError(f"{cls.__name__} takes exactly {sorted(expected)}, got {sorted(fields)}")
    msg = cls.__new__(cls)
    msg._check_fields = False
    for name, value in fields.items():
        setattr(msg, "_" + name, value)
    return msg


_FIELDS: dict[type, frozenset[str]] = {}


def times(stamp_s: np.ndarray) -> list[Time]:
    """builtin_interfaces/Time of each stamp (s of simulation time), as :func:`time_msg` gives
    it, the nanoseconds computed for all at once: a stream chunk has thousands of stamps."""
    ns = np.maximum(np.round(np.asarray(stamp_s, dtype=float) * 1e9), 0.0).astype(np.int64)
    sec, nanosec = np.divmod(ns, 1_000_000_000)
    return [assemble(Time, sec=a, nanosec=b) for a, b in zip(sec.tolist(), nanosec.tolist())]


def pressure_messages(stream: PressureStream) -> list[FluidPressure]:
    """One jack_pressure message per sample (Pa; variance in Pa^2)."""
    variance = float(stream.variance_pa2)
    frame = topics.FRAME_JACK
    return [
        assemble(
            FluidPressure,
            header=assemble(Header, stamp=t, frame_id=frame),
            fluid_pressure=p,
            variance=variance,
        )
        for t, p in zip(times(stream.stamp_s), stream.pressure_pa.tolist())
    ]


def imu_messages(stream: ImuStream) -> list[Imu]:
    """One imu message per sample: rad/s and m/s^2 in the IMU frame, no orientation. The
    messages of one call share their constant parts (orientation, covariances), which nothing
    changes."""
    orientation = Quaternion(w=1.0)
    no_orientation = np.array(NO_ORIENTATION)
    gyro_cov = np.diag([float(stream.gyro_variance)] * 3).ravel()
    accel_cov = np.diag([float(stream.accel_variance)] * 3).ravel()
    frame = topics.FRAME_IMU
    return [
        assemble(
            Imu,
            header=assemble(Header, stamp=t, frame_id=frame),
            orientation=orientation,
            orientation_covariance=no_orientation,
            angular_velocity=assemble(Vector3, x=w[0], y=w[1], z=w[2]),
            angular_velocity_covariance=gyro_cov,
            linear_acceleration=assemble(Vector3, x=a[0], y=a[1], z=a[2]),
            linear_acceleration_covariance=accel_cov,
        )
        for t, w, a in zip(
            times(stream.stamp_s),
            stream.angular_velocity_radps.tolist(),
            stream.linear_acceleration_mps2.tolist(),
        )
    ]


def _float32_array(values: np.ndarray) -> array.array:
    """A float32 sequence field's value from numpy, through its buffer (no object per sample)."""
    out = array.array("f")
    out.frombytes(np.ascontiguousarray(values, dtype=np.float32).tobytes())
    return out


def vibration_messages(blocks: VibrationBlocks) -> list[LaserScan]:
    """One ``vibration`` message (sensor_msgs/LaserScan, docs/interface.md) per block: stamp of
    the first sample, its running index in angle_min/angle_max, the sample period in
    time_increment, the block's duration in scan_time, the measuring range in range_min/max
    and the samples (m/s^2) in ranges."""
    out = []
    edges = blocks.offsets()
    period = float(blocks.period_s)
    for b in range(blocks.count):
        high, low = topics.index_words(int(blocks.first_index[b]))
        length = int(blocks.lengths[b])
        out.append(
            LaserScan(
                header=header(float(blocks.stamp_s[b]), topics.FRAME_ACCELEROMETER),
                angle_min=high,
                angle_max=low,
                angle_increment=0.0,
                time_increment=period,
                scan_time=period * length,
                range_min=-float(blocks.range_mps2),
                range_max=float(blocks.range_mps2),
                ranges=_float32_array(blocks.accel_mps2[edges[b] : edges[b + 1]]),
            )
        )
    return out


def vibration_blocks(
    messages: Sequence[LaserScan], refused: list[str] | None = None
) -> VibrationBlocks:
    """``vibration`` messages back to blocks, in arrival order (samples read through their
    buffers). The period and range are the first message's. A message that carries no block
    (its index words, period or range out of range: tail_beam_sim.topics), or whose period
    differs from the first one's, raises InputError naming the field; with ``refused``, it is
    left out instead and the reason appended there."""
    kept: list[tuple[LaserScan, int]] = []
    for m in messages:
        try:
            index, period, _ = topics.block_header(
                m.angle_min, m.angle_max, m.time_increment, m.range_max, len(m.ranges)
            )
            if kept and period != kept[0][0].time_increment:
                raise InputError(
                    "vibration.time_increment",
                    period,
                    f"must be the stream's sample period, {kept[0][0].time_increment:g} s",
                )
        except InputError as exc:
            if refused is None:
                raise
            refused.append(str(exc))
            continue
        kept.append((m, index))
    if not kept:
        return VibrationBlocks.empty()
    pieces = [np.frombuffer(m.ranges, dtype=np.float32) for m, _ in kept]
    first = kept[0][0]
    return VibrationBlocks(
        first_index=np.array([index for _, index in kept], dtype=np.int64),
        lengths=np.array([p.size for p in pieces], dtype=np.int64),
        stamp_s=np.array([stamp_s(m.header.stamp) for m, _ in kept]),
        accel_mps2=np.concatenate(pieces),
        period_s=float(first.time_increment),
        range_mps2=float(first.range_max),
    )


def rebound_message(rebound: Rebound) -> TwistStamped:
    """rebound_velocity: the particle's velocity leaving the plate, m/s, plate frame."""
    msg = TwistStamped(header=header(rebound.stamp_s, topics.FRAME_PLATE))
    v = [float(x) for x in rebound.velocity_mps]
    msg.twist.linear.x, msg.twist.linear.y, msg.twist.linear.z = v
    return msg


def point_message(point: ImpactPoint) -> PointStamped:
    """impact_point: where the particle struck, m, plate frame, stamped as its rebound."""
    msg = PointStamped(header=header(point.stamp_s, topics.FRAME_PLATE))
    msg.point.x, msg.point.y, msg.point.z = [float(x) for x in point.point_m]
    return msg


def point_values(msg: PointStamped) -> tuple[float, str, np.ndarray]:
    """impact_point back to (stamp_s, frame_id, point_m (3,)), unchecked."""
    p = msg.point
    return stamp_s(msg.header.stamp), msg.header.frame_id, np.array([p.x, p.y, p.z])


def string_message(payload: dict[str, Any]) -> String:
    """A std_msgs/String holding one JSON object."""
    return String(data=json.dumps(payload))


def clock_message(stamp: float) -> Clock:
    """rosgraph_msgs/Clock at ``stamp`` seconds of simulation time."""
    return Clock(clock=time_msg(stamp))


def pressure_arrays(messages: Sequence[FluidPressure]) -> tuple[np.ndarray, np.ndarray]:
    """jack_pressure messages back to (stamp_s (T,), pressure_pa (T,))."""
    stamps = np.array([stamp_s(m.header.stamp) for m in messages])
    return stamps, np.array([m.fluid_pressure for m in messages])


def imu_arrays(messages: Sequence[Imu]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """imu messages back to (stamp_s (T,), angular_velocity_radps (T,3),
    linear_acceleration_mps2 (T,3))."""
    stamps = np.array([stamp_s(m.header.stamp) for m in messages])
    gyro = np.array(
        [(m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z) for m in messages]
    ).reshape(-1, 3)
    accel = np.array(
        [
            (m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z)
            for m in messages
        ]
    ).reshape(-1, 3)
    return stamps, gyro, accel


def rebound_values(msg: TwistStamped) -> tuple[float, np.ndarray]:
    """rebound_velocity back to (stamp_s, velocity_mps (3,))."""
    v = msg.twist.linear
    return stamp_s(msg.header.stamp), np.array([v.x, v.y, v.z])
