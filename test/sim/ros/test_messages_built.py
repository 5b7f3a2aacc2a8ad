"""Stream messages built without their constructors (tail_beam_sim.ros.messages.assemble) are
the constructors' messages: equal and serialised byte for byte alike."""

from __future__ import annotations

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Quaternion, Vector3
from rclpy.serialization import serialize_message
from sensor_msgs.msg import FluidPressure, Imu
from std_msgs.msg import Header

from tail_beam_sim import topics
from tail_beam_sim.physics.sensors import ImuStream, PressureStream
from tail_beam_sim.ros import messages

pytestmark = pytest.mark.ros


def _stamps(n: int) -> np.ndarray:
    """Stamps on a 2 kHz grid with jitter, from 0 (the clock's start) to past 2^31 ns."""
    rng = np.random.default_rng(3)
    return np.concatenate(
        [[0.0, 1e-9, 2.5e-9], 4.0 + np.arange(n) / 2000.0 + rng.uniform(0, 1e-6, n)]
    )


def test_imu_and_pressure_messages_equal_what_the_constructors_build():
    stamps = _stamps(300)
    rng = np.random.default_rng(4)
    imu = ImuStream(
        stamps, rng.normal(size=(stamps.size, 3)), rng.normal(size=(stamps.size, 3)), 1e-4, 2e-3
    )
    pressure = PressureStream(stamps, rng.normal(3e7, 1e5, stamps.size), 1e6)
    built_imu = messages.imu_messages(imu)
    built_pressure = messages.pressure_messages(pressure)
    for k, t in enumerate(stamps.tolist()):
        header = Header(stamp=messages.time_msg(t), frame_id=topics.FRAME_IMU)
        w, a = imu.angular_velocity_radps[k].tolist(), imu.linear_acceleration_mps2[k].tolist()
        expected = Imu(
            header=header,
            orientation=Quaternion(w=1.0),
            orientation_covariance=[-1.0] + [0.0] * 8,
            angular_velocity=Vector3(x=w[0], y=w[1], z=w[2]),
            angular_velocity_covariance=np.diag([1e-4] * 3).ravel().tolist(),
            linear_acceleration=Vector3(x=a[0], y=a[1], z=a[2]),
            linear_acceleration_covariance=np.diag([2e-3] * 3).ravel().tolist(),
        )
        assert built_imu[k] == expected
        assert serialize_message(built_imu[k]) == serialize_message(expected)
        expected_pressure = FluidPressure(
            header=Header(stamp=messages.time_msg(t), frame_id=topics.FRAME_JACK),
            fluid_pressure=float(pressure.pressure_pa[k]),
            variance=1e6,
        )
        assert serialize_message(built_pressure[k]) == serialize_message(expected_pressure)


def test_a_built_message_is_refused_unless_every_field_is_given():
    with pytest.raises(ValueError, match="nanosec"):
        messages.assemble(Time, sec=1)
    with pytest.raises(ValueError, match="extra"):
        messages.assemble(Time, sec=1, nanosec=2, extra=3)
    assert messages.assemble(Time, sec=1, nanosec=2) == Time(sec=1, nanosec=2)
