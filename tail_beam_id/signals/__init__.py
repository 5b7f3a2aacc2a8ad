"""What one recording's signals say about each impact: pulses found in the IMU and the
accelerometer, the jack pressure's steps, the contact read-out, the camera's rebounds, the
sensors' mounting signs and whether their clocks agree. Pure numpy/scipy, no state across
impacts."""

__all__ = [
    "camera",
    "contact_fit",
    "features",
    "imu_detection",
    "mounting",
    "pressure_detection",
    "timing",
]
