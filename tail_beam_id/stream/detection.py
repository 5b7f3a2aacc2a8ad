"""Finding candidate impacts in the streams, three ways, each handed to the impact association
(:class:`tail_beam_id.stream.association.ImpactAssociation`) as a pending impact:

* a pulse in an acceleration channel: the vibration stream's while it is in use, the IMU's
  where the vibration stream does not cover it (before it began, after it stopped, in its
  outages);
* a camera rebound no pulse can claim (no acceleration channel live, or the pulse lost in
  noise), its onset put ``rebound_onset_lead_s`` before its stamp;
* a step in the jack pressure, only where no acceleration channel is live (or none was ever
  seen), and in the stretches the pressure stood in for an IMU that came back.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from tail_beam_id.signals.features import BeamModel
from tail_beam_id.signals.imu_detection import Pulse, PulseDetector
from tail_beam_id.signals.innovations import prediction_errors
from tail_beam_id.signals.pressure_detection import PressureDetector
from tail_beam_id.stream.acceleration import PlateNormalAcceleration
from tail_beam_id.stream.association import ImpactAssociation, PendingImpact
from tail_beam_id.stream.buffers import Series
from tail_beam_id.stream.camera_frame import CameraFrame
from tail_beam_id.stream.channels import SensorChannels, within_outage
from tail_beam_id.stream.config import IdentifierConfig


def scanned_s(series: Series, detector: PulseDetector) -> float:
    """Stamp up to which ``detector`` has examined ``series``, s (-inf before any)."""
    local = detector.cursor - series.base_index - 1
    if local < 0 or not series.stamp_s.size:
        return -math.inf
    return float(series.stamp_s[min(local, series.stamp_s.size - 1)])


class ImpactFinder:
    """The pulse and pressure detectors, and the rules for which of them (or the camera)
    stands for an impact where (module docstring)."""

    def __init__(
        self,
        config: IdentifierConfig,
        model: BeamModel,
        channels: SensorChannels,
        acceleration: PlateNormalAcceleration,
        association: ImpactAssociation,
        camera: CameraFrame,
    ) -> None:
        """``model``: the support the detectors follow (its sway frequency, the pressure's
        moment arm); the others: the parts of the identifier this one reads and feeds."""
        self.config = config
        self.channels = channels
        self.acceleration = acceleration
        self.association = association
        self.camera = camera
        sway_hz = model.support.rigid_mode_frequency_hz
        self.imu_detector = PulseDetector(config.detection, sway_hz)
        self.vibration_detector = PulseDetector(
            config.detection, sway_hz, config.detection.vibration_ring_fraction
        )
        self.pressure_detector = PressureDetector(
            model,
            config.detection.pressure_threshold_sigma,
            config.pressure_pre_s,
            config.window_s,
            config.detection.ring_window_s,
            config.detection.pressure_drift_confirm_sigma,
        )
        self.held: list[Pulse] = []  # IMU pulses the vibration stream may yet cover
        # The profile's one-step predictor of the accelerometer's ringing and its rate (Hz):
        # a second detector then scans what it leaves (signals.innovations) for the contacts
        # the vibration detector loses in ringing; its pulses wait in innovation_held, beside
        # the vibration detector's recent onsets.
        self.predictor: tuple[np.ndarray, float] | None = None
        self.innovation_detector = PulseDetector(
            config.detection, sway_hz, config.detection.vibration_ring_fraction
        )
        self.innovation_held: list[Pulse] = []
        self.found_onsets: list[float] = []

    def follow_profile(self, profile: Mapping[str, Any]) -> None:
        """Take the accelerometer's ringing predictor from a checked ``calibration`` section
        (config.check_profile), when it has one. A predictor taken mid-stream (a profile
        learnt online) starts where the vibration detector has got to: the impacts before are
        decided, and a second look at their samples would label them again. Pulses the old
        predictor found and that still wait are released as before; the same predictor again
        changes nothing."""
        coefficients = profile.get("vibration_predictor")
        rate_hz = profile.get("vibration_predictor_rate_hz")
        predictor = (
            (np.asarray(coefficients, dtype=float), float(rate_hz))
            if coefficients and rate_hz
            else None
        )
        same = (predictor is None and self.predictor is None) or (
            predictor is not None
            and self.predictor is not None
            and predictor[1] == self.predictor[1]
            and np.array_equal(predictor[0], self.predictor[0])
        )
        if same:
            return  # the same profile again: the second detector carries on as it was
        self.predictor = predictor
        detector = self.vibration_detector
        self.innovation_detector = PulseDetector(
            detector.config, detector.sway_frequency_hz, detector.fast_ring_fraction
        )
        self.innovation_detector.cursor = detector.cursor
        if predictor is None:
            # nothing releases them any more: they go with the predictor that found them
            self.innovation_held, self.found_onsets = [], []

    def _predicts(self, stamp_s: np.ndarray) -> bool:
        """The profile has a ringing predictor fitted at this stream's rate (within 1 %)."""
        if self.predictor is None or stamp_s.size < 2:
            return False
        period_s = self.vibration_detector.period_s or float(np.median(np.diff(stamp_s)))
        return abs(period_s * self.predictor[1] - 1.0) <= 0.01

    def _innovation_pulses(
        self, vibration_z: np.ndarray, found: list[Pulse], ended: bool
    ) -> None:
        """Pulses of what the ringing predictor leaves of the accelerometer's samples that the
        vibration detector did not find (no pulse of its onset within max_contact_s): the
        contacts inside another impact's ringing. Each waits until the vibration detector has
        scanned past it, so that whether it found the same contact is known whatever the
        chunking; then it becomes an impact of its own."""
        vibration = self.channels.vibration
        if not self._predicts(vibration.stamp_s):
            return
        tolerance_s = self.config.detection.max_contact_s
        self.found_onsets += [p.onset_s for p in found]
        self.innovation_held += self.innovation_detector.scan(
            vibration.stamp_s,
            prediction_errors(vibration_z, self.predictor[0]),  # type: ignore[index]
            vibration.base_index,
            ended,
        )
        known_s = (
            math.inf
            if ended
            else scanned_s(vibration, self.vibration_detector)
            - self.vibration_detector.lookback_s()
        )
        waiting = []
        for pulse in self.innovation_held:
            if pulse.onset_s + tolerance_s > known_s:
                waiting.append(pulse)
            elif not any(abs(t - pulse.onset_s) <= tolerance_s for t in self.found_onsets):
                if not within_outage(self.channels.vibration_outages, pulse.onset_s):
                    self.association.pending.append(
                        PendingImpact(onset_s=pulse.onset_s, pulse=pulse, channel="vibration")
                    )
        self.innovation_held = waiting
        # the first detector's onsets a pulse still waiting, or one the second detector is yet
        # to find (its onset no earlier than its scan's progress less its look-back), may meet
        coming_s = (
            scanned_s(vibration, self.innovation_detector) - self.innovation_detector.lookback_s()
        )
        oldest = min([p.onset_s for p in waiting] + [coming_s]) - tolerance_s
        self.found_onsets = [t for t in self.found_onsets if t >= oldest]

    def waiting_pulses(self) -> list[Pulse]:
        """Pulses found but not yet made impacts: the IMU's the vibration stream may yet cover,
        and the predictor's the vibration detector has not yet scanned past."""
        return self.held + self.innovation_held

    def recalibrate(self, model: BeamModel, ring_decay_s: float | None) -> None:
        """Follow a support measured on this support: its model (sway frequency, moment arm)
        and, when the profile measured it, how long the beam rings after an impact, s."""
        self.pressure_detector.model = model
        for detector in (self.imu_detector, self.vibration_detector, self.innovation_detector):
            detector.sway_frequency_hz = model.support.rigid_mode_frequency_hz
            if ring_decay_s is not None:
                detector.config = replace(detector.config, ring_decay_s=float(ring_decay_s))

    def find(self, final: bool) -> None:
        """Add the impacts the newest data show to the pending ones (``final``: the end of the
        data, every stream has said all it will)."""
        self._pulse_impacts(final)
        self.find_rebound_impacts(final)
        self._pressure_impacts(final)

    def accel_scanned_s(self) -> float:
        """Stamp up to which the acceleration channel in use (the vibration stream while it is
        in use, else the IMU) has been examined for pulses, s."""
        if self.channels.vibration_in_use():
            return scanned_s(self.channels.vibration, self.vibration_detector)
        return scanned_s(self.channels.imu, self.imu_detector)

    def onsets_known_s(self) -> float:
        """Stamp before which every pulse onset of the acceleration channel in use has been
        found, s: the scan's progress less how far before its trigger a pulse's onset may lie
        (:meth:`tail_beam_id.signals.imu_detection.PulseDetector.lookback_s`)."""
        if self.channels.vibration_in_use():
            known_s = self.accel_scanned_s() - self.vibration_detector.lookback_s()
            if self._predicts(self.channels.vibration.stamp_s):
                # the second detector's pulses become impacts too: its progress bounds as well
                # and a pulse of it still waiting is not known yet
                known_s = min(
                    known_s,
                    scanned_s(self.channels.vibration, self.innovation_detector)
                    - self.innovation_detector.lookback_s(),
                    *(math.nextafter(p.onset_s, -math.inf) for p in self.innovation_held),
                )
            return known_s
        return self.accel_scanned_s() - self.imu_detector.lookback_s()

    def _pulse_impacts(self, final: bool) -> None:
        """Pulses of the acceleration channels: the vibration stream's, and the IMU's where the
        vibration stream does not cover them (before it began, after it stopped); an IMU pulse
        the vibration stream has not yet passed is held until it does or is declared stopped."""
        channels, association = self.channels, self.association
        imu, vibration = channels.imu, channels.vibration
        # A stream declared stopped gets no more samples: a pulse at its end is decided from
        # what there is now, before a rebound it should claim is taken for an impact of its own.
        vibration_ended = final or channels.vibration_stop_s < math.inf
        vibration_z = (
            self.acceleration.vibration_z(vibration_ended) if vibration.stamp_s.size else None
        )
        if vibration_z is not None:
            found = self.vibration_detector.scan(
                vibration.stamp_s, vibration_z, vibration.base_index, vibration_ended
            )
            for pulse in found:
                if not within_outage(channels.vibration_outages, pulse.onset_s):
                    association.pending.append(
                        PendingImpact(onset_s=pulse.onset_s, pulse=pulse, channel="vibration")
                    )
            self._innovation_pulses(vibration_z, found, vibration_ended)
        if vibration.seen:
            # IMU pulses already waiting from before the vibration stream was first seen.
            covered = [
                i
                for i in association.pending
                if i.channel == "imu"
                and i.pulse is not None
                and i.onset_s >= channels.vibration_start_s
            ]
            association.pending = [
                i for i in association.pending if not any(i is c for c in covered)
            ]
            self.held += [i.pulse for i in covered]  # type: ignore[misc]
        imu_z = self.acceleration.imu_z()
        if imu_z is not None:
            self.held += [
                pulse
                for pulse in self.imu_detector.scan(
                    imu.stamp_s,
                    imu_z,
                    imu.base_index,
                    final or channels.imu_stop_s < math.inf,
                )
                if not within_outage(channels.imu_outages, pulse.onset_s)
            ]
        held, self.held = self.held, []
        for pulse in held:
            covered_by_vibration = (
                vibration.seen
                and channels.vibration_start_s
                <= pulse.onset_s
                <= min(channels.vibration_stop_s, vibration.latest_s)
                and not within_outage(channels.vibration_outages, pulse.onset_s)
            )
            if covered_by_vibration:
                continue
            if channels.vibration_in_use() and pulse.onset_s > vibration.latest_s and not final:
                self.held.append(pulse)  # the vibration stream may yet cover it, or stop first
            else:
                association.pending.append(PendingImpact(onset_s=pulse.onset_s, pulse=pulse))

    def find_rebound_impacts(self, final: bool) -> None:
        """A rebound no pulse can claim is an impact of its own (acceleration channels stopped
        or absent, or the pulse lost in noise); its onset is put ``rebound_onset_lead_s``
        before its stamp. One a waiting pulse may claim late (a camera slower than known) is
        that pulse's instead."""
        # A late claim takes a waiting pulse's rebound window out of play, so a rebound passed
        # over as claimable before it is looked at again: the impacts found do not depend on
        # whether the claim came in this call or an earlier one.
        while self._rebound_impacts_once(final):
            pass

    def _rebound_impacts_once(self, final: bool) -> bool:
        """One pass of :meth:`find_rebound_impacts`; True when a pulse took a rebound late."""
        c = self.config.detection
        channels, association = self.channels, self.association
        # A pulse with its onset up to rebound_early_tolerance_s after the rebound may claim it.
        scanned = math.inf if final else self.onsets_known_s()
        claimed_late = False
        for stamp, velocity in association.rebounds:
            if stamp in association.used_rebounds:
                continue
            accel_gone = stamp > channels.accel_stop_s() + c.max_contact_s
            accel_absent = not channels.accel_seen() and (
                final or channels.newest_s() >= stamp + self.config.stream_timeout_s
            )
            claimable = association.claimable(stamp)
            orphan = channels.accel_seen() and scanned >= stamp + c.rebound_early_tolerance_s
            if (accel_gone or accel_absent or orphan) and not claimable:
                late = (
                    association.late_claimant(stamp)
                    if orphan and not accel_gone and self.camera.may_be_slower(stamp)
                    else None
                )
                if late is not None:
                    association.take_late_rebound(late, stamp, velocity)
                    claimed_late = True
                    continue
                association.used_rebounds.add(stamp)
                onset = stamp - c.rebound_onset_lead_s
                association.pending.append(
                    PendingImpact(
                        onset_s=onset, pulse=None, rebound=(stamp, velocity), source="rebound"
                    )
                )
        return claimed_late

    def _accel_absent(self, final: bool) -> bool:
        """No acceleration channel (IMU, vibration) at all, after the pressure has run
        ``stream_timeout_s`` without one (or at the end of the data, ``final``)."""
        pressure = self.channels.pressure
        if self.channels.accel_seen() or not pressure.stamp_s.size:
            return False
        return final or pressure.latest_s >= pressure.stamp_s[0] + self.config.stream_timeout_s

    def _pressure_impacts(self, final: bool) -> None:
        """With every acceleration channel stopped or absent, impacts found in the pressure
        (unless a rebound already stands for them)."""
        channels, association = self.channels, self.association
        pressure_outages = channels.pressure_outages
        stop_s = channels.accel_stop_s()
        # An IMU back after a stop: the pressure finishes the stretch it stood in for, no further.
        unfinished = (
            bool(pressure_outages) and self.pressure_detector.scanned_s <= pressure_outages[-1][1]
        )
        if stop_s == math.inf and not self._accel_absent(final) and not unfinished:
            return
        if stop_s < math.inf:
            # A new stop: the stretch since the last was the acceleration channel's.
            self.pressure_detector.skip_to(stop_s)
        start_s = stop_s if stop_s < math.inf else -math.inf
        margin_s = self.config.detection.pressure_onset_uncertainty_s
        for onset in self.pressure_detector.scan(
            channels.pressure.stamp_s, channels.pressure.values[:, 0], start_s, final
        ):
            if (
                stop_s == math.inf
                and not self._accel_absent(final)
                and not within_outage(pressure_outages, onset.onset_s)
            ):
                continue  # after the IMU came back: its pulses find the impacts there
            known_s = [
                i.onset_s for i in association.pending if i.source == "rebound"
            ] + association.decided
            if all(abs(onset.onset_s - t) > margin_s for t in known_s):
                association.pending.append(
                    PendingImpact(onset_s=onset.onset_s, pulse=None, source="pressure")
                )
