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

:class:`StreamIdentifier` coordinates parts that each do one job, in modules of their own:

* :mod:`~tail_beam_id.stream.channels`: taking the samples in, and which streams are live;
* :mod:`~tail_beam_id.stream.acceleration`: the acceleration along the plate normal, the
  sensors' mounting signs;
* :mod:`~tail_beam_id.stream.camera_frame`: the camera's frame period;
* :mod:`~tail_beam_id.stream.detection`: finding impacts (pulses, rebounds, pressure steps);
* :mod:`~tail_beam_id.stream.association`: which rebound and neighbours belong to an impact;
* :mod:`~tail_beam_id.stream.impact_point`: where the camera saw the particle strike, paired
  with its rebound;
* :mod:`~tail_beam_id.stream.readiness`: when an impact's data are all in;
* :mod:`~tail_beam_id.stream.decision`: deciding an impact with the method and labelling it
  (:class:`~tail_beam_id.stream.label.Label`);
* :mod:`~tail_beam_id.stream.retention`: forgetting data no decision can need.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from tail_beam_id.methods import Method, build_method
from tail_beam_id.signals.camera import FramePeriod
from tail_beam_id.signals.features import BeamModel
from tail_beam_id.signals.imu_detection import PulseDetector
from tail_beam_id.signals.pressure_detection import PressureDetector
from tail_beam_id.signals.timing import SensorTiming
from tail_beam_id.stream.acceleration import PlateNormalAcceleration
from tail_beam_id.stream.association import ImpactAssociation
from tail_beam_id.stream.buffers import Series
from tail_beam_id.stream.camera_frame import CameraFrame
from tail_beam_id.stream.channels import Outages, SensorChannels
from tail_beam_id.stream.config import IdentifierConfig, check_profile
from tail_beam_id.stream.decision import ImpactDecider, profile_says_timing_suspect
from tail_beam_id.stream.detection import ImpactFinder
from tail_beam_id.stream.impact_point import ImpactPoints
from tail_beam_id.stream.label import Label
from tail_beam_id.stream.readiness import Readiness
from tail_beam_id.stream.retention import DataRetention
from tail_beam_sim import topics
from tail_beam_sim.config import load_parameters


def _measured_on_this_support(merged: Mapping[str, Any]) -> bool:
    """The support parameters are a profile measured on this support (tail-beam calibrate)
    rather than the nominal config/: the methods then use their calibrated models."""
    return check_profile(merged).get("rigid_mode_frequency_hz") is not None


class StreamIdentifier:
    """Labels each impact in continuous sensor streams coal or gangue (docs/interface.md
    ``label``): takes the samples in, and hands out the labels of the impacts decidable."""

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
        if params is None or model_params is None:
            defaults: Mapping[str, Any] = load_parameters()
            params = defaults["identification"] if params is None else params
            model_params = defaults if model_params is None else model_params
        section = dict(params)
        if method is not None:
            section["method"] = method
        self.config = IdentifierConfig.from_params(section)
        merged = dict(model_params)
        merged["identification"] = section
        # A profile's section (tail-beam calibrate), read by the methods and here: refused by
        # name unless each of its fields is a plausible measurement.
        profile = check_profile(merged)
        if prebuilt is not None and prebuilt.name == self.config.method:
            built = prebuilt
        else:
            built = build_method(self.config.method, merged, model_path)
        model = BeamModel.from_params(merged)
        self.channels = SensorChannels(self.config)
        self.acceleration = PlateNormalAcceleration(self.channels, model.support.gravity_mps2)
        self.camera_frame = CameraFrame(merged)
        # Pending impacts, rebounds, recent decisions; its rebound windows follow the camera.
        self.impacts = ImpactAssociation(self.config, self.camera_frame.period_at)
        self.finder = ImpactFinder(
            self.config, model, self.channels, self.acceleration, self.impacts, self.camera_frame
        )
        self._follow_profile(profile)
        self.readiness = Readiness(
            self.config, self.channels, self.finder, self.impacts, self.camera_frame
        )
        self.decider = ImpactDecider(
            self.config,
            model,
            built,
            _measured_on_this_support(merged),
            SensorTiming(
                self.config.timing, profile_says_timing_suspect(merged, self.config.timing)
            ),
            self.channels,
            self.acceleration,
            self.impacts,
            self.camera_frame,
        )
        self.retention = DataRetention(self.config, self.channels, self.finder, self.impacts)
        # Where the camera saw the particles strike, checked against the plate of the support
        # as known at the time (a profile may change it).
        self.points = ImpactPoints(self._plate_m, self.config.camera_timeout_s)
        self.decider.points = self.points

    def _follow_profile(self, profile: Mapping[str, Any]) -> None:
        """What a checked ``calibration`` section sets: the detectors' ringing and the
        accelerometer-found impacts' data window."""
        self.finder.follow_profile(profile)
        self.impacts.follow_profile(profile)

    def _plate_m(self) -> tuple[float, float]:
        """The plate's (length from the hinge, width), m."""
        support = self.decider.model.support
        return support.beam_length_m, support.plate_width_m

    def recalibrate(self, model_params: Mapping[str, Any], method: Method | None = None) -> None:
        """Decide from here on with a support profile measured on this support (``model_params``:
        the merged parameters with the profile in; ``method``: the method built for them, when
        it depends on the support). Pending impacts keep their data; only decisions change."""
        merged = dict(model_params)
        merged["identification"] = dict(
            merged.get("identification") or {}, method=self.config.method
        )
        model = BeamModel.from_params(merged)
        # The ringing the profile measured (tail_beam_id.calibration.modes) sets how long the
        # detectors follow it, s.
        ring_decay_s = ((model_params.get("identification") or {}).get("detection") or {}).get(
            "ring_decay_s"
        )
        self.finder.recalibrate(model, ring_decay_s)
        self._follow_profile(check_profile(merged))
        self.acceleration.gravity_mps2 = model.support.gravity_mps2
        self.decider.model = model
        if method is not None:
            self.decider.method = method
        self.decider.calibrated = _measured_on_this_support(merged)
        self.camera_frame.recalibrate(merged)

    # ---- input -------------------------------------------------------------------------------
    def add_pressure(self, stamp_s: np.ndarray, pressure_pa: np.ndarray) -> None:
        """Jack pressure samples: stamps (s), absolute pressure (Pa)."""
        self.channels.add_pressure(stamp_s, pressure_pa)

    def add_imu(
        self,
        stamp_s: np.ndarray,
        angular_velocity_radps: np.ndarray,
        linear_acceleration_mps2: np.ndarray,
    ) -> None:
        """IMU samples: stamps (s), angular velocity (T, 3) rad/s, specific force (T, 3) m/s^2."""
        self.channels.add_imu(stamp_s, angular_velocity_radps, linear_acceleration_mps2)

    def add_vibration(self, stamp_s: np.ndarray, accel_mps2: np.ndarray) -> None:
        """High-rate tail-beam accelerometer samples: stamps (s, in order) and specific force
        along the plate normal (z of the plate frame), m/s^2. While this stream is live it
        replaces the IMU's linear_acceleration z for pulse detection and the IMU impulse."""
        self.channels.add_vibration(stamp_s, accel_mps2)

    def add_rebound(self, stamp_s: float, velocity_mps: np.ndarray) -> None:
        """One rebound: the camera's stamp (s) and the particle's velocity (3,) in the plate frame
        (:meth:`ImpactAssociation.add_rebound`: a non-finite one is left out and counted)."""
        refused_before = self.impacts.refused_rebounds
        taken_before = len(self.impacts.rebounds)
        self.impacts.add_rebound(stamp_s, velocity_mps)
        if self.impacts.refused_rebounds == refused_before:
            self.camera_frame.add_rebound(float(stamp_s))
        if len(self.impacts.rebounds) > taken_before:
            self.points.add_rebound(float(stamp_s))

    def add_impact_point(
        self, stamp_s: float, point_m: np.ndarray, frame_id: str = topics.FRAME_PLATE
    ) -> str | None:
        """Where the camera saw a particle strike: its stamp (s, its rebound's), (x, y, z) on the
        plate, m, and frame (:class:`ImpactPoints`). Returns why it was refused (counted in
        ``refused_points``), or None: it is then its rebound's impact's ``impact_x_m`` and
        ``impact_y_m``."""
        return self.points.add(float(stamp_s), point_m, frame_id)

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

    def _run(self, final: bool) -> list[Label]:
        """Take in what came, find the impacts it shows, decide those whose data are all in
        (every pending one at the end of the data, ``final``), and forget what is no longer
        needed."""
        self.channels.update(final)
        self.finder.find(final)
        self.impacts.pending.sort(key=lambda impact: impact.onset_s)
        labels: list[Label] = []
        while self.impacts.pending and (final or self.readiness.ready(self.impacts.pending[0])):
            label = self.decider.decide(self.impacts.pending.pop(0))
            if label is not None:
                labels.append(label)
            # The decided impact's rebound window claims no more: a rebound it left is now an
            # impact of its own, found before the next decision however the data were chunked.
            self.finder.find_rebound_impacts(final)
            self.impacts.pending.sort(key=lambda impact: impact.onset_s)
        self.retention.trim()
        if final:
            self.points.flush()
        else:
            self.points.expire(self.channels.newest_s())
        self.points.forget_before(self.retention.forgotten_before_s)
        return labels

    # ---- the parts' state, as callers read it ------------------------------------------------
    @property
    def refused_rebounds(self) -> int:
        """Rebounds with a non-finite stamp or velocity, left out."""
        return self.impacts.refused_rebounds

    @property
    def refused_points(self) -> dict[str, int]:
        """impact_point messages refused or set aside, by reason."""
        return self.points.refused

    @property
    def refused_samples(self) -> dict[str, int]:
        """Samples with a non-finite stamp or value left out, by stream."""
        return self.channels.refused_samples

    @property
    def pressure(self) -> Series:
        """The jack pressure buffer (stamps s, Pa)."""
        return self.channels.pressure

    @property
    def imu(self) -> Series:
        """The IMU buffer (stamps s; angular velocity rad/s, specific force m/s^2)."""
        return self.channels.imu

    @property
    def vibration(self) -> Series:
        """The tail-beam accelerometer buffer (stamps s; specific force m/s^2)."""
        return self.channels.vibration

    @property
    def vibration_start_s(self) -> float:
        """The first vibration stamp seen, s (inf before any)."""
        return self.channels.vibration_start_s

    @property
    def imu_stop_s(self) -> float:
        """Stamp after which the IMU was declared stopped, s (inf while it is live)."""
        return self.channels.imu_stop_s

    @property
    def vibration_stop_s(self) -> float:
        """Stamp after which the vibration stream was declared stopped, s (inf while live)."""
        return self.channels.vibration_stop_s

    @property
    def imu_outages(self) -> Outages:
        """(declared stopped at, taken up again from) of each time the IMU came back, s."""
        return self.channels.imu_outages

    @property
    def vibration_outages(self) -> Outages:
        """The same for the vibration stream, s."""
        return self.channels.vibration_outages

    @property
    def mount_sign(self) -> float | None:
        """+1: IMU z along the plate normal; -1: mounted upside down; None: not yet known."""
        return self.acceleration.mount_sign

    @property
    def vibration_mount_sign(self) -> float | None:
        """The same for the tail-beam accelerometer."""
        return self.acceleration.vibration_mount_sign

    @property
    def detector(self) -> PulseDetector:
        """The IMU's pulse detector."""
        return self.finder.imu_detector

    @property
    def vibration_detector(self) -> PulseDetector:
        """The tail-beam accelerometer's pulse detector."""
        return self.finder.vibration_detector

    @property
    def pressure_detector(self) -> PressureDetector:
        """The jack pressure's impact detector."""
        return self.finder.pressure_detector

    @property
    def camera(self) -> FramePeriod:
        """The camera's frame period, configured and measured from the rebound stamps, s."""
        return self.camera_frame.frame_period

    @property
    def profile_frame_s(self) -> float | None:
        """The camera frame self-calibration measured, s (None: not measured)."""
        return self.camera_frame.profile_frame_s

    @property
    def model(self) -> BeamModel:
        """The support model the features are read with."""
        return self.decider.model

    @property
    def method(self) -> Method:
        """The method that decides."""
        return self.decider.method

    @property
    def calibrated(self) -> bool:
        """The support parameters are a profile measured on this support."""
        return self.decider.calibrated

    @property
    def timing(self) -> SensorTiming:
        """The delay check's running verdict on the recording's sensor timing."""
        return self.decider.timing
