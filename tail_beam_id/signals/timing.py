"""Whether a recording's sensor clocks agree the way the training's did.

The labels lean on the delay from an impact's onset (acceleration channel) to the camera's
stamp: it carries the contact duration, and coal and rock of the same impulse differ in it by
60-200 us. A camera or accelerometer whose stamps are offset by a fraction of a millisecond
(another clock, a DAQ's filter delay) shifts every delay alike, and the labels go surely wrong.
One impact cannot show it (a shorter delay is also a harder particle), but a recording can: the
statistical method says, per impact, whether its delay is unusual for its other features
(``delay_unusual``: outside the 0.5-99.5 % band of the training impacts' residuals), which few
impacts are when the clocks agree (about 1 % of the training's by the band's construction,
somewhat more on other supports) and many are when they are offset by a fraction of a
millisecond. This module counts them; once a recording has more than agreeing clocks would give
but once in a thousand recordings (a binomial tail), its labels that used the delay are decided
again without it (the statistical method's twin fitted without the delay: an offset pushes
every delay one way, the other signals still tell the materials apart), capped, and say
``sensor_timing`` among ``outside_training``. (A fixed share of unusual impacts, judged from a
recording's first few, would trip on the few unusual ones a foreign support's base rate often
gives among them and cap recordings whose clocks agree; the tail asks for a larger share the
fewer are checked. Late stamps with the check in place: docs/results/robustness.md.)"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from scipy.special import bdtrc

from tail_beam_sim.spec import Section, integer, number, positive

UNUSUAL = (
    "delay_unusual"  # the decision estimate: 1.0 when the impact's delay is unusual, 0.0 when not
)
OUTSIDE_NAME = "sensor_timing"  # what a capped label lists in outside_training
# The feature (1.0) of an impact decided without its delay because the recording's delays were
# found unlike the training's: methods with a twin fitted without the delay use it then.
DELAY_UNTRUSTED = "delay_untrusted"


SENSOR_TIMING = Section(
    "identification.sensor_timing",
    "The check of the camera's and the acceleration channel's clocks.",
    (
        integer(
            "min_impacts",
            "Impacts checked before a recording is judged.",
            1,
            10**6,
            default=10,
        ),
        positive(
            "agreeing_rate",
            "Share of unusual delays agreeing clocks give.",
            high=0.5,
            default=0.03,
        ),
        positive(
            "false_alarm", "Share of agreeing recordings called suspect.", high=0.5, default=1e-3
        ),
        number(
            "confidence_cap",
            "Confidence cap of a suspect recording's delay labels.",
            "",
            0.5,
            1.0,
            default=0.6,
        ),
        number(
            "clean_gap_s",
            "Only impacts with no other this long before (nor overlapping) are checked.",
            "s",
            0.0,
            10.0,
            default=0.25,
        ),
    ),
    file="identification.yaml",
)


@dataclass(frozen=True)
class TimingConfig:
    """``identification.sensor_timing``: how many impacts with a delay check a recording needs
    before it is judged (``min_impacts``); the share of unusual delays agreeing clocks may give
    (``agreeing_rate``) and how rarely a recording with agreeing clocks may be called suspect
    (``false_alarm``); the confidence its labels that used the delay are then capped at; and
    how long (s) an impact must come after any other to count (``clean_gap_s``; nor may another
    overlap it): in a dense flow an onset and a delay read in another impact's response are
    unusual more often whatever the clocks, and a clock offset shows in the isolated impacts
    as well."""

    min_impacts: int
    agreeing_rate: float
    false_alarm: float
    confidence_cap: float
    clean_gap_s: float = 0.25  # an impact with another this soon before it (s) is no evidence

    @classmethod
    def from_params(cls, section: Mapping[str, Any]) -> TimingConfig:
        return cls(**SENSOR_TIMING.check(section))


class SensorTiming:
    """The count of a recording's impacts with a delay check and of the unusual ones; suspect
    once there are ``min_impacts`` and the unusual count is one agreeing clocks give less often
    than ``false_alarm`` (and from then on), or from the start when a self-calibration pass over
    the recording found so."""

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
        where = (
            " (and the self-calibration pass over the recording found so)"
            if self.from_profile
            else ""
        )
        return (
            f"{self.unusual} of {self.checked} impacts{where} have a delay from onset to camera "
            "stamp unlike the training's "
            "for their size and speed: the camera's and the acceleration channel's clocks may be "
            "offset (docs/identification.md, Sensor clocks that disagree); labels that used the "
            "delay are decided without it, "
            f"capped at {self.config.confidence_cap:g} and list {OUTSIDE_NAME} in outside_training"
        )


def judge(checked: int, unusual: int, config: TimingConfig) -> bool:
    """Whether ``unusual`` of ``checked`` impacts make the timing suspect: at least min_impacts
    checked, and at least that many unusual less likely than false_alarm when each impact is
    unusual with probability agreeing_rate (at 3 % and 0.001: 4 of 10, 5 of 20, 7 of 40)."""
    if checked < config.min_impacts or unusual <= 0:
        return False
    # bdtrc(k - 1, n, p) = P(X >= k) for X ~ Binomial(n, p): scipy.stats.binom.sf's value
    # without its distribution object's overhead (it runs once per impact until the recording
    # is judged suspect).
    return float(bdtrc(unusual - 1, checked, config.agreeing_rate)) < config.false_alarm
