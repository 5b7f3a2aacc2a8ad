"""The topic contract (interface.md): names, message types and frames, in one place."""

from __future__ import annotations

IMPACT_CMD = "impact_cmd"
JACK_PRESSURE = "jack_pressure"
IMU = "imu"
REBOUND_VELOCITY = "rebound_velocity"
IMPACT_TRUTH = "impact_truth"
LABEL = "label"

MSG_TYPES: dict[str, str] = {
    IMPACT_CMD: "std_msgs/msg/String",
    JACK_PRESSURE: "sensor_msgs/msg/FluidPressure",
    IMU: "sensor_msgs/msg/Imu",
    REBOUND_VELOCITY: "geometry_msgs/msg/TwistStamped",
    IMPACT_TRUTH: "std_msgs/msg/String",
    LABEL: "std_msgs/msg/String",
}

FRAME_JACK = "tail_beam_jack"
FRAME_IMU = "tail_beam_imu"
FRAME_PLATE = "tail_beam_plate"


def stamp_ns(stamp_s: float) -> int:
    """Seconds of simulation time as integer nanoseconds (rounded, never negative)."""
    return max(0, int(round(stamp_s * 1e9)))
