"""The topic contract (docs/interface.md): names, message types and frames, in one place."""

from __future__ import annotations

import math

from tail_beam_sim.errors import InputError

IMPACT_CMD = "impact_cmd"
JACK_PRESSURE = "jack_pressure"
IMU = "imu"
VIBRATION = "vibration"
REBOUND_VELOCITY = "rebound_velocity"
IMPACT_POINT = "impact_point"
IMPACT_TRUTH = "impact_truth"
LABEL = "label"
WINDOW_CMD = "window_cmd"  # drawing-window commands (scenario.source flow)
GANGUE_SHARE_TRUTH = "gangue_share_truth"  # true gangue share per interval of a flow
WINDOW_STATE = "window_state"  # a caving window opened or closed, and why (caving_node)
CAVING_DECISION = "caving_decision"  # a closing rule's decision and what it rested on

MSG_TYPES: dict[str, str] = {
    IMPACT_CMD: "std_msgs/msg/String",
    JACK_PRESSURE: "sensor_msgs/msg/FluidPressure",
    IMU: "sensor_msgs/msg/Imu",
    VIBRATION: "sensor_msgs/msg/LaserScan",
    REBOUND_VELOCITY: "geometry_msgs/msg/TwistStamped",
    IMPACT_POINT: "geometry_msgs/msg/PointStamped",
    IMPACT_TRUTH: "std_msgs/msg/String",
    LABEL: "std_msgs/msg/String",
    WINDOW_CMD: "std_msgs/msg/String",
    GANGUE_SHARE_TRUTH: "std_msgs/msg/String",
    WINDOW_STATE: "std_msgs/msg/String",
    CAVING_DECISION: "std_msgs/msg/String",
}


# Topics a support publishes only when its sensors say so (sensors.camera_reports_impact_point): a
# bag written offline gets their connection only when it holds their messages.
OPTIONAL_TOPICS = (IMPACT_POINT,)


def qualified(namespace: str, name: str) -> str:
    """The fully qualified name of contract topic ``name`` in ``namespace`` (``/`` or
    ``/support_07``), as rosbag2 stores it: ``/imu``, ``/support_07/imu``."""
    return f"{namespace.rstrip('/')}/{name}" if namespace.strip("/") else f"/{name}"


def namespace_of(topic: str) -> str:
    """The namespace of a recorded topic name: ``/support_07/imu`` -> ``/support_07``,
    ``/imu`` and a relative ``imu`` -> ``/``."""
    head = topic.strip("/").rpartition("/")[0]
    return f"/{head}" if head else "/"


FRAME_JACK = "tail_beam_jack"
FRAME_IMU = "tail_beam_imu"
FRAME_PLATE = "tail_beam_plate"
FRAME_ACCELEROMETER = "tail_beam_accelerometer"

# A vibration block's running sample index travels exactly as two float32 integer words in
# LaserScan's angle_min (high) and angle_max (low): each word < 2**24 is exact in float32.
INDEX_WORD = 2**24


def index_words(first_index: int) -> tuple[float, float]:
    """(angle_min, angle_max) carrying a block's first sample index (0 <= index < 2**48)."""
    if not 0 <= first_index < INDEX_WORD**2:
        raise ValueError(f"sample index {first_index} outside [0, 2**48)")
    high, low = divmod(int(first_index), INDEX_WORD)
    return float(high), float(low)


def index_from_words(angle_min: float, angle_max: float) -> int:
    """The first sample index a vibration block carries in (angle_min, angle_max); InputError
    naming the field for a word that carries none (a message not from an accelerometer of the
    contract: NaN, negative, fractional or too large)."""
    for name, word in (("angle_min", angle_min), ("angle_max", angle_max)):
        value = float(word)
        if not (math.isfinite(value) and 0.0 <= value < INDEX_WORD and value == math.floor(value)):
            raise InputError(
                f"vibration.{name}",
                word,
                "must be a whole number in [0, 2**24): a word of the block's running sample index",
            )
    return int(angle_min) * INDEX_WORD + int(angle_max)


MAX_BLOCK_PERIOD_S = 1.0  # the slowest accelerometer a vibration block may come from: 1 Hz, s


def block_period_s(time_increment: float) -> float:
    """A vibration block's sample period (LaserScan time_increment), s; InputError unless in (0,
    1] s."""
    value = float(time_increment)
    if not (math.isfinite(value) and 0.0 < value <= MAX_BLOCK_PERIOD_S):
        raise InputError(
            "vibration.time_increment",
            time_increment,
            f"must be the sample period, in (0, {MAX_BLOCK_PERIOD_S:g}] s",
        )
    return value


def block_range_mps2(range_max: float) -> float:
    """A vibration block's measuring range (LaserScan range_max), m/s^2; InputError unless
    finite and > 0."""
    value = float(range_max)
    if not (math.isfinite(value) and value > 0.0):
        raise InputError(
            "vibration.range_max",
            range_max,
            "must be the accelerometer's measuring range, a finite number > 0 m/s^2",
        )
    return value


def block_samples(count: int) -> int:
    """A vibration block's sample count (len(ranges)); InputError for an empty one: it carries no
    block, and taken as one it would claim its index from the real block that comes there."""
    if count < 1:
        raise InputError(
            "vibration.ranges",
            f"{count} samples",
            "must hold at least one sample of the accelerometer",
        )
    return count


def block_header(
    angle_min: float, angle_max: float, time_increment: float, range_max: float, samples: int
) -> tuple[int, float, float]:
    """A vibration message's (first sample index, sample period s, measuring range m/s^2), each
    checked as :func:`index_from_words`, :func:`block_period_s` and :func:`block_range_mps2` do,
    and its sample count (``samples``) as :func:`block_samples`: the one reading of a block's
    header, for the topic and for bags."""
    index = index_from_words(angle_min, angle_max)
    period, range_mps2 = block_period_s(time_increment), block_range_mps2(range_max)
    block_samples(samples)
    return index, period, range_mps2


IMPACT_POINT_Z_TOLERANCE_M = 1e-9  # |point.z| above this is not the plate's surface, m


def impact_point_xy(
    frame_id: str, x_m: float, y_m: float, z_m: float, length_m: float, width_m: float
) -> tuple[float, float]:
    """An impact_point message's (along, across) position on the plate, m: the one reading of
    the topic and of bags. InputError naming the field for a message that is no point on the
    plate of ``length_m`` (from the hinge) by ``width_m`` (centred on the beam's axis): another
    frame than ``tail_beam_plate``, a coordinate not finite, z other than 0, x outside
    [0, length_m] or |y| above width_m / 2."""
    if frame_id != FRAME_PLATE:
        raise InputError(
            "impact_point.header.frame_id", frame_id, f"must be {FRAME_PLATE!r} (the plate frame)"
        )
    for name, value in (("x", x_m), ("y", y_m), ("z", z_m)):
        if not math.isfinite(float(value)):
            raise InputError(f"impact_point.point.{name}", value, "must be a finite number, m")
    if abs(float(z_m)) > IMPACT_POINT_Z_TOLERANCE_M:
        raise InputError("impact_point.point.z", z_m, "must be 0 m (the plate's surface)")
    if not 0.0 <= float(x_m) <= length_m:
        raise InputError(
            "impact_point.point.x",
            x_m,
            f"must be in [0, {length_m:g}] m (on the plate, from the hinge)",
        )
    if abs(float(y_m)) > 0.5 * width_m:
        raise InputError(
            "impact_point.point.y",
            y_m,
            f"must be in [{-0.5 * width_m:g}, {0.5 * width_m:g}] m (on the plate, across it)",
        )
    return float(x_m), float(y_m)


def stamp_ns(stamp_s: float) -> int:
    """Seconds of simulation time as integer nanoseconds (rounded, never negative)."""
    return max(0, int(round(stamp_s * 1e9)))
