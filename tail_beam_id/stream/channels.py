"""The identifier's three continuous sensor streams (jack pressure, IMU, tail-beam
accelerometer): taking their samples in, and knowing which of them are live.

A continuous stream whose newest stamp lags the newest of the others by more than
``stream_timeout_s`` is declared stopped. One that comes back (samples stamped after its stop
that keep up with the others) is taken up again once its pulse detector has had a sway and a
baseline window of the new samples; the stretch between is recorded as an outage, in which
the channel that stood in for it (the IMU, or the jack pressure) keeps finding the impacts.
Everything here depends on stamps only, never on arrival order or wall time.
"""

from __future__ import annotations

import math

import numpy as np

from tail_beam_id.stream.buffers import Series
from tail_beam_id.stream.config import IdentifierConfig
from tail_beam_sim.errors import InputError

# (declared stopped at, taken up again from) of each time a stream came back, s.
Outages = list[tuple[float, float]]


def within_outage(outages: Outages, stamp_s: float) -> bool:
    """``stamp_s`` lies within one of the (stopped at, taken up again from) stretches, s."""
    return any(stop < stamp_s < back for stop, back in outages)


class SensorChannels:
    """The jack pressure, IMU and vibration buffers, the samples refused from them, and when
    each acceleration channel was declared stopped or taken up again (module docstring)."""

    def __init__(self, config: IdentifierConfig) -> None:
        """``config``: its ``stream_timeout_s`` decides liveness; its detection's sway and
        baseline windows how long a channel that came back waits before its pulses count."""
        self.config = config
        self.pressure = Series()  # jack pressure, Pa
        self.imu = Series()  # angular velocity rad/s (3 columns), specific force m/s^2 (3)
        self.vibration = Series()  # tail-beam accelerometer, specific force along the normal
        # Samples with a non-finite stamp or value (a sensor's dropout, a corrupt message),
        # left out, by stream: a missing sample, as a lost message is, never a number.
        self.refused_samples = {"jack_pressure": 0, "imu": 0, "vibration": 0}
        self.vibration_start_s = math.inf  # first vibration stamp seen, s
        self.imu_stop_s = math.inf  # stamp after which the IMU was declared stopped, s
        self.vibration_stop_s = math.inf  # the same for the vibration stream, s
        # Each time the IMU came back; and of those, the ones the jack pressure stood in for
        # (no other acceleration channel live then).
        self.imu_outages: Outages = []
        self.pressure_outages: Outages = []
        # Each time the vibration stream came back: the IMU's pulses count there.
        self.vibration_outages: Outages = []

    # ---- input -------------------------------------------------------------------------------
    def add_pressure(self, stamp_s: np.ndarray, pressure_pa: np.ndarray) -> None:
        """Jack pressure samples: stamps (s), absolute pressure (Pa)."""
        stamps = np.atleast_1d(np.asarray(stamp_s, dtype=float))
        values = np.atleast_1d(np.asarray(pressure_pa, dtype=float)).reshape(-1, 1)
        if stamps.size != values.shape[0]:
            raise InputError(
                "pressure_pa", values.shape, f"must hold one value per stamp ({stamps.size})"
            )
        self.pressure.append(*self._finite("jack_pressure", stamps, values))

    def add_imu(
        self,
        stamp_s: np.ndarray,
        angular_velocity_radps: np.ndarray,
        linear_acceleration_mps2: np.ndarray,
    ) -> None:
        """IMU samples: stamps (s), angular velocity (T, 3) rad/s, specific force (T, 3) m/s^2."""
        stamps = np.atleast_1d(np.asarray(stamp_s, dtype=float))
        gyro = np.asarray(angular_velocity_radps, dtype=float).reshape(-1, 3)
        accel = np.asarray(linear_acceleration_mps2, dtype=float).reshape(-1, 3)
        if gyro.shape[0] != stamps.size or accel.shape[0] != stamps.size:
            raise InputError(
                "imu",
                (gyro.shape, accel.shape),
                f"must hold (T, 3) arrays for T = {stamps.size} stamps",
            )
        self.imu.append(*self._finite("imu", stamps, np.hstack([gyro, accel])))

    def add_vibration(self, stamp_s: np.ndarray, accel_mps2: np.ndarray) -> None:
        """High-rate tail-beam accelerometer samples: stamps (s, in order) and specific force
        along the plate normal (z of the plate frame), m/s^2."""
        stamps = np.atleast_1d(np.asarray(stamp_s, dtype=float))
        values = np.atleast_1d(np.asarray(accel_mps2, dtype=float)).reshape(-1, 1)
        if stamps.size != values.shape[0]:
            raise InputError(
                "vibration accel_mps2",
                values.shape,
                f"must hold one value per stamp ({stamps.size})",
            )
        stamps, values = self._finite("vibration", stamps, values)
        if stamps.size and self.vibration_start_s == math.inf:
            self.vibration_start_s = float(stamps[0])
        self.vibration.append(stamps, values)

    def _finite(
        self, name: str, stamps: np.ndarray, values: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The samples whose stamp and values are all finite; the others counted in
        ``refused_samples`` under ``name``."""
        ok = np.isfinite(stamps) & np.isfinite(values).all(axis=1)
        if ok.all():
            return stamps, values
        self.refused_samples[name] += int((~ok).sum())
        return stamps[ok], values[ok]

    # ---- liveness ----------------------------------------------------------------------------
    def newest_s(self) -> float:
        """The newest stamp of any continuous stream, s (-inf before any sample)."""
        return max(self.pressure.latest_s, self.imu.latest_s, self.vibration.latest_s)

    def continuous(self) -> tuple[Series, ...]:
        """The continuous streams: jack pressure, IMU, vibration."""
        return (self.pressure, self.imu, self.vibration)

    def vibration_in_use(self) -> bool:
        """The vibration stream is the acceleration channel (seen and not declared stopped)."""
        return self.vibration.seen and self.vibration_stop_s == math.inf

    def acceleration_in_use(self) -> Series:
        """The acceleration channel pulses are detected in: the vibration stream while it is
        in use, else the IMU."""
        return self.vibration if self.vibration_in_use() else self.imu

    def accel_seen(self) -> bool:
        """Any acceleration channel (IMU, vibration) has delivered a sample."""
        return self.imu.seen or self.vibration.seen

    def accel_stop_s(self) -> float:
        """Stamp after which no acceleration channel is live (inf while one is), s."""
        stops = [
            stop
            for series, stop in (
                (self.imu, self.imu_stop_s),
                (self.vibration, self.vibration_stop_s),
            )
            if series.seen
        ]
        return max(stops, default=math.inf)

    def live(self, series: Series, final: bool) -> bool:
        """A continuous stream is live unless never seen or lagging the newest stamp by more
        than ``stream_timeout_s`` (at the end of the data, ``final``, every seen one is)."""
        if not series.seen:
            return False
        return final or series.latest_s >= self.newest_s() - self.config.stream_timeout_s

    def update(self, final: bool) -> None:
        """Join the samples that came, declare the acceleration channels that fell behind
        stopped, and take up again those that came back."""
        for series in self.continuous():
            series.join()
        if self.imu.seen and not self.live(self.imu, final) and self.imu_stop_s == math.inf:
            self.imu_stop_s = self.imu.latest_s
        if (
            self.vibration.seen
            and not self.live(self.vibration, final)
            and self.vibration_stop_s == math.inf
        ):
            self.vibration_stop_s = self.vibration.latest_s
        self._vibration_resumed()
        self._imu_resumed()

    def _vibration_resumed(self) -> None:
        """Take the vibration stream up again when samples stamped after its stop come and it
        keeps up with the others (its driver restarted, its cable back). The IMU's pulses count
        from the stop until the detector has had a sway and a baseline window of the new
        samples (a step across the gap is no pulse); the accelerometer's from then on."""
        back = self._back_after_stop(self.vibration, self.vibration_stop_s)
        if back is not None:
            self.vibration_outages.append((self.vibration_stop_s, back))
            self.vibration_stop_s = math.inf

    def _imu_resumed(self) -> None:
        """The same for the IMU. With no accelerometer live, the jack pressure finds the
        impacts from the IMU's stop until it is back, and only there (``pressure_outages``);
        the IMU's pulses count from then on."""
        back = self._back_after_stop(self.imu, self.imu_stop_s)
        if back is not None:
            self.imu_outages.append((self.imu_stop_s, back))
            if self.accel_stop_s() < math.inf:  # no accelerometer live: the pressure stood in
                self.pressure_outages.append((self.imu_stop_s, back))
            self.imu_stop_s = math.inf

    def _back_after_stop(self, series: Series, stop_s: float) -> float | None:
        """When a stream declared stopped at ``stop_s`` (s) has samples after it again and
        keeps up with the others: the stamp from which its pulses count (its first new sample
        plus a sway and a baseline window, what the detector needs of them), s; else None."""
        if stop_s == math.inf or not series.latest_s > stop_s or not self.live(series, False):
            return None
        first = float(series.stamp_s[np.searchsorted(series.stamp_s, stop_s, side="right")])
        return (
            first + self.config.detection.sway_window_s + self.config.detection.baseline_window_s
        )

    # ---- memory ------------------------------------------------------------------------------
    def forget_before(self, oldest_needed_s: float, slack_s: float) -> None:
        """Drop each stream's samples older than ``oldest_needed_s`` (s), once its oldest lies
        more than ``slack_s`` (s) before that (trimming in steps, not on every call)."""
        for series in (self.imu, self.pressure, self.vibration):
            if series.stamp_s.size and series.stamp_s[0] < oldest_needed_s - slack_s:
                series.trim_before(oldest_needed_s)
