"""What the identifier knows of the camera's frame period: configured
(``sensors.camera_frame_rate_hz``), measured from the rebound stamps so far
(:class:`tail_beam_id.signals.camera.FramePeriod`), or read by a self-calibration pass over
the recording (its profile's ``calibration.camera_frame_rate_hz``).

A camera slower than its frame is known to be stamps a rebound up to a frame after the contact
ended, so the rebound windows, the late-rebound rule and the delay feature all ask here.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from tail_beam_id.signals.camera import FramePeriod, may_be_slower
from tail_beam_id.stream.config import check_profile
from tail_beam_sim.errors import require_section
from tail_beam_sim.spec import SENSORS


def configured_frame_period_s(merged: Mapping[str, Any]) -> float | None:
    """The camera's frame period the parameters give (``sensors.camera_frame_rate_hz``), s;
    None when they give none."""
    sensors = require_section("sensors", merged.get("sensors") or {})
    if sensors.get("camera_frame_rate_hz") is None:
        return None
    return 1.0 / SENSORS.check(sensors, only=["camera_frame_rate_hz"])["camera_frame_rate_hz"]


def profile_frame_period_s(merged: Mapping[str, Any]) -> float | None:
    """The camera frame (s) a self-calibration pass read from the recording's rebound stamps
    (its profile's ``calibration.camera_frame_rate_hz``), or None. Unlike
    ``sensors.camera_frame_rate_hz`` it is a measurement, not a setting (config/'s 5 kHz is
    every support's)."""
    rate = check_profile(merged).get("camera_frame_rate_hz")
    return None if rate is None else 1.0 / rate


class CameraFrame:
    """The camera's frame period as known at each stamp, and whether the camera may be slower
    than that (module docstring)."""

    def __init__(self, merged: Mapping[str, Any]) -> None:
        """``merged``: the merged parameters (``sensors`` and, from a profile,
        ``calibration``)."""
        # The configured frame period, refined by the rebound stamps as they come, s.
        self.frame_period = FramePeriod(configured_frame_period_s(merged))
        # The frame period self-calibration measured, s (None: not measured).
        self.profile_frame_s = profile_frame_period_s(merged)

    def recalibrate(self, merged: Mapping[str, Any]) -> None:
        """Take the self-calibrated frame period of a new profile (``merged``: the merged
        parameters with the profile in)."""
        self.profile_frame_s = profile_frame_period_s(merged)

    def add_rebound(self, stamp_s: float) -> None:
        """A rebound's camera stamp (s): one more stamp to measure the frame from."""
        self.frame_period.add(stamp_s)

    def period_at(self, stamp_s: float) -> float | None:
        """The frame period (s) as known from the stamps up to ``stamp_s`` (s), or None."""
        return self.frame_period.period_at(stamp_s)

    def may_be_slower(self, stamp_s: float) -> bool:
        """Whether the camera may be slower than its frame is known to be at ``stamp_s`` (s)
        (:func:`tail_beam_id.signals.camera.may_be_slower`): measured from the stamps so far,
        else by the self-calibration pass. A camera known to be fast stamps no rebound after
        its window: one that comes there is another impact's (or a slow IMU's onset came
        early), not late."""
        measured = self.frame_period.measured_at(stamp_s)
        return may_be_slower(measured if measured is not None else self.profile_frame_s)
