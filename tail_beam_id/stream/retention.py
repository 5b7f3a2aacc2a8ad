"""Bounded memory on long streams: dropping the samples, rebounds and decided onsets no pending
or future decision can need.

Kept are four times the longest look-back (the detector's noise block, the pressure fit) before
the oldest pending onset or held pulse, and never anything a pulse detector has not examined
yet: a backlogged acceleration channel may lag the pressure by more than that look-back, and
trimming by the newest stamp of any stream would cut into it and make the result depend on
arrival order.
"""

from __future__ import annotations

import math

from tail_beam_id.stream.association import ImpactAssociation
from tail_beam_id.stream.channels import SensorChannels
from tail_beam_id.stream.config import IdentifierConfig
from tail_beam_id.stream.detection import ImpactFinder, scanned_s


class DataRetention:
    """Trims the identifier's buffers to what its decisions can still need (module docstring)."""

    def __init__(
        self,
        config: IdentifierConfig,
        channels: SensorChannels,
        finder: ImpactFinder,
        association: ImpactAssociation,
    ) -> None:
        """The parts of the identifier that hold data (``channels``, ``association``) and the
        one whose progress bounds what may go (``finder``)."""
        self.config = config
        self.channels = channels
        self.finder = finder
        self.association = association
        # Everything stamped before this (s) was let go at the last trim.
        self.forgotten_before_s = -math.inf

    def keep_s(self) -> float:
        """How far before the oldest needed stamp data are kept, s."""
        return self.config.kept_s

    def trim(self) -> None:
        """Drop what no pending or future decision can need (module docstring)."""
        channels, finder = self.channels, self.finder
        keep_s = self.keep_s()
        horizon_s = channels.newest_s()
        if channels.imu.seen and channels.imu_stop_s == math.inf:
            horizon_s = min(horizon_s, scanned_s(channels.imu, finder.imu_detector))
        if channels.vibration_in_use():
            horizon_s = min(horizon_s, scanned_s(channels.vibration, finder.vibration_detector))
            if finder.predictor is not None:
                horizon_s = min(
                    horizon_s, scanned_s(channels.vibration, finder.innovation_detector)
                )
        oldest_needed_s = (
            min(
                [i.onset_s for i in self.association.pending]
                + [p.onset_s for p in finder.waiting_pulses()],
                default=horizon_s,
            )
            - keep_s
        )
        self.forgotten_before_s = max(self.forgotten_before_s, oldest_needed_s)
        channels.forget_before(oldest_needed_s, keep_s)
        self.association.forget_before(oldest_needed_s)
