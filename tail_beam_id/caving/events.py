"""What a caving window's closing rule is fed, and the decision it gives.

Times are stamps in seconds on the face's clock. A label's ``stamp_s`` is its impact's; it is
known at ``arrival_s`` (the identifier's latency later), and a decision made on it is made then.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tail_beam_id.stream.label import MATERIALS, Label
from tail_beam_sim.errors import InputError

__all__ = [
    "Decision",
    "Event",
    "LabelEvent",
    "Opened",
    "ShareEstimate",
    "Tick",
    "TrueShare",
]


@dataclass(frozen=True)
class Opened:
    """The window opened at ``stamp_s``: what is stamped earlier belongs to an earlier window."""

    stamp_s: float

    @property
    def known_s(self) -> float:
        return self.stamp_s


@dataclass(frozen=True)
class Tick:
    """The clock reached ``stamp_s`` with nothing else to say (a timer)."""

    stamp_s: float

    @property
    def known_s(self) -> float:
        return self.stamp_s


@dataclass(frozen=True)
class LabelEvent:
    """One lump's label: its impact stamp (s), material ("coal" or "gangue"), confidence (the
    stated label's probability, 0..1) and when it became known (s; None: at its stamp)."""

    stamp_s: float
    material: str
    confidence: float
    arrival_s: float | None = None

    def __post_init__(self) -> None:
        if self.material not in MATERIALS:
            raise InputError("label", self.material, f"must be one of {', '.join(MATERIALS)}")
        if not (math.isfinite(self.confidence) and 0.0 <= self.confidence <= 1.0):
            raise InputError("confidence", self.confidence, "must be in [0, 1]")
        if not math.isfinite(self.stamp_s):
            raise InputError("impact_stamp", self.stamp_s, "must be a finite time, s")

    @property
    def known_s(self) -> float:
        return self.stamp_s if self.arrival_s is None else self.arrival_s

    @property
    def gangue(self) -> bool:
        return self.material == "gangue"

    @classmethod
    def of(cls, label: Label, arrival_s: float | None = None) -> LabelEvent:
        """The event of an identifier's :class:`~tail_beam_id.stream.label.Label`."""
        return cls(label.impact_stamp_s, label.material, label.confidence, arrival_s)


@dataclass(frozen=True)
class ShareEstimate:
    """A ``gangue_share`` estimate: the share of gangue over the interval ending at
    ``stamp_s`` (s) of length ``interval_s``, with its interval ``[low, high]``, known at
    ``arrival_s`` (None: at its stamp)."""

    stamp_s: float
    share: float
    low: float
    high: float
    interval_s: float = 0.0
    arrival_s: float | None = None
    standard_error: float | None = None  # the estimator's (None: not stated)

    def __post_init__(self) -> None:
        for name in ("share", "low", "high"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 <= value <= 1.0):
                raise InputError(f"gangue_share.{name}", value, "must be in [0, 1]")
        if not self.low <= self.share <= self.high:
            raise InputError(
                "gangue_share.share", self.share, f"must lie in [{self.low:g}, {self.high:g}]"
            )
        if self.standard_error is not None and not (
            math.isfinite(self.standard_error) and self.standard_error >= 0.0
        ):
            raise InputError(
                "gangue_share.standard_error", self.standard_error, "must be >= 0 or null"
            )

    @property
    def known_s(self) -> float:
        return self.stamp_s if self.arrival_s is None else self.arrival_s


@dataclass(frozen=True)
class TrueShare:
    """The true instantaneous gangue share (by mass, 0..1) of the flow at ``stamp_s``: known
    to the simulation only (the oracle rule's upper bound)."""

    stamp_s: float
    share: float

    @property
    def known_s(self) -> float:
        return self.stamp_s


Event = Opened | Tick | LabelEvent | ShareEstimate | TrueShare


@dataclass(frozen=True)
class Decision:
    """Close the window: when (``stamp_s``, s: when the deciding event was known), which rule,
    why (one line), and the events it rested on."""

    stamp_s: float
    rule: str
    reason: str
    evidence: tuple[Event, ...]
