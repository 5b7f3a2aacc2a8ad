"""What the support's sensors report, from a trajectory: noise-free signals and sampled streams.

* Jack pressure: the piston chamber's absolute pressure, point-sampled, clipped to the
  transducer's range (a saturated transducer reads its limit).
* IMU on the beam: angular velocity about y and specific force (acceleration minus gravity,
  so a plate at rest reads +g along z). Each sample is the mean over its sample period, as an
  integrating, alias-free accelerometer gives: a pulse shorter than a sample shows as its
  impulse, not as a spike caught by chance.
* Camera: the particle's velocity as it last leaves the plate, stamped at the first frame
  at or after separation.

Noise is Gaussian, seeded per sensor so that changing one rate leaves the others' noise alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tail_beam_sim.scene import SensorSpec
from tail_beam_sim.solvers.problem import Samples, Trajectory


@dataclass
class PressureStream:
    """Jack pressure samples: stamps (s, simulation time) and absolute pressure (Pa)."""

    stamp_s: np.ndarray
    pressure_pa: np.ndarray
    variance_pa2: float


@dataclass
class ImuStream:
    """IMU samples: stamps (s), angular velocity (rad/s, T x 3), specific force (m/s^2, T x 3)."""

    stamp_s: np.ndarray
    angular_velocity_radps: np.ndarray
    linear_acceleration_mps2: np.ndarray
    gyro_variance: float
    accel_variance: float


@dataclass
class Rebound:
    """The camera's rebound measurement: stamp (s) and velocity in the plate frame (m/s)."""

    stamp_s: float
    velocity_mps: np.ndarray  # (x along the beam, y, z along the outward normal)
    true_velocity_mps: np.ndarray


def specific_force_z(trajectory: Trajectory, samples: Samples) -> np.ndarray:
    """Noise-free, instantaneous specific force along the plate normal at the IMU, m/s^2."""
    structure = trajectory.problem.structure
    angle = structure.imu_slope_shape @ samples.q
    return structure.gravity_mps2 * np.cos(angle) - structure.imu_shape @ samples.qdd


def imu_samples(trajectory: Trajectory, t_s: np.ndarray, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free IMU readings averaged over (t - period, t]: gyro (T x 3), accel (T x 3)."""
    structure = trajectory.problem.structure
    now = trajectory.sample(t_s)
    before = trajectory.sample(t_s - period_s)
    slope, imu = structure.imu_slope_shape, structure.imu_shape
    angle = slope @ now.q
    gyro = np.zeros((t_s.size, 3))
    gyro[:, 1] = slope @ (now.q - before.q) / period_s
    accel = np.zeros((t_s.size, 3))
    rate = slope @ now.qd
    g = structure.gravity_mps2
    accel[:, 0] = -structure.imu_from_hinge_m * rate**2 - g * np.sin(angle)
    accel[:, 2] = g * np.cos(angle) - imu @ (now.qd - before.qd) / period_s
    return gyro, accel


def sample_grid(start_s: float, end_s: float, rate_hz: float) -> np.ndarray:
    """Sample instants k / rate_hz of the absolute clock that fall in [start_s, end_s]."""
    first = math.ceil(start_s * rate_hz - 1e-9)
    last = math.floor(end_s * rate_hz + 1e-9)
    return np.arange(first, last + 1) / rate_hz


class SensorSuite:
    """Samples a trajectory the way the support's sensors would, with seeded noise."""

    def __init__(self, spec: SensorSpec, seed: int | None = None) -> None:
        self.spec = spec
        pressure, imu, camera = np.random.SeedSequence(spec.seed if seed is None else seed).spawn(3)
        self._pressure_rng = np.random.default_rng(pressure)
        self._imu_rng = np.random.default_rng(imu)
        self._camera_rng = np.random.default_rng(camera)

    def pressure(self, trajectory: Trajectory, stamp_s: np.ndarray, contact_stamp_s: float) -> PressureStream:
        """Pressure samples at absolute stamps; the trajectory's t = 0 is ``contact_stamp_s``."""
        spec = self.spec
        state = trajectory.sample(stamp_s - contact_stamp_s)
        clean = trajectory.problem.structure.pressure_pa(state.q, state.qd)
        noisy = clean + self._pressure_rng.normal(0.0, spec.pressure_noise_pa, stamp_s.size)
        noisy = np.clip(noisy, spec.pressure_range_min_pa, spec.pressure_range_max_pa)
        return PressureStream(stamp_s, noisy, spec.pressure_noise_pa**2)

    def imu(self, trajectory: Trajectory, stamp_s: np.ndarray, contact_stamp_s: float) -> ImuStream:
        """IMU samples at absolute stamps, each averaged over its sample period."""
        spec = self.spec
        gyro, accel = imu_samples(trajectory, stamp_s - contact_stamp_s, 1.0 / spec.imu_rate_hz)
        gyro_sigma = spec.imu_gyro_noise_radps * spec.imu_noise_scale
        accel_sigma = spec.imu_accel_noise_mps2 * spec.imu_noise_scale
        gyro = gyro + self._imu_rng.normal(0.0, gyro_sigma, gyro.shape)
        accel = accel + self._imu_rng.normal(0.0, accel_sigma, accel.shape)
        return ImuStream(stamp_s, gyro, accel, gyro_sigma**2, accel_sigma**2)

    def rebound(self, trajectory: Trajectory, contact_stamp_s: float) -> Rebound:
        """The camera's view of the particle leaving the plate for the last time."""
        spec = self.spec
        true = np.array([0.0, 0.0, trajectory.rebound_velocity_mps])
        sigma = spec.camera_velocity_noise_mps + spec.camera_velocity_noise_fraction * abs(true[2])
        measured = true + self._camera_rng.normal(0.0, sigma, 3) * np.array([1.0, 0.0, 1.0])
        separation = contact_stamp_s + trajectory.final_separation_s
        stamp = math.ceil(separation * spec.camera_frame_rate_hz - 1e-9) / spec.camera_frame_rate_hz
        return Rebound(stamp, measured, true)
