"""IMU and jack-pressure pulse detection: where impacts start in the sensor streams."""

__all__ = ["imu", "pressure"]
