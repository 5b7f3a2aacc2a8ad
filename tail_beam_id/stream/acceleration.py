"""The specific force along the plate normal from each acceleration channel (the IMU's
``linear_acceleration.z``, the tail-beam accelerometer), the right way up (+g at rest).

Impacts are detected and their impulse read along the plate normal; a sensor bolted upside
down reads every pulse with the opposite sign. Each channel's mounting sign is read once and
then kept: the IMU's from gravity, the accelerometer's from gravity or, for an AC-coupled one
(no gravity), by comparing it with the IMU beside it (:mod:`tail_beam_id.signals.mounting`).
"""

from __future__ import annotations

import math

import numpy as np

from tail_beam_id.signals import mounting
from tail_beam_id.stream.channels import SensorChannels

IMU_MOUNT_SAMPLES = 16  # IMU samples whose median gravity reading gives the mounting's sign
VIBRATION_MOUNT_SAMPLES = 64  # accelerometer samples whose median gravity reading gives its sign
IMU_Z_COLUMN = 5  # linear_acceleration.z in the IMU's rows (3 angular velocity, then 3 force)


class PlateNormalAcceleration:
    """Each acceleration channel's specific force along the plate normal, m/s^2, and the
    mounting signs it was read with (module docstring)."""

    def __init__(self, channels: SensorChannels, gravity_mps2: float) -> None:
        """``channels``: the streams read; ``gravity_mps2``: the gravity a DC-coupled
        accelerometer reads at rest, m/s^2 (the support model's)."""
        self.channels = channels
        self.gravity_mps2 = gravity_mps2
        self.mount_sign: float | None = None  # +1: IMU z along the plate normal; -1: inverted
        self.vibration_mount_sign: float | None = None  # the same for the accelerometer
        self._next_block_s: float | None = None  # start of the next block compared, s

    @property
    def imu_inverted(self) -> bool:
        """The IMU is known to be mounted upside down."""
        return self.mount_sign is not None and self.mount_sign < 0

    @property
    def vibration_inverted(self) -> bool:
        """The tail-beam accelerometer is known to be mounted upside down."""
        return self.vibration_mount_sign is not None and self.vibration_mount_sign < 0

    def imu_z(self) -> np.ndarray | None:
        """The IMU's specific force along the plate normal, the right way up, m/s^2.

        The sign is read once, from gravity in the median of the first ``IMU_MOUNT_SAMPLES``
        samples (an impact among them cannot move it). None until there are that many."""
        imu = self.channels.imu
        if self.mount_sign is None:
            if imu.stamp_s.size < IMU_MOUNT_SAMPLES:
                return None
            gravity = float(np.median(imu.values[:IMU_MOUNT_SAMPLES, IMU_Z_COLUMN]))
            self.mount_sign = -1.0 if gravity < 0.0 else 1.0
        return imu.values[:, IMU_Z_COLUMN] * self.mount_sign

    def vibration_z(self, final: bool = False) -> np.ndarray | None:
        """The accelerometer's specific force along the plate normal, the right way up, m/s^2;
        None until its mounting is known.

        The sign is read once: from gravity in the median of the first
        ``VIBRATION_MOUNT_SAMPLES`` samples; for an AC-coupled sensor (no gravity), from the IMU
        beside it, block by block of ``mounting.BLOCK_S`` from the stream's start, once both
        streams have passed a block's end (so the answer does not depend on how the data came);
        without an IMU, or with no answer after ``mounting.GIVE_UP_S`` of data or at the end of
        the data (``final``), as configured (+1). Until then the accelerometer is not scanned:
        its data are kept, and its pulses found once the sign is known."""
        vibration = self.channels.vibration
        if self.vibration_mount_sign is None:
            if vibration.stamp_s.size < VIBRATION_MOUNT_SAMPLES and not final:
                return None
            sign = mounting.sign_from_gravity(
                vibration.values[:VIBRATION_MOUNT_SAMPLES, 0], self.gravity_mps2
            )
            if sign is None:
                sign = self._vibration_sign_from_imu(final)
            if sign is None:
                return None
            self.vibration_mount_sign = sign
        column = vibration.values[:, 0]
        return column if self.vibration_mount_sign > 0.0 else -column

    def _vibration_sign_from_imu(self, final: bool) -> float | None:
        """The AC-coupled accelerometer's sign from the IMU, block by block (``vibration_z``);
        +1 (as configured) when it cannot be had; None while it may yet come."""
        imu, vibration = self.channels.imu, self.channels.vibration
        imu_z = self.imu_z()
        if self._next_block_s is None:
            self._next_block_s = float(vibration.stamp_s[0])
        while imu_z is not None:
            end = self._next_block_s + mounting.BLOCK_S
            complete = min(imu.latest_s, vibration.latest_s) >= end
            if not (complete or final):
                break
            sign = mounting.sign_from_imu(
                vibration.stamp_s,
                vibration.values[:, 0],
                imu.stamp_s,
                imu_z,
                self._next_block_s,
                end if complete else math.inf,
            )
            if sign is not None:
                return sign
            if not complete:  # the end of the data: the last, partial block
                break
            self._next_block_s = end
        waited_s = vibration.latest_s - float(vibration.stamp_s[0])
        imu_gone = not imu.seen and waited_s >= self.channels.config.stream_timeout_s
        return 1.0 if final or imu_gone or waited_s >= mounting.GIVE_UP_S else None
