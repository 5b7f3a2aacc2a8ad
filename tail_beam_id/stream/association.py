"""Impact association: which detections, rebounds and neighbours belong to one impact.

The identifier's impact finder (:mod:`tail_beam_id.stream.detection`) finds candidate impacts
in three ways (a pulse in an acceleration channel, a rebound no pulse claims, a step in the
jack pressure) and keeps them here until decided. This module holds the rules that tie them
together, all on stamps (s):

* which camera rebound is an impact's (its rebound window);
* whether another impact lies close enough to spoil its features (overlap);
* whether the camera has said all it will about it (readiness, camera side).

Nothing here reads the sensor streams; the identifier asks with the stamps it has.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from tail_beam_id.signals.imu_detection import Pulse

if TYPE_CHECKING:
    from tail_beam_id.stream.config import IdentifierConfig


@dataclass
class PendingImpact:
    """A detected impact waiting for its data (stamps in s)."""

    onset_s: float
    pulse: Pulse | None
    rebound: tuple[float, np.ndarray] | None = None  # (camera stamp s, velocity m/s, plate)
    # What detected it: imu (a pulse in an acceleration channel) | rebound | pressure.
    source: str = "imu"
    channel: str = "imu"  # the acceleration channel of its pulse: imu | vibration
    # Its rebound came after its window (a camera slower than known):
    # ImpactAssociation.late_claimant.
    late_rebound: bool = False


class ImpactAssociation:
    """The pending impacts, the camera's rebounds and the recently decided onsets, and the rules
    that associate them (module docstring)."""

    def __init__(
        self,
        config: IdentifierConfig,
        frame_period_at: Callable[[float], float | None] = lambda stamp_s: None,
    ) -> None:
        """``frame_period_at(stamp)``: the camera's frame period (s) as known from the rebound
        stamps up to ``stamp`` (tail_beam_id.signals.camera.FramePeriod.period_at), or None."""
        self.config = config
        self.frame_period_at = frame_period_at
        self.pending: list[PendingImpact] = []
        self.rebounds: list[tuple[float, np.ndarray]] = []  # (stamp s, velocity m/s), in order
        self.refused_rebounds = 0  # rebounds with a non-finite stamp or velocity, left out
        self.used_rebounds: set[float] = set()  # stamps of rebounds given to an impact
        # Onsets of recently decided impacts (overlap and ringing checks), s.
        self.decided: list[float] = []
        # The data window of an impact the accelerometer found, s (follow_profile).
        self.vibration_window_s = config.vibration_window_s

    def follow_profile(self, profile: Mapping[str, Any]) -> None:
        """Take the accelerometer-found impacts' data window from a checked ``calibration``
        section (config.check_profile): ``vibration_window_mode_periods`` periods of the
        slowest bending mode it measured (``ringing_modes_hz``) when that is longer than
        ``vibration_window_s``, at most ``window_s``. A velocity step or pressure fit over less
        than a period of a slow mode reads that mode's swing as the impact's: on a support whose
        first bending mode rings at 100-200 Hz, 6 ms is about one period."""
        cfg = self.config
        modes = profile.get("ringing_modes_hz") or ()  # checked: 1 Hz and up
        window = cfg.vibration_window_s
        if modes and cfg.vibration_window_mode_periods > 0.0:
            window = max(window, min(cfg.window_s, cfg.vibration_window_mode_periods / min(modes)))
        self.vibration_window_s = window

    def add_rebound(self, stamp_s: float, velocity_mps: np.ndarray) -> None:
        """One rebound: the camera's stamp (s) and the particle's velocity (3,) in the plate frame.
        A rebound with a non-finite stamp or velocity is no measurement: it is left out (its
        impact is decided without the camera) and counted in ``refused_rebounds``; one not
        after the newest is a repeat and ignored."""
        velocity = np.asarray(velocity_mps, dtype=float).reshape(3)
        if not (math.isfinite(stamp_s) and np.isfinite(velocity).all()):
            self.refused_rebounds += 1
            return
        if self.rebounds and stamp_s <= self.rebounds[-1][0]:
            return
        self.rebounds.append((float(stamp_s), velocity))

    def windows(self, impact: PendingImpact) -> tuple[float, float, float]:
        """(data window, end of the impulse fit, overlap window) after this impact's onset, s.
        An impact the accelerometer found needs less data (``vibration_window_s``, or longer on a
        support with a slow bending mode: :meth:`follow_profile`): its pulse pins the onset to a
        39 us sample and its velocity step to a few milliseconds."""
        cfg = self.config
        if impact.channel == "vibration":
            window = self.vibration_window_s
            return window, min(cfg.impulse_post_s, window), min(cfg.overlap_window_s, window)
        return cfg.window_s, cfg.impulse_post_s, cfg.overlap_window_s

    def slow_camera_s(self, stamp_s: float) -> float:
        """How much longer than the windows allow for (``rebound_frame_allowance_s``) the
        camera's frame is, as known at ``stamp_s``, s: a slower camera stamps a rebound up to a
        frame after the contact ended."""
        period = self.frame_period_at(stamp_s)
        return (
            0.0
            if period is None
            else max(0.0, period - self.config.detection.rebound_frame_allowance_s)
        )

    def rebound_window(self, impact: PendingImpact) -> tuple[float, float]:
        """Stamps a rebound of this impact may carry, s (widened for a slow camera)."""
        c = self.config.detection
        late = c.max_contact_s + self.slow_camera_s(impact.onset_s)
        if impact.source == "pressure":
            return (
                impact.onset_s - c.pressure_onset_uncertainty_s,
                impact.onset_s + late + c.pressure_onset_uncertainty_s,
            )
        if impact.pulse is None:
            return impact.onset_s, impact.rebound[0] if impact.rebound else impact.onset_s + late
        return impact.pulse.onset_s - c.rebound_early_tolerance_s, impact.pulse.onset_s + late

    def matching_rebound(self, impact: PendingImpact) -> tuple[float, np.ndarray] | None:
        """The first unused rebound within this impact's rebound window, or None."""
        lo, hi = self.rebound_window(impact)
        for stamp, velocity in self.rebounds:
            if lo <= stamp <= hi and stamp not in self.used_rebounds:
                return stamp, velocity
        return None

    def late_claimant(self, stamp_s: float) -> PendingImpact | None:
        """The impact a rebound that no window claims was stamped late for, or None: the latest
        onset before ``stamp_s`` (pending or decided) is a pulse's, still waiting without a
        rebound, at most ``late_rebound_max_s`` before it. A camera slower than its frame is
        known to be (:mod:`tail_beam_id.signals.camera`: read from the 4th rebound on, up to
        2 ms) stamps a rebound up to a frame after the contact ended; another impact's onset in
        between means the rebound may be that one's, and it is not given. Nor is it given to an
        impact whose own rebound window still holds an unused rebound: that one is its own, and
        the late one another lump's (a dense flow's next lump, whose pulse went unseen)."""
        late_s = self.config.detection.late_rebound_max_s
        onsets = [i.onset_s for i in self.pending] + self.decided
        before = [t for t in onsets if t < stamp_s]
        if late_s <= 0.0 or not before:
            return None
        latest = max(before)
        for impact in self.pending:
            if (
                impact.onset_s == latest
                and impact.pulse is not None
                and impact.rebound is None
                and stamp_s - impact.onset_s <= late_s
                and self.matching_rebound(impact) is None
            ):
                return impact
        return None

    def take_late_rebound(
        self, impact: PendingImpact, stamp_s: float, velocity_mps: np.ndarray
    ) -> None:
        """Give ``impact`` the rebound at ``stamp_s`` (s) that came after its window
        (late_claimant)."""
        impact.rebound = (stamp_s, velocity_mps)
        impact.late_rebound = True
        self.used_rebounds.add(stamp_s)

    def claimable(self, stamp_s: float) -> bool:
        """A pending impact without a rebound could still take the rebound at ``stamp_s``."""
        return any(
            i.rebound is None and self.rebound_window(i)[0] <= stamp_s <= self.rebound_window(i)[1]
            for i in self.pending
        )

    def neighbours(self, impact: PendingImpact) -> list[PendingImpact]:
        """Pending impacts whose onsets fall within the overlap window of this one's."""
        overlap_s = self.windows(impact)[2]
        return [
            o
            for o in self.pending
            if o is not impact and abs(o.onset_s - impact.onset_s) < overlap_s
        ]

    def known_onsets(self, impact: PendingImpact, before_s: float) -> list[float]:
        """Onsets (s) of the other impacts, pending or decided, from ``before_s`` before this
        one's up to the end of its overlap window: those its decision may rest on, known
        whatever the chunking once it is ready (:mod:`tail_beam_id.stream.readiness`; decided
        onsets are kept IdentifierConfig.kept_s before the oldest pending one)."""
        lo = impact.onset_s - before_s
        hi = impact.onset_s + self.windows(impact)[2]
        pending = [o.onset_s for o in self.pending if o is not impact]
        return sorted(t for t in pending + self.decided if lo <= t < hi)

    def overlapping(self, impact: PendingImpact) -> bool:
        """Another impact within the overlap window that something besides the IMU confirms (its
        own rebound, or detected from a rebound or the pressure), or one already labelled."""
        own = impact.rebound[0] if impact.rebound else None
        for other in self.neighbours(impact):
            if other.source != "imu" or other.rebound is not None:
                return True
            lo, hi = self.rebound_window(other)
            if any(
                lo <= stamp <= hi and stamp != own and stamp not in self.used_rebounds
                for stamp, _ in self.rebounds
            ):
                return True
        return any(abs(t - impact.onset_s) < self.windows(impact)[2] for t in self.decided)

    def camera_settled(self, impact: PendingImpact, newest_s: float) -> bool:
        """The camera has said all it will about this impact: it has its rebound, a rebound in
        its window is unambiguous (no neighbour could claim it), the camera has reported a later
        rebound, or ``camera_timeout_s`` of stamp time (``newest_s``: the newest stream stamp)
        has passed the window's end."""
        if impact.rebound is not None:
            return True
        _, rebound_end = self.rebound_window(impact)
        camera_passed = bool(self.rebounds) and self.rebounds[-1][0] > rebound_end
        if self.matching_rebound(impact) is not None and not self.neighbours(impact):
            return True
        return camera_passed or newest_s >= rebound_end + self.config.camera_timeout_s

    def take_rebound(self, impact: PendingImpact) -> None:
        """Give the impact its rebound (if it has none yet and one matches) and mark it used."""
        if impact.rebound is None:
            impact.rebound = self.matching_rebound(impact)
        if impact.rebound is not None:
            self.used_rebounds.add(impact.rebound[0])

    def data_horizon_s(self, impact: PendingImpact) -> float:
        """The latest stamp of data a decision on this impact needs (s): the data latency's end."""
        horizon = impact.onset_s + self.windows(impact)[0]
        if impact.rebound is not None:
            return max(horizon, impact.rebound[0])
        return max(horizon, self.rebound_window(impact)[1] + self.config.camera_timeout_s)

    def forget_before(self, stamp_s: float) -> None:
        """Drop rebounds and decided onsets older than ``stamp_s`` (s): no pending decision
        needs them."""
        self.rebounds = [r for r in self.rebounds if r[0] >= stamp_s]
        self.decided = [t for t in self.decided if t >= stamp_s]
        self.used_rebounds = {t for t in self.used_rebounds if t >= stamp_s}
