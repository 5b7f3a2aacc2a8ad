"""Turning one pending impact into a :class:`~tail_beam_id.stream.label.Label`: its features
read from the streams (the pressure fit, the impulse and contact fit of its pulse, its
rebound), the method's decision on them, and what the label says of how far to trust it.

An IMU pulse nothing else confirms (no rebound, no pressure impulse) while the beam still rings
from an earlier impact, or too weak to stand alone, gives no label. A label's confidence is
capped when another impact overlaps it, when it struck the beam still ringing from an earlier
one (``ringing_window_s`` after it), or once the recording's sensor timing is found suspect
(:mod:`tail_beam_id.signals.timing`); then the decision is made without the rebound delay
where the method can.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from tail_beam_id.methods import Decision, Method
from tail_beam_id.methods.inputs import IMPACT_X, IMPACT_Y, POINT_USED
from tail_beam_id.signals.contact_fit import clipped_near, fit_contact, half_periods, unreliable
from tail_beam_id.signals.contact_force import pulse_shapes
from tail_beam_id.signals.features import (
    VIBRATION_CHANNEL,
    BeamModel,
    PressureFit,
    background_s,
    fit_pressure,
    impact_features,
    imu_impulse,
)
from tail_beam_id.signals.timing import (
    DELAY_UNTRUSTED,
    OUTSIDE_NAME,
    UNUSUAL,
    SensorTiming,
    TimingConfig,
    judge,
)
from tail_beam_id.stream.acceleration import PlateNormalAcceleration
from tail_beam_id.stream.association import ImpactAssociation, PendingImpact
from tail_beam_id.stream.camera_frame import CameraFrame
from tail_beam_id.stream.channels import SensorChannels
from tail_beam_id.stream.config import IdentifierConfig
from tail_beam_id.stream.impact_point import ImpactPoints
from tail_beam_id.stream.label import Label, make_label

UNUSUAL_DELAY_PROBABILITY = 0.5  # above it, the delay check counts an impact's delay unusual
# In a label's outside_training: it struck within ringing_window_s of an earlier known onset.
RINGING_NAME = "earlier_impact_ringing"


def around(
    stamp_s: np.ndarray, values: np.ndarray, onset_s: float, before_s: float, after_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """The samples (stamps s, increasing; values) from ``before_s`` before ``onset_s`` to
    ``after_s`` after it, each end inclusive, and one more on either side: every sample the
    pulse's read-outs select by stamp, so that they select the same ones without scanning the
    whole buffer (several seconds of a fast channel)."""
    low = max(int(np.searchsorted(stamp_s, onset_s - before_s, side="left")) - 1, 0)
    high = int(np.searchsorted(stamp_s, onset_s + after_s, side="right")) + 1
    return stamp_s[low:high], values[low:high]


def in_ringing(onset_s: float, known: Sequence[float], window_s: float) -> bool:
    """Another known onset lies at most ``window_s`` before ``onset_s`` (s): the impact struck
    the beam still ringing from it."""
    return any(0.0 < onset_s - t <= window_s for t in known)


def impulse_neighbours(
    onset_s: float, known: Sequence[float], pre_s: float, post_s: float, cfg: IdentifierConfig
) -> tuple[list[float], float]:
    """The other onsets (s) near a pulse's velocity-step window, and how far back (s) the joint
    fit then reads (:func:`tail_beam_id.signals.features.imu_impulse`). Any onset that
    would cut the lone read-out's background (up to ``impulse_background_s`` before the onset,
    ending ``background_after_onset_s`` after an earlier one) or falls in its data window
    counts; the fit then reads from ``impulse_pre_s`` before the earliest (at most
    ``impulse_background_s``), so that the background is seen before every kick. Onsets closer
    than ``impulse_skip_s`` are read with the impact's. None: ([], pre_s), the lone
    read-out."""
    if not cfg.impulse_neighbour_fit:
        return [], pre_s
    reach_s = cfg.impulse_background_s + cfg.background_after_onset_s
    among = [
        t
        for t in known
        if abs(t - onset_s) >= cfg.impulse_skip_s and -reach_s < t - onset_s < post_s
    ]
    earlier = [t for t in among if t < onset_s]
    if not earlier:
        return among, pre_s
    window_s = min(onset_s - min(earlier) + cfg.impulse_pre_s, cfg.impulse_background_s)
    return among, max(window_s, pre_s)


def profile_says_timing_suspect(merged: Mapping[str, Any], config: TimingConfig) -> bool:
    """A self-calibration pass over the recording (its profile's ``calibration`` section) found
    its sensor timing suspect (:mod:`tail_beam_id.signals.timing`): then the labels are capped
    from the first."""
    calibration = merged.get("calibration") or {}
    checked, unusual = (
        calibration.get("delay_checked_impacts"),
        calibration.get("delay_unusual_impacts"),
    )
    if not isinstance(checked, int) or not isinstance(unusual, int):
        return False
    return judge(checked, unusual, config)


class ImpactDecider:
    """Decides pending impacts with a method and labels them (module docstring)."""

    def __init__(
        self,
        config: IdentifierConfig,
        model: BeamModel,
        method: Method,
        calibrated: bool,
        timing: SensorTiming,
        channels: SensorChannels,
        acceleration: PlateNormalAcceleration,
        association: ImpactAssociation,
        camera: CameraFrame,
    ) -> None:
        """``model``: the support the features are read with; ``method``: what decides;
        ``calibrated``: the support parameters are a profile measured on this support (the
        methods then use their calibrated models); ``timing``: the delay check's running
        verdict on the recording's sensor timing; the others: the parts of the identifier
        this one reads."""
        self.config = config
        self.model = model
        self.method = method
        self.calibrated = calibrated
        self.timing = timing
        self.channels = channels
        self.acceleration = acceleration
        self.association = association
        self.camera = camera
        # Where the camera saw the particles strike (topic impact_point), when it reports it.
        self.points: ImpactPoints | None = None
        if config.contact_fit.force_readout:
            pulse_shapes()  # the force read-out's shapes tabulated now, not in the first decision

    def decide(self, impact: PendingImpact) -> Label | None:
        """The label of ``impact``, now that its data are in; None when it is taken for the
        beam's ringing or noise. Records its onset among the decided ones."""
        started_s = time.perf_counter()
        cfg = self.config
        channels, association = self.channels, self.association
        association.take_rebound(impact)
        overlap = association.overlapping(impact)
        onset_s = impact.onset_s
        if impact.rebound is not None and not impact.late_rebound:
            before_s = cfg.detection.onset_before_rebound_max_s + association.slow_camera_s(
                impact.onset_s
            )
            onset_s = max(onset_s, impact.rebound[0] - before_s)
        window_s, post_s, _ = association.windows(impact)
        fit: PressureFit | None = None
        # every other onset the identifier still knows (decided ones are kept kept_s before the
        # oldest pending impact): the background stretches end after the latest earlier one
        known = association.known_onsets(impact, cfg.kept_s)
        if channels.pressure.stamp_s.size:
            pre_s = background_s(
                onset_s,
                known,
                cfg.pressure_pre_s,
                cfg.pressure_background_s,
                cfg.background_after_onset_s,
            )
            fit = fit_pressure(
                self.model,
                channels.pressure.stamp_s,
                channels.pressure.values[:, 0],
                onset_s,
                pre_s,
                window_s,
                # over a stretch longer than the least the sway drifts against the nominal one
                sway_drift=pre_s > cfg.pressure_pre_s,
                other_onsets_s=(
                    [t for t in known if t >= impact.onset_s - cfg.pressure_pre_s]
                    if cfg.neighbour_fit
                    else ()
                ),
                min_separation_s=cfg.neighbour_min_separation_s,
            )
        if impact.pulse is not None and impact.rebound is None:
            ringing = in_ringing(impact.onset_s, association.decided, cfg.detection.ring_window_s)
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
                (channels.vibration, self.acceleration.vibration_z())
                if impact.channel == "vibration"
                else (channels.imu, self.acceleration.imu_z())
            )
            pre_s = background_s(
                impact.pulse.onset_s,
                known,
                cfg.impulse_pre_s,
                cfg.impulse_background_s,
                cfg.background_after_onset_s,
            )
            among, among_pre_s = impulse_neighbours(
                impact.pulse.onset_s, known, pre_s, post_s, cfg
            )
            stamps, values = around(
                series.stamp_s,
                values,
                impact.pulse.onset_s,
                max(among_pre_s, cfg.contact_fit.before_s),
                max(post_s, cfg.contact_fit.after_s, cfg.contact_fit.ring_end_s),
            )
            impulse = imu_impulse(
                self.model,
                stamps,
                values,
                impact.pulse,
                among_pre_s,
                cfg.impulse_skip_s,
                post_s,
                sway_drift=among_pre_s > cfg.impulse_pre_s,
                other_onsets_s=among,
            )
            contact = fit_contact(
                stamps,
                values,
                impact.pulse.onset_s,
                impact.pulse.period_s,
                impact.pulse.noise_mps2,
                cfg.contact_fit,
                with_force=cfg.contact_fit.force_readout,
            )
            if clipped_near(stamps, values, impact.pulse.onset_s, cfg.contact_fit):
                saturated.append(impact.channel)
        features = impact_features(
            self.model,
            impact.pulse,
            impulse,
            fit,
            impact.rebound,
            contact,
            half_periods(contact, cfg.contact_fit),
            self.calibrated,
        )
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
            frame_period_s = self.camera.period_at(impact.rebound[0])
            if impact.late_rebound:
                # Stamped after the window the known frame allows: the frame is at least the
                # delay from the onset (erring long only makes the decision less sure).
                frame_period_s = max(
                    frame_period_s or 0.0,
                    impact.rebound[0] - impact.onset_s,
                    features.get("rebound_delay_s", 0.0),
                )
                features["rebound_late"] = 1.0
            if frame_period_s is not None:
                features["camera_frame_period_s"] = frame_period_s
        if impact.rebound is not None and self.points is not None:
            point = self.points.point_of(impact.rebound[0])
            if point is not None:
                features[IMPACT_X], features[IMPACT_Y] = point
        if impulse is not None and impact.channel == "vibration":
            # The imu_* features came from the accelerometer (anti-alias filtered point samples,
            # not the IMU's period means): the physics method keeps a lag model of its own for it.
            features[VIBRATION_CHANNEL] = 1.0
        decision: Decision = self.method.decide(features)
        timing_suspect = False
        if UNUSUAL in decision.estimates:
            if not association.known_onsets(impact, cfg.timing.clean_gap_s):
                # none in the gap before it, none overlapping it: evidence on the clocks
                self.timing.add(decision.estimates[UNUSUAL] > UNUSUAL_DELAY_PROBABILITY)
            timing_suspect = self.timing.suspect
            if timing_suspect:
                decision = self._decide_without_the_delay(features, decision)
        if decision.signals is not None:
            # The label says what the decision rested on (a pulse whose duration was not read:
            # not the acceleration channel).
            signals = [
                s
                for s in signals
                if ("imu" if s in ("imu", "vibration") else s) in decision.signals
            ]
        if decision.estimates.get(POINT_USED) and IMPACT_X in features:
            signals.append("impact_point")
        confidence = decision.confidence
        if overlap:
            confidence = min(confidence, cfg.overlap_confidence_cap)
        elif in_ringing(impact.onset_s, known, cfg.ringing_window_s):
            # Struck while the beam still rang from the impact before: every read-out holds
            # some of that impact's response, which no training impact had.
            confidence = min(confidence, cfg.ringing_confidence_cap)
            decision = replace(
                decision, outside_training=(*decision.outside_training, RINGING_NAME)
            )
        doubtful = unreliable(contact, cfg.contact_fit)
        used = decision.signals is None or "imu" in decision.signals
        if doubtful and used and "contact_duration_s" in features:
            # The decision read the contact's duration, and the pulse says it is not to be
            # trusted (a contact as long as a mode's half period, a fit that did not hold).
            confidence = min(confidence, cfg.contact_fit.unreliable_confidence_cap)
            decision = replace(decision, outside_training=(*decision.outside_training, *doubtful))
        if timing_suspect:
            confidence = min(confidence, cfg.timing.confidence_cap)
            decision = replace(
                decision, outside_training=(*decision.outside_training, OUTSIDE_NAME)
            )
        association.decided.append(impact.onset_s)
        horizon_s = association.data_horizon_s(impact)
        return make_label(
            impact_stamp_s=onset_s,
            decision=decision,
            confidence=confidence,
            method=self.method.name,
            compute_ms=(time.perf_counter() - started_s) * 1e3,
            data_latency_ms=(horizon_s - onset_s) * 1e3,
            signals=signals,
            overlap=overlap,
            calibrated=self.calibrated,
            features=features,
            saturated=saturated,
            imu_inverted=self.acceleration.imu_inverted,
            vibration_inverted=impact.channel == "vibration"
            and self.acceleration.vibration_inverted,
        )

    def _decide_without_the_delay(
        self, features: dict[str, float], decision: Decision
    ) -> Decision:
        """The decision of the method's twin without the rebound delay, once the recording's
        delays are found unlike the training's (the camera's and the acceleration channel's
        clocks offset: :mod:`tail_beam_id.signals.timing`): a delay shifted by an offset
        pushes every label one way, while the other signals still tell the materials apart.
        Sets ``delay_untrusted`` in ``features``. Keeps the delay check's own estimates (the
        calibration counts them), and ``decision`` as it is when the method has no such twin
        (it would read the delay again)."""
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
