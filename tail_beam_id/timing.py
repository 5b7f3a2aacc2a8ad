"""Whether a recording's sensor clocks agree the way the training's did.

The labels lean on the delay from an impact's onset (acceleration channel) to the camera's
stamp: it carries the contact duration, and coal and rock of the same impulse differ in it by
60-200 us. A camera or accelerometer whose stamps are offset by a fraction of a millisecond
(another clock, a DAQ's filter delay) shifts every delay alike, and the labels go surely wrong:
on a foreign set, accelerometer stamps 0.3 ms late took 82 % to 57 % with 65 of 200 wrong at
>= 0.9. One impact cannot show it (a shorter delay is also a harder particle), but a recording
can: the statistical method says, per impact, whether its delay is unusual for its other
features (``delay_unusual``: outside the 0.5-99.5 % band of the training impacts' residuals),
which about 1 % of impacts are when the clocks agree and a quarter to a half are when they are
offset by 0.3 ms or more. This module counts them; once a recording has too many, its labels
that used the delay are capped and say ``sensor_timing`` among ``outside_training``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from tail_beam_sim.errors import require_range

UNUSUAL = "delay_unusual"  # the decision estimate: 1.0 when the impact's delay is unusual, 0.0 when not
OUTSIDE_NAME = "sensor_timing"  # what a capped label lists in outside_training


@dataclass(frozen=True)
class TimingConfig:
    """``identification.sensor_timing``: how many impacts with a delay check (``min_impacts``)
    and what share of unusual ones among them (``unusual_fraction``) make a recording's timing
    suspect, and the confidence its labels that used the delay are then capped at."""

    min_impacts: int
    unusual_fraction: float
    confidence_cap: float

    @classmethod
    def from_params(cls, section: Mapping[str, Any]) -> TimingConfig:
        name = "identification.sensor_timing"
        return cls(
            min_impacts=int(require_range(f"{name}.min_impacts", section.get("min_impacts", 10), 1, 1e6)),
            unusual_fraction=require_range(f"{name}.unusual_fraction", section.get("unusual_fraction", 0.2), 0.0, 1.0, low_open=True),
            confidence_cap=require_range(f"{name}.confidence_cap", section.get("confidence_cap", 0.6), 0.5, 1.0),
        )


class SensorTiming:
    """The count of a recording's impacts with a delay check and of the unusual ones; suspect
    once there are ``min_impacts`` and the unusual share reaches ``unusual_fraction`` (and from
    then on), or from the start when a self-calibration pass over the recording found so."""

    def __init__(self, config: TimingConfig, suspect: bool = False) -> None:
        self.config = config
        self.checked = 0
        self.unusual = 0
        self.suspect = suspect
        self.from_profile = suspect  # suspect from the start: the self-calibration pass found it

    def add(self, unusual: bool) -> None:
        """One impact's check."""
        self.checked += 1
        self.unusual += int(unusual)
        if not self.suspect:
            self.suspect = judge(self.checked, self.unusual, self.config)

    def describe(self) -> str:
        """One line for the log."""
        where = " (and the self-calibration pass over the recording found so)" if self.from_profile else ""
        return (f"{self.unusual} of {self.checked} impacts{where} have a delay from onset to camera stamp unlike the training's "
                "for their size and speed: the camera's and the acceleration channel's clocks may be offset (README, "
                f"Supports other than the shipped one); labels that use the delay are capped at {self.config.confidence_cap:g} "
                f"and list {OUTSIDE_NAME} in outside_training")


def judge(checked: int, unusual: int, config: TimingConfig) -> bool:
    """Whether ``unusual`` of ``checked`` impacts make the timing suspect."""
    return checked >= config.min_impacts and unusual >= config.unusual_fraction * checked
