"""Streaming coal-gangue identification: buffers the three sensor streams, detects impacts,
and labels each one once the data it needs has arrived.

Determinism: every decision depends only on message stamps and contents. An impact is decided
once every live continuous stream (jack pressure, IMU) has passed its onset plus ``window_s``
and the camera has either delivered the impact's rebound or has had ``camera_timeout_s`` of
stamp time beyond the rebound window to do so. A continuous stream whose newest stamp lags the
newest of the others by more than ``stream_timeout_s`` is declared stopped; labels then say
which ``signals`` they used, and the methods' confidence falls with the signals they lose. An
acceleration channel that comes back is taken up again once its detector has had a sway and a
baseline window of the new samples (``vibration_outages``, ``imu_outages``); the channel that
stood in for it (the IMU, or the jack pressure) keeps the stretch between.

Acceleration channel: impacts are detected in the specific force along the plate normal. That
is the IMU's ``linear_acceleration.z`` unless a high-rate tail-beam accelerometer
(:meth:`StreamIdentifier.add_vibration`) is fed: while that vibration stream is live it is the
channel for pulse detection and the IMU impulse (labels name ``vibration`` in ``signals``
instead of ``imu``); the IMU's pulses count only before the vibration stream began and after
it stopped. The vibration stream is a continuous stream for liveness and timeouts.

Its parts live in modules of their own: the stream buffers (:mod:`tail_beam_id.stream.buffers`), the
pulse and pressure detectors (:mod:`tail_beam_id.signals`), impact association: rebounds,
overlap, the camera's side of readiness (:mod:`tail_beam_id.stream.association`), the methods and their
registry (:mod:`tail_beam_id.methods`), and the :class:`~tail_beam_id.stream.label.Label` it returns
(:func:`tail_beam_id.stream.label.make_label`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from tail_beam_id.methods import Decision, Method, build_method
from tail_beam_id.signals import mounting
from tail_beam_id.signals.camera import FramePeriod, may_be_slower
from tail_beam_id.signals.contact_fit import clipped_near, fit_contact
from tail_beam_id.signals.features import (
    VIBRATION_CHANNEL,
    BeamModel,
    PressureFit,
    fit_pressure,
    impact_features,
    imu_impulse,
)
from tail_beam_id.signals.imu_detection import Pulse, PulseDetector
from tail_beam_id.signals.pressure_detection import PressureDetector
from tail_beam_id.signals.timing import (
    DELAY_UNTRUSTED,
    OUTSIDE_NAME,
    UNUSUAL,
    SensorTiming,
    TimingConfig,
    judge,
)
from tail_beam_id.stream.association import ImpactAssociation, PendingImpact
from tail_beam_id.stream.buffers import Series
from tail_beam_id.stream.config import IdentifierConfig
from tail_beam_id.stream.label import Label, make_label
from tail_beam_sim.config import load_parameters
from tail_beam_sim.errors import InputError, require_range, require_section

MOUNT_SAMPLES = 16  # IMU samples whose median gravity reading gives the mounting's sign
VIBRATION_MOUNT_SAMPLES = (
    64  # accelerometer samples whose median gravity reading gives its mounting's sign
)


def _configured_frame_period_s(merged: Mapping[str, Any]) -> float | None:
    """The camera's frame period the parameters give (``sensors.camera_frame_rate_hz``), s; None
    when they give none."""
    rate = (merged.get("sensors") or {}).get("camera_frame_rate_hz")
    if rate is None:
        return None
    return 1.0 / require_range(
        "sensors.camera_frame_rate_hz", rate, 0.0, 1e6, low_open=True, unit="Hz"
    )


def _profile_frame_period_s(merged: Mapping[str, Any]) -> float | None:
    """The camera frame (s) a self-calibration pass read from the recording's rebound stamps
    (its profile's ``calibration.camera_frame_rate_hz``), or None: unlike sensors.camera_frame_rate_hz,
    a measurement, not a setting (config/'s 5 kHz is everyone's)."""
    rate = (merged.get("calibration") or {}).get("camera_frame_rate_hz")
    if not isinstance(rate, (int, float)) or not math.isfinite(rate) or rate <= 0.0:
        return None
    return 1.0 / float(rate)


def _inside(outages: list[tuple[float, float]], stamp_s: float) -> bool:
    """``stamp_s`` lies within one of the (stopped at, taken up again from) stretches, s."""
    return any(stop < stamp_s < back for stop, back in outages)


def _profile_says_timing_suspect(merged: Mapping[str, Any], config: TimingConfig) -> bool:
    """A self-calibration pass over the recording (its profile's ``calibration`` section) found
    its sensor timing suspect (tail_beam_id.signals.timing): then the labels are capped from the first."""
    calibration = merged.get("calibration") or {}
    checked, unusual = (
        calibration.get("delay_checked_impacts"),
        calibration.get("delay_unusual_impacts"),
    )
    if not isinstance(checked, int) or not isinstance(unusual, int):
        return False
    return judge(checked, unusual, config)


class StreamIdentifier:
    """Labels each impact in continuous sensor streams coal or gangue (docs/interface.md ``label``)."""

    def __init__(
        self,
        method: str | None = None,
        params: Mapping[str, Any] | None = None,
        model_params: Mapping[str, Any] | None = None,
        model_path: str | None = None,
        prebuilt: Method | None = None,
    ) -> None:
        """``params``: the ``identification`` section (None: shipped defaults); ``method``
        overrides its ``method``; ``model_params``: merged parameters holding the nominal
        ``support`` and ``materials`` (None: shipped defaults); ``prebuilt``: a method
        instance to reuse (many short streams) when its name is the method asked for."""
        defaults = None
        if params is None or model_params is None:
            defaults = load_parameters()
        section = dict(params if params is not None else defaults["identification"])  # type: ignore[index]
        if method is not None:
            section["method"] = method
        self.config = IdentifierConfig.from_params(section)
        merged = dict(model_params if model_params is not None else defaults)  # type: ignore[arg-type]
        merged["identification"] = section
        # A profile's section (tail-beam calibrate), read by the methods and here: a number or
        # text in its place is refused by name (it ended in an AttributeError).
        require_section("calibration", merged.get("calibration"))
        if prebuilt is not None and prebuilt.name == self.config.method:
            self.method = prebuilt
        else:
            self.method = build_method(self.config.method, merged, model_path)
        self.model = BeamModel.from_params(merged)
        # Whether the support parameters are a profile measured on this support (tail-beam
        # calibrate) rather than the nominal config/: the methods then use their calibrated models.
        self.calibrated = bool((merged.get("calibration") or {}).get("rigid_mode_frequency_hz"))
        self.pressure = Series()
        self.imu = Series()
        self.vibration = Series()  # high-rate accelerometer, specific force along the plate normal
        # Samples with a non-finite stamp or value (a sensor's dropout, a corrupt message), left out
        # by stream: one NaN pressure sample made a label "gangue" with confidence NaN.
        self.refused_samples = {"jack_pressure": 0, "imu": 0, "vibration": 0}
        sway_hz = self.model.support.rigid_mode_frequency_hz
        self.detector = PulseDetector(self.config.detection, sway_hz)
        self.vibration_detector = PulseDetector(self.config.detection, sway_hz)
        c = self.config
        self.pressure_detector = PressureDetector(
            self.model,
            c.detection.pressure_threshold_sigma,
            c.pressure_pre_s,
            c.window_s,
            c.detection.ring_window_s,
            c.detection.pressure_drift_confirm_sigma,
        )
        self.camera = FramePeriod(
            _configured_frame_period_s(merged)
        )  # the camera's frame period, s
        self.profile_frame_s = _profile_frame_period_s(
            merged
        )  # the frame self-calibration measured, s (None: not)
        # Pending impacts, rebounds, recent decisions; its rebound windows follow the camera's frame.
        self.impacts = ImpactAssociation(self.config, self.camera.period_at)
        self.timing = SensorTiming(
            self.config.timing, _profile_says_timing_suspect(merged, self.config.timing)
        )
        self.imu_stop_s = math.inf  # stamp after which the IMU was declared stopped
        # (declared stopped at, taken up again from) of each time the IMU came back, s; and of
        # those, the ones the jack pressure stood in for (no other acceleration channel live).
        self.imu_outages: list[tuple[float, float]] = []
        self._pressure_outages: list[tuple[float, float]] = []
        self.mount_sign: float | None = (
            None  # +1: IMU z along the plate normal; -1: mounted upside down
        )
        self.vibration_mount_sign: float | None = None  # the same for the tail-beam accelerometer
        self._mount_block_s: float | None = (
            None  # start of the next block the IMU comparison looks at, s
        )
        self.vibration_start_s = math.inf  # first vibration stamp seen
        self.vibration_stop_s = (
            math.inf
        )  # stamp after which the vibration stream was declared stopped
        # (declared stopped at, taken up again from) of each time the vibration stream came back
        # after a stop, s: the IMU's pulses count there (_vibration_resumed).
        self.vibration_outages: list[tuple[float, float]] = []
        self._held: list[Pulse] = []  # IMU pulses the vibration stream may yet cover

    def recalibrate(self, model_params: Mapping[str, Any], method: Method | None = None) -> None:
        """Decide from here on with a support profile measured on this support (``model_params``:
        the merged parameters with the profile in; ``method``: the method built for them, when
        it depends on the support). Pending impacts keep their data; only decisions change."""
        merged = dict(model_params)
        merged["identification"] = dict(
            merged.get("identification") or {}, method=self.config.method
        )
        self.model = BeamModel.from_params(merged)
        self.pressure_detector.model = self.model
        # The ringing the profile measured (tail_beam_id.calibration.modes) sets how long the detectors follow it.
        ring_decay = ((model_params.get("identification") or {}).get("detection") or {}).get(
            "ring_decay_s"
        )
        for detector in (self.detector, self.vibration_detector):
            detector.sway_frequency_hz = self.model.support.rigid_mode_frequency_hz
            if ring_decay is not None:
                detector.config = replace(detector.config, ring_decay_s=float(ring_decay))
        if method is not None:
            self.method = method
        self.calibrated = bool((merged.get("calibration") or {}).get("rigid_mode_frequency_hz"))
        self.profile_frame_s = _profile_frame_period_s(merged)

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
        along the plate normal (z of the plate frame), m/s^2. While this stream is live it
        replaces the IMU's linear_acceleration z for pulse detection and the IMU impulse."""
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
        ``refused_samples`` (a missing sample, as a lost message is, never a number)."""
        ok = np.isfinite(stamps) & np.isfinite(values).all(axis=1)
        if ok.all():
            return stamps, values
        self.refused_samples[name] += int((~ok).sum())
        return stamps[ok], values[ok]

    def add_rebound(self, stamp_s: float, velocity_mps: np.ndarray) -> None:
        """One rebound: the camera's stamp (s) and the particle's velocity (3,) in the plate frame
        (:meth:`ImpactAssociation.add_rebound`: a non-finite one is left out and counted)."""
        before = self.impacts.refused_rebounds
        self.impacts.add_rebound(stamp_s, velocity_mps)
        if self.impacts.refused_rebounds == before:
            self.camera.add(float(stamp_s))

    @property
    def refused_rebounds(self) -> int:
        """Rebounds with a non-finite stamp or velocity, left out."""
        return self.impacts.refused_rebounds

    # ---- output ------------------------------------------------------------------------------
    def poll(self) -> list[Label]:
        """Labels of the impacts now decidable, in impact_stamp order."""
        return self._run(final=False)

    def flush(self) -> list[Label]:
        """End of data: decide everything pending from what there is."""
        return self._run(final=True)

    def next_horizon_s(self) -> float:
        """Stamp the streams must pass before the earliest pending impact can be decided (its
        onset plus its data window), s; inf when nothing is pending. A live consumer polls as
        soon as its data is in (``id_node``'s wake) instead of on its next periodic tick."""
        return min(
            (i.onset_s + self.impacts.windows(i)[0] for i in self.impacts.pending),
            default=math.inf,
        )

    # ---- internals ---------------------------------------------------------------------------
    def _newest_s(self) -> float:
        return max(self.pressure.latest_s, self.imu.latest_s, self.vibration.latest_s)

    def _continuous(self) -> tuple[Series, ...]:
        return (self.pressure, self.imu, self.vibration)

    def _vibration_in_use(self) -> bool:
        """The vibration stream is the acceleration channel (seen and not declared stopped)."""
        return self.vibration.seen and self.vibration_stop_s == math.inf

    def _accel_seen(self) -> bool:
        return self.imu.seen or self.vibration.seen

    def _accel_stop_s(self) -> float:
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

    def _live(self, series: Series, final: bool) -> bool:
        """A continuous stream is live unless never seen or lagging by more than the timeout."""
        if not series.seen:
            return False
        return final or series.latest_s >= self._newest_s() - self.config.stream_timeout_s

    def _run(self, final: bool) -> list[Label]:
        for series in self._continuous():
            series.join()
        if self.imu.seen and not self._live(self.imu, final) and self.imu_stop_s == math.inf:
            self.imu_stop_s = self.imu.latest_s
        if (
            self.vibration.seen
            and not self._live(self.vibration, final)
            and self.vibration_stop_s == math.inf
        ):
            self.vibration_stop_s = self.vibration.latest_s
        self._vibration_resumed()
        self._imu_resumed()
        self._detect_pulses(final)
        self._rebound_impacts(final)
        self._pressure_impacts(final)
        self.impacts.pending.sort(key=lambda impact: impact.onset_s)
        labels: list[Label] = []
        while self.impacts.pending and (final or self._ready(self.impacts.pending[0])):
            impact = self.impacts.pending.pop(0)
            label = self._decide(impact)
            if label is not None:
                labels.append(label)
        self._trim()
        return labels

    def _vibration_resumed(self) -> None:
        """Take the vibration stream up again when samples stamped after its stop come and it
        keeps up with the others (its driver restarted, its cable back): it was declared stopped
        for good, and after a 300 ms gap the impacts were decided from the IMU and the
        accelerometer in turn, one of them twice. The IMU's pulses count from the stop until the
        detector has had a sway and a baseline window of the new samples (a step across the
        gap is no pulse); the accelerometer's count from then on."""
        back = self._back_after_stop(self.vibration, self.vibration_stop_s)
        if back is not None:
            self.vibration_outages.append((self.vibration_stop_s, back))
            self.vibration_stop_s = math.inf

    def _imu_resumed(self) -> None:
        """The same for the IMU: with the IMU alone, the jack pressure finds the impacts from its
        stop until it is back (and only there), the IMU's pulses count from then on; before, the
        pressure went on finding impacts beside the IMU's (1-2 extra labels in 20)."""
        back = self._back_after_stop(self.imu, self.imu_stop_s)
        if back is not None:
            self.imu_outages.append((self.imu_stop_s, back))
            if self._accel_stop_s() < math.inf:  # no accelerometer live: the pressure stood in
                self._pressure_outages.append((self.imu_stop_s, back))
            self.imu_stop_s = math.inf

    def _back_after_stop(self, series: Series, stop_s: float) -> float | None:
        """When a stream declared stopped at ``stop_s`` has samples after it again and keeps up
        with the others: the stamp from which its pulses count (its first new sample plus a
        sway and a baseline window, what the detector needs of them); else None."""
        if stop_s == math.inf or not series.latest_s > stop_s or not self._live(series, False):
            return None
        first = float(series.stamp_s[np.searchsorted(series.stamp_s, stop_s, side="right")])
        return (
            first + self.config.detection.sway_window_s + self.config.detection.baseline_window_s
        )

    def _accel_z(self) -> np.ndarray | None:
        """The IMU's specific force along the plate normal, the right way up (+g at rest).

        Self-calibration of the mounting: an IMU bolted upside down reads -g and every pulse with
        the opposite sign; the sign is read once, from gravity in the first ``MOUNT_SAMPLES``
        samples (their median: an impact among them cannot move it). None until then."""
        if self.mount_sign is None:
            if self.imu.stamp_s.size < MOUNT_SAMPLES:
                return None
            self.mount_sign = (
                -1.0 if float(np.median(self.imu.values[:MOUNT_SAMPLES, 5])) < 0.0 else 1.0
            )
        return self.imu.values[:, 5] * self.mount_sign

    def _vibration_z(self, final: bool = False) -> np.ndarray | None:
        """The accelerometer's specific force along the plate normal, the right way up; None
        until its mounting is known (:mod:`tail_beam_id.signals.mounting`).

        The sign is read once: from gravity in the median of the first
        ``VIBRATION_MOUNT_SAMPLES`` samples; for an AC-coupled sensor (no gravity), from the IMU
        beside it, block by block of ``mounting.BLOCK_S`` from the stream's start, once both
        streams have passed a block's end (so the answer does not depend on how the data came);
        without an IMU, or with no answer after ``mounting.GIVE_UP_S`` of data or at the end,
        as configured. Until then the accelerometer is not scanned: its data are kept, and its
        pulses found once the sign is known."""
        if self.vibration_mount_sign is None:
            if self.vibration.stamp_s.size < VIBRATION_MOUNT_SAMPLES and not final:
                return None
            sign = mounting.sign_from_gravity(
                self.vibration.values[:VIBRATION_MOUNT_SAMPLES, 0], self.model.support.gravity_mps2
            )
            if sign is None:
                sign = self._vibration_sign_from_imu(final)
            if sign is None:
                return None
            self.vibration_mount_sign = sign
        column = self.vibration.values[:, 0]
        return column if self.vibration_mount_sign > 0.0 else -column

    def _vibration_sign_from_imu(self, final: bool) -> float | None:
        """The AC-coupled accelerometer's sign from the IMU, block by block (``_vibration_z``);
        +1 (as configured) when it cannot be had; None while it may yet come."""
        imu_z = self._accel_z()
        if self._mount_block_s is None:
            self._mount_block_s = float(self.vibration.stamp_s[0])
        while imu_z is not None:
            end = self._mount_block_s + mounting.BLOCK_S
            complete = min(self.imu.latest_s, self.vibration.latest_s) >= end
            if not (complete or final):
                break
            sign = mounting.sign_from_imu(
                self.vibration.stamp_s,
                self.vibration.values[:, 0],
                self.imu.stamp_s,
                imu_z,
                self._mount_block_s,
                end if complete else math.inf,
            )
            if sign is not None:
                return sign
            if not complete:  # the end of the data: the last, partial block
                break
            self._mount_block_s = end
        waited = self.vibration.latest_s - float(self.vibration.stamp_s[0])
        imu_gone = not self.imu.seen and waited >= self.config.stream_timeout_s
        return 1.0 if final or imu_gone or waited >= mounting.GIVE_UP_S else None

    def _detect_pulses(self, final: bool) -> None:
        """Pulses of the acceleration channels: the vibration stream's, and the IMU's where the
        vibration stream does not cover them (before it began, after it stopped); an IMU pulse
        the vibration stream has not yet passed is held until it does or is declared stopped."""
        # A stream declared stopped gets no more samples: a pulse at its end is decided from what
        # there is now, before a rebound it should claim is taken for an impact of its own.
        vibration_ended = final or self.vibration_stop_s < math.inf
        vibration_z = self._vibration_z(vibration_ended) if self.vibration.stamp_s.size else None
        if vibration_z is not None:
            for pulse in self.vibration_detector.scan(
                self.vibration.stamp_s, vibration_z, self.vibration.base_index, vibration_ended
            ):
                if not _inside(self.vibration_outages, pulse.onset_s):
                    self.impacts.pending.append(
                        PendingImpact(onset_s=pulse.onset_s, pulse=pulse, channel="vibration")
                    )
        if self.vibration.seen:
            # IMU pulses already waiting from before the vibration stream was first seen.
            covered = [
                i
                for i in self.impacts.pending
                if i.channel == "imu"
                and i.pulse is not None
                and i.onset_s >= self.vibration_start_s
            ]
            self.impacts.pending = [
                i for i in self.impacts.pending if not any(i is c for c in covered)
            ]
            self._held += [i.pulse for i in covered]  # type: ignore[misc]
        accel_z = self._accel_z()
        if accel_z is not None:
            self._held += [
                pulse
                for pulse in self.detector.scan(
                    self.imu.stamp_s,
                    accel_z,
                    self.imu.base_index,
                    final or self.imu_stop_s < math.inf,
                )
                if not _inside(self.imu_outages, pulse.onset_s)
            ]
        held, self._held = self._held, []
        for pulse in held:
            covered = (
                self.vibration.seen
                and self.vibration_start_s
                <= pulse.onset_s
                <= min(self.vibration_stop_s, self.vibration.latest_s)
                and not _inside(self.vibration_outages, pulse.onset_s)
            )
            if covered:
                continue
            if self._vibration_in_use() and pulse.onset_s > self.vibration.latest_s and not final:
                self._held.append(pulse)  # the vibration stream may yet cover it, or stop first
            else:
                self.impacts.pending.append(PendingImpact(onset_s=pulse.onset_s, pulse=pulse))

    def _rebound_impacts(self, final: bool) -> None:
        """A rebound no IMU pulse can claim is an impact of its own (IMU stopped or absent, or
        the pulse lost in noise); its onset is put ``rebound_onset_lead_s`` before its stamp."""
        c = self.config.detection
        scanned = math.inf if final else self._imu_scanned_s()
        for stamp, velocity in self.impacts.rebounds:
            if stamp in self.impacts.used_rebounds:
                continue
            imu_gone = stamp > self._accel_stop_s() + c.max_contact_s
            imu_absent = not self._accel_seen() and (
                final or self._newest_s() >= stamp + self.config.stream_timeout_s
            )
            claimable = self.impacts.claimable(stamp)
            orphan = self._accel_seen() and scanned >= stamp + c.rebound_early_tolerance_s
            if (imu_gone or imu_absent or orphan) and not claimable:
                late = (
                    self.impacts.late_claimant(stamp)
                    if orphan and not imu_gone and self._camera_may_be_slower(stamp)
                    else None
                )
                if late is not None:
                    self.impacts.take_late_rebound(late, stamp, velocity)
                    continue
                self.impacts.used_rebounds.add(stamp)
                onset = stamp - c.rebound_onset_lead_s
                self.impacts.pending.append(
                    PendingImpact(
                        onset_s=onset, pulse=None, rebound=(stamp, velocity), source="rebound"
                    )
                )

    def _imu_absent(self, final: bool) -> bool:
        """No acceleration channel (IMU, vibration) at all, after the pressure has run
        ``stream_timeout_s`` without one."""
        if self._accel_seen() or not self.pressure.stamp_s.size:
            return False
        return (
            final
            or self.pressure.latest_s >= self.pressure.stamp_s[0] + self.config.stream_timeout_s
        )

    def _pressure_impacts(self, final: bool) -> None:
        """With the IMU stopped or absent, impacts found in the pressure (unless a rebound
        already stands for them)."""
        stop = self._accel_stop_s()
        # An IMU back after a stop: the pressure finishes the stretch it stood in for, no further.
        unfinished = (
            bool(self._pressure_outages)
            and self.pressure_detector.scanned_s <= self._pressure_outages[-1][1]
        )
        if stop == math.inf and not self._imu_absent(final) and not unfinished:
            return
        if stop < math.inf:
            self.pressure_detector.skip_to(
                stop
            )  # a new stop: the stretch since the last was the IMU's
        start = stop if stop < math.inf else -math.inf
        margin = self.config.detection.pressure_onset_uncertainty_s
        for onset in self.pressure_detector.scan(
            self.pressure.stamp_s, self.pressure.values[:, 0], start, final
        ):
            if (
                stop == math.inf
                and not self._imu_absent(final)
                and not _inside(self._pressure_outages, onset.onset_s)
            ):
                continue  # after the IMU came back: its pulses find the impacts there
            known = [
                i.onset_s for i in self.impacts.pending if i.source == "rebound"
            ] + self.impacts.decided
            if all(abs(onset.onset_s - t) > margin for t in known):
                self.impacts.pending.append(
                    PendingImpact(onset_s=onset.onset_s, pulse=None, source="pressure")
                )

    def _ready(self, impact: PendingImpact) -> bool:
        """Every live stream has passed the impact's data window, the acceleration channel has
        been scanned over its overlap window (and no held pulse lies in it), and the camera has
        settled (:meth:`ImpactAssociation.camera_settled`)."""
        window_s, _, overlap_s = self.impacts.windows(impact)
        horizon = impact.onset_s + window_s
        for series in self._continuous():
            if self._live(series, False) and series.latest_s < horizon:
                return False
        accel = self.vibration if self._vibration_in_use() else self.imu
        if self._live(accel, False) and self._imu_scanned_s() < impact.onset_s + overlap_s:
            return False
        if any(p.onset_s < impact.onset_s + overlap_s for p in self._held):
            return False
        if self._late_rebound_undecided(impact):
            return False
        return self.impacts.camera_settled(impact, self._newest_s())

    def _late_rebound_undecided(self, impact: PendingImpact) -> bool:
        """A rebound this impact may claim late (ImpactAssociation.late_claimant) has come, but
        the acceleration channel has not yet been scanned past it: a pulse there would make it
        that impact's instead. The impact waits (it would otherwise be decided without the
        camera, and the rebound become an impact of its own)."""
        if (
            impact.pulse is None
            or impact.rebound is not None
            or self.config.detection.late_rebound_max_s <= 0.0
        ):
            return False
        accel = self.vibration if self._vibration_in_use() else self.imu
        if not self._live(accel, False):
            return False
        settled_s = self._imu_scanned_s() - self.config.detection.rebound_early_tolerance_s
        # The same conditions _rebound_impacts will claim it on, the camera's frame as known at
        # the rebound's own stamp.
        return any(
            stamp not in self.impacts.used_rebounds
            and stamp > settled_s
            and not self.impacts.claimable(stamp)
            and self._camera_may_be_slower(stamp)
            and self.impacts.late_claimant(stamp) is impact
            for stamp, _ in self.impacts.rebounds
        )

    def _camera_may_be_slower(self, stamp_s: float) -> bool:
        """Whether the camera may be slower than its frame is known to be at ``stamp_s``
        (tail_beam_id.signals.camera.may_be_slower): measured from the stamps so far, else by the
        self-calibration pass. A camera known to be fast stamps no rebound after its window:
        one that comes there is another impact's (or a slow IMU's onset came early), not late."""
        measured = self.camera.measured_at(stamp_s)
        return may_be_slower(measured if measured is not None else self.profile_frame_s)

    def _imu_scanned_s(self) -> float:
        """Stamp up to which the detector has examined the acceleration channel in use (the
        vibration stream while it is live, else the IMU), s."""
        if self._vibration_in_use():
            return self._scanned_s(self.vibration, self.vibration_detector)
        return self._scanned_s(self.imu, self.detector)

    @staticmethod
    def _scanned_s(series: Series, detector: PulseDetector) -> float:
        """Stamp up to which ``detector`` has examined ``series``, s."""
        local = detector.cursor - series.base_index - 1
        if local < 0 or not series.stamp_s.size:
            return -math.inf
        return float(series.stamp_s[min(local, series.stamp_s.size - 1)])

    def _decide(self, impact: PendingImpact) -> Label | None:
        started = time.perf_counter()
        cfg = self.config
        self.impacts.take_rebound(impact)
        overlap = self.impacts.overlapping(impact)
        onset = impact.onset_s
        if impact.rebound is not None and not impact.late_rebound:
            before = cfg.detection.onset_before_rebound_max_s + self.impacts.slow_camera_s(
                impact.onset_s
            )
            onset = max(onset, impact.rebound[0] - before)
        window_s, post_s, _ = self.impacts.windows(impact)
        fit: PressureFit | None = None
        if self.pressure.stamp_s.size:
            fit = fit_pressure(
                self.model,
                self.pressure.stamp_s,
                self.pressure.values[:, 0],
                onset,
                cfg.pressure_pre_s,
                window_s,
            )
        if impact.pulse is not None and impact.rebound is None:
            ringing = any(
                0.0 < impact.onset_s - t < cfg.detection.ring_window_s
                for t in self.impacts.decided
            )
            weak = (
                impact.pulse.peak_sigma < cfg.detection.unconfirmed_pulse_sigma
                and not self._pressure_confirms(fit)
            )
            if ringing or weak:
                return None  # the beam still ringing, or noise: nothing else saw an impact
        impulse = contact = None
        saturated = ["jack_pressure"] if fit is not None and fit.saturated else []
        if impact.pulse is not None:
            series, values = (
                (self.vibration, self._vibration_z())
                if impact.channel == "vibration"
                else (self.imu, self._accel_z())
            )
            impulse = imu_impulse(
                self.model,
                series.stamp_s,
                values,
                impact.pulse,
                cfg.impulse_pre_s,
                cfg.impulse_skip_s,
                post_s,
            )
            contact = fit_contact(
                series.stamp_s,
                values,
                impact.pulse.onset_s,
                impact.pulse.period_s,
                impact.pulse.noise_mps2,
                cfg.contact_fit,
            )
            if clipped_near(series.stamp_s, values, impact.pulse.onset_s, cfg.contact_fit):
                saturated.append(impact.channel)
        features = impact_features(self.model, impact.pulse, impulse, fit, impact.rebound, contact)
        signals = []
        if fit is not None and not fit.saturated:
            signals.append("jack_pressure")
        if impact.pulse is not None:
            signals.append(impact.channel)
        if impact.rebound is not None:
            signals.append("rebound_velocity")
        if self.calibrated:
            features["support_calibrated"] = 1.0
        if impact.rebound is not None:
            frame_period = self.camera.period_at(impact.rebound[0])
            if impact.late_rebound:
                # Stamped after the window the known frame allows: the frame is at least the
                # delay from the onset (erring long only makes the decision less sure).
                frame_period = max(
                    frame_period or 0.0,
                    impact.rebound[0] - impact.onset_s,
                    features.get("rebound_delay_s", 0.0),
                )
                features["rebound_late"] = 1.0
            if frame_period is not None:
                features["camera_frame_period_s"] = frame_period
        if impulse is not None and impact.channel == "vibration":
            # The imu_* features came from the accelerometer (anti-alias filtered point samples,
            # not the IMU's period means): the physics method keeps a lag model of its own for it.
            features[VIBRATION_CHANNEL] = 1.0
        decision: Decision = self.method.decide(features)
        timing_suspect = False
        if UNUSUAL in decision.estimates:
            self.timing.add(decision.estimates[UNUSUAL] > 0.5)
            timing_suspect = self.timing.suspect
            if timing_suspect:
                decision = self._decide_without_the_delay(features, decision)
        if (
            decision.signals is not None
        ):  # the label says what the decision rested on (a pulse whose duration was not read: not it)
            signals = [
                s
                for s in signals
                if ("imu" if s in ("imu", "vibration") else s) in decision.signals
            ]
        confidence = decision.confidence
        if overlap:
            confidence = min(confidence, cfg.overlap_confidence_cap)
        if timing_suspect:
            confidence = min(confidence, cfg.timing.confidence_cap)
            decision = replace(
                decision, outside_training=(*decision.outside_training, OUTSIDE_NAME)
            )
        self.impacts.decided.append(impact.onset_s)
        horizon = self.impacts.data_horizon_s(impact)
        return make_label(
            impact_stamp_s=onset,
            decision=decision,
            confidence=confidence,
            method=self.method.name,
            compute_ms=(time.perf_counter() - started) * 1e3,
            data_latency_ms=(horizon - onset) * 1e3,
            signals=signals,
            overlap=overlap,
            calibrated=self.calibrated,
            features=features,
            saturated=saturated,
            imu_inverted=self.mount_sign is not None and self.mount_sign < 0,
            vibration_inverted=impact.channel == "vibration"
            and self.vibration_mount_sign is not None
            and self.vibration_mount_sign < 0,
        )

    def _decide_without_the_delay(
        self, features: dict[str, float], decision: Decision
    ) -> Decision:
        """The decision of the method's twin without the rebound delay, once the recording's
        delays are found unlike the training's (the camera's and the acceleration channel's clocks
        offset: tail_beam_id.signals.timing): a delay shifted by an offset pushes every label one way,
        while the other signals still tell the materials apart (a camera 0.5 ms late: 64.0 %
        capped, 86.5 % by the twin; bench_robustness.py). Sets ``delay_untrusted`` in
        ``features``. Keeps the delay check's own estimates (the calibration counts them), and
        ``decision`` as it is when the method has no such twin (it would read the delay again)."""
        untrusted = self.method.decide({**features, DELAY_UNTRUSTED: 1.0})
        if UNUSUAL in untrusted.estimates or not untrusted.signals:
            return decision
        features[DELAY_UNTRUSTED] = 1.0
        checked = {k: v for k, v in decision.estimates.items() if k in ("delay_residual", UNUSUAL)}
        return replace(untrusted, estimates={**untrusted.estimates, **checked})

    def _pressure_confirms(self, fit: PressureFit | None) -> bool:
        """The jack pressure saw a moment impulse ``pressure_confirm_sigma`` standard errors
        above zero at this onset."""
        threshold = self.config.detection.pressure_confirm_sigma
        return (
            fit is not None
            and not fit.saturated
            and fit.moment_impulse_nms > threshold * fit.sigma_nms
        )

    def _trim(self) -> None:
        """Drop data no pending or future decision can need (bounded memory on long streams):
        keeps four times the longest look-back (noise block, pressure fit) before the oldest
        pending onset, and never trims past what the IMU detector has not examined yet (a
        backlogged IMU may lag the pressure by more than that look-back: trimming by the newest
        stamp of any topic would cut into it and make the result depend on arrival order)."""
        keep_s = 4.0 * max(
            self.config.detection.noise_block_s, self.config.pressure_pre_s + self.config.window_s
        )
        horizon = self._newest_s()
        if self.imu.seen and self.imu_stop_s == math.inf:
            horizon = min(horizon, self._scanned_s(self.imu, self.detector))
        if self._vibration_in_use():
            horizon = min(horizon, self._scanned_s(self.vibration, self.vibration_detector))
        oldest_needed = (
            min(
                [i.onset_s for i in self.impacts.pending] + [p.onset_s for p in self._held],
                default=horizon,
            )
            - keep_s
        )
        if self.imu.stamp_s.size and self.imu.stamp_s[0] < oldest_needed - keep_s:
            self.imu.trim_before(oldest_needed)
        if self.pressure.stamp_s.size and self.pressure.stamp_s[0] < oldest_needed - keep_s:
            self.pressure.trim_before(oldest_needed)
        if self.vibration.stamp_s.size and self.vibration.stamp_s[0] < oldest_needed - keep_s:
            self.vibration.trim_before(oldest_needed)
        self.impacts.forget_before(oldest_needed)
