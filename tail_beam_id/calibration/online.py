"""``id_node`` calibrating itself on its own first minutes of data (docs/calibration.md, online
calibration).

What ``tail-beam calibrate BAG`` does offline (tail_beam_id.calibration.offline: the beam's sway in
the
jack pressure gives the oil column, the IMU's answer to the impacts the beam inertia), done on
the first ``learn_s`` of stamp time the node hands its identifier. Until then labels say
``calibrated: false``; once the profile is found the identifier decides with it (labels say
``calibrated: true``), and the log says what was measured, or that nothing clear was and the
node stays on config/. The work (a replay of the learned window) runs in a worker thread, so
that the node keeps taking messages meanwhile.

A profile is taken only when the sway it read is clear as ``tail-beam calibrate`` judges it
(a spectral peak standing MIN_PEAK_RATIO above the band, resolved, one the support's oil column
can give) and was rung by the impacts of the window: at least MIN_IMPACTS impacts identified
in it. A steady tone in the jack pressure with nothing striking the beam is no sway.
:meth:`OnlineCalibration.restart` (a new time base) forgets what was learned.

Pure: no ROS. :class:`tail_beam_id.ros.arrival.GatedIdentifier` records into it what it releases.
"""

from __future__ import annotations

from collections.abc import Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from tail_beam_id.calibration.offline import (
    MIN_IMPACTS,
    SupportProfile,
    calibrate,
    with_profile,
)
from tail_beam_sim.physics.sensors import ImuStream, PressureStream, Rebound

if TYPE_CHECKING:
    from tail_beam_id.methods import Method
    from tail_beam_id.stream.label import Label
    from tail_beam_id.stream.release import Release


@dataclass(frozen=True)
class Calibrated:
    """The outcome: the profile, and (when it holds a sway) the parameters and method to use."""

    profile: SupportProfile
    model_params: dict[str, Any] | None
    method: Method | None  # rebuilt when the method depends on the support (physics), else None
    impacts: int = 0  # impacts the calibration pass identified in the learned window


class OnlineCalibration:
    """Learns a support profile from the first ``learn_s`` (stamp s) of released data."""

    def __init__(
        self, params: Mapping[str, Any], learn_s: float, method: str, background: bool = True
    ) -> None:
        """``params``: the node's merged parameters (nominal support); ``method``: the
        identification method in use; ``background``: compute in a worker thread (the node)
        or at once (tests)."""
        self.params = params
        self.learn_s = learn_s
        self.method_name = method
        self.background = background
        self.state = "learning"  # learning -> calibrating -> done
        self.result: Calibrated | None = None
        self._pressure: list[tuple[np.ndarray, np.ndarray]] = []
        self._imu: list[tuple[np.ndarray, np.ndarray]] = []
        self._rebounds: list[tuple[float, np.ndarray]] = []
        self._first_s: float | None = None
        self._last_s = -np.inf
        self._future: Future[Calibrated] | None = None
        self._pool: ThreadPoolExecutor | None = None

    def restart(self) -> None:
        """A new time base: forget what was recorded or learned and learn again from its first
        ``learn_s`` (a calibration still computing is abandoned)."""
        if self._pool is not None:
            self._pool.shutdown(wait=False)
        self.state = "learning"
        self.result = None
        self._pressure, self._imu, self._rebounds = [], [], []
        self._first_s = None
        self._last_s = -np.inf
        self._future = None
        self._pool = None

    def record(self, release: Release) -> None:
        """Keep what the identifier was just given, while learning."""
        if self.state != "learning":
            return
        for name, (stamps, values) in release.streams.items():
            if not stamps.size:
                continue
            if name == "jack_pressure":
                self._pressure.append((stamps, values[:, 0]))
            elif name == "imu":
                self._imu.append((stamps, values))
            else:
                continue  # the vibration: the profile is read from the IMU and the jack
            self._first_s = (
                float(stamps[0]) if self._first_s is None else min(self._first_s, float(stamps[0]))
            )
            self._last_s = max(self._last_s, float(stamps[-1]))
        self._rebounds += list(release.rebounds)

    def poll(self) -> str | None:
        """Advance; a line for the log when something happened."""
        if (
            self.state == "learning"
            and self._first_s is not None
            and self._last_s - self._first_s >= self.learn_s
        ):
            self.state = "calibrating"
            pressure, imu, rebounds = self._streams()
            self._pressure, self._imu, self._rebounds = [], [], []
            if self.background:
                self._pool = ThreadPoolExecutor(1, thread_name_prefix="calibration")
                self._future = self._pool.submit(self._calibrate, pressure, imu, rebounds)
            else:
                self._future = Future()
                self._future.set_result(self._calibrate(pressure, imu, rebounds))
            return (
                f"calibration: learning done ({self.learn_s:g} s of data, {len(rebounds)} "
                "rebounds); measuring the support"
            )
        if self.state == "calibrating" and self._future is not None and self._future.done():
            self.state = "done"
            if self._pool is not None:
                self._pool.shutdown(wait=False)
            try:
                self.result = self._future.result()
            except Exception as exc:  # noqa: BLE001 - reported, the node goes on uncalibrated
                return (
                    f"calibration: failed ({type(exc).__name__}: {exc}); "
                    "staying on the configured support"
                )
            p = self.result.profile
            if self.result.model_params is None:
                return (
                    "calibration: no clear sway of the beam in the jack pressure rung by "
                    f"impacts (sway {_hz(p.rigid_mode_frequency_hz)}, oil column "
                    f"{'found' if p.oil_bulk_modulus_pa else 'none'}, {self.result.impacts} "
                    f"impacts of the {MIN_IMPACTS} needed); staying on the configured support "
                    "(labels say calibrated: false)"
                )
            gain = (
                f"{p.impacts_used} impacts for the IMU gain"
                if p.beam_inertia_about_hinge_kgm2
                else "IMU gain not measured"
            )
            return (
                f"calibration: sway {p.rigid_mode_frequency_hz:.2f} Hz, oil bulk modulus "
                f"{p.oil_bulk_modulus_pa:.3g} Pa, "
                f"{gain}, {p.describe_hysteresis()}; labels from here on say calibrated: true"
            )
        return None

    def _streams(self) -> tuple[PressureStream, ImuStream, list[Rebound]]:
        def joined(parts, width):
            if not parts:
                return np.zeros(0), np.zeros((0, width)) if width else np.zeros(0)
            return np.concatenate([t for t, _ in parts]), np.concatenate([v for _, v in parts])

        p_t, p_v = joined(self._pressure, 0)
        i_t, i_v = joined(self._imu, 6)
        pressure = PressureStream(p_t, p_v, 0.0)
        imu = ImuStream(i_t, i_v[:, :3], i_v[:, 3:], 0.0, 0.0)
        return (
            pressure,
            imu,
            [Rebound(stamp, velocity, velocity) for stamp, velocity in self._rebounds],
        )

    def _calibrate(
        self, pressure: PressureStream, imu: ImuStream, rebounds: list[Rebound]
    ) -> Calibrated:
        """The profile of the learned window (as ``tail-beam calibrate`` on a bag of it)."""
        from tail_beam_id.methods import build_method
        from tail_beam_id.stream.identifier import StreamIdentifier
        from tail_beam_id.stream.replay import replay

        impacts = [0]  # what the last calibration pass identified

        def identify(model_params: Mapping[str, Any]) -> list[Label]:
            labels = replay(
                StreamIdentifier("statistical", model_params["identification"], model_params),
                pressure,
                imu,
                rebounds,
            )
            impacts[0] = len(labels)
            return labels

        profile = calibrate(
            self.params,
            (pressure.stamp_s, pressure.pressure_pa),
            (imu.stamp_s, imu.linear_acceleration_mps2[:, 2]),
            identify,
        )
        clear = (
            profile.calibrated
            and profile.oil_bulk_modulus_pa is not None
            and impacts[0] >= MIN_IMPACTS
        )
        if not clear:
            return Calibrated(profile, None, None, impacts[0])
        merged = with_profile(self.params, profile)
        # The physics method holds the support; the statistical one, the support's hysteresis.
        rebuild = self.method_name == "physics" or (
            self.method_name == "statistical" and profile.hysteresis_weights is not None
        )
        method = build_method(self.method_name, merged) if rebuild else None
        return Calibrated(profile, merged, method, impacts[0])


def _hz(frequency_hz: float | None) -> str:
    return "none" if frequency_hz is None else f"{frequency_hz:.2f} Hz"
