"""The ``identification`` parameter section, validated once for the stream identifier."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from tail_beam_id.methods import METHODS
from tail_beam_id.signals.contact_fit import ContactFitConfig
from tail_beam_id.signals.imu_detection import DetectionConfig
from tail_beam_id.signals.timing import TimingConfig
from tail_beam_sim.errors import InputError, require_range, require_section


@dataclass(frozen=True)
class IdentifierConfig:
    """The ``identification`` parameter section, validated (times in s of stamp time)."""

    method: str
    window_s: float
    vibration_window_s: float  # the data window of an impact the accelerometer found (s)
    pressure_pre_s: float
    impulse_pre_s: float
    impulse_skip_s: float
    impulse_post_s: float
    stream_timeout_s: float
    camera_timeout_s: float
    overlap_window_s: float
    overlap_confidence_cap: float
    detection: DetectionConfig
    timing: TimingConfig
    contact_fit: ContactFitConfig

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> IdentifierConfig:
        if not isinstance(params, Mapping):
            raise InputError("identification", params, "missing parameter section")

        def seconds(name: str) -> float:
            return require_range(
                f"identification.{name}", params.get(name), 0.0, 10.0, low_open=True, unit="s"
            )

        method = params.get("method")
        if method not in METHODS:
            raise InputError(
                "identification.method", method, f"must be one of {', '.join(METHODS)}"
            )
        window = seconds("window_s")
        overlap = seconds("overlap_window_s")
        if seconds("impulse_post_s") > window:
            raise InputError(
                "identification.impulse_post_s",
                params.get("impulse_post_s"),
                f"must be <= window_s ({window:g} s)",
            )
        if overlap > window:
            raise InputError(
                "identification.overlap_window_s", overlap, f"must be <= window_s ({window:g} s)"
            )
        vibration_window = params.get("vibration_window_s", window)
        vibration_window = require_range(
            "identification.vibration_window_s",
            vibration_window,
            0.0,
            window,
            low_open=True,
            unit="s",
        )
        return cls(
            method=method,
            window_s=window,
            vibration_window_s=vibration_window,
            pressure_pre_s=seconds("pressure_pre_s"),
            impulse_pre_s=seconds("impulse_pre_s"),
            impulse_skip_s=seconds("impulse_skip_s"),
            impulse_post_s=seconds("impulse_post_s"),
            stream_timeout_s=seconds("stream_timeout_s"),
            camera_timeout_s=seconds("camera_timeout_s"),
            overlap_window_s=overlap,
            overlap_confidence_cap=require_range(
                "identification.overlap_confidence_cap",
                params.get("overlap_confidence_cap"),
                0.5,
                1.0,
            ),
            detection=DetectionConfig.from_params(
                require_section("identification.detection", params.get("detection"))
            ),
            timing=TimingConfig.from_params(
                require_section("identification.sensor_timing", params.get("sensor_timing"))
            ),
            contact_fit=ContactFitConfig.from_params(
                require_section("identification.contact_fit", params.get("contact_fit"))
            ),
        )


__all__ = ["IdentifierConfig"]
