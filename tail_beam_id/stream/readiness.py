"""When a pending impact may be decided: once the data it needs have arrived, judged on stamps
only so that the labels do not depend on how the data came.

An impact is ready once every live continuous stream has passed its onset plus its data window,
the acceleration channel has been scanned over its overlap window (no pulse still held there)
and far enough past it that every rebound whose onset falls in that window and that no pulse
claims has become an impact of its own (so its overlap flag does not depend on how the streams
were chunked), no rebound it may yet claim late is undecided, and the camera has settled
(:meth:`tail_beam_id.stream.association.ImpactAssociation.camera_settled`).
"""

from __future__ import annotations

from tail_beam_id.stream.association import ImpactAssociation, PendingImpact
from tail_beam_id.stream.camera_frame import CameraFrame
from tail_beam_id.stream.channels import SensorChannels
from tail_beam_id.stream.config import IdentifierConfig
from tail_beam_id.stream.detection import ImpactFinder


class Readiness:
    """Whether a pending impact's data are all in (module docstring)."""

    def __init__(
        self,
        config: IdentifierConfig,
        channels: SensorChannels,
        finder: ImpactFinder,
        association: ImpactAssociation,
        camera: CameraFrame,
    ) -> None:
        """The parts of the identifier whose progress readiness reads."""
        self.config = config
        self.channels = channels
        self.finder = finder
        self.association = association
        self.camera = camera

    def ready(self, impact: PendingImpact) -> bool:
        """Every live stream has passed the impact's data window, the acceleration channel has
        been scanned over its overlap window (and no held pulse lies in it), no late rebound
        of it is undecided, and the camera has settled."""
        channels = self.channels
        window_s, _, overlap_s = self.association.windows(impact)
        horizon_s = impact.onset_s + window_s
        for series in channels.continuous():
            if channels.live(series, False) and series.latest_s < horizon_s:
                return False
        accel = channels.acceleration_in_use()
        if channels.live(accel, False) and self.finder.onsets_known_s() < self._scan_needed_s(
            impact.onset_s + overlap_s
        ):
            return False
        if any(p.onset_s < impact.onset_s + overlap_s for p in self.finder.waiting_pulses()):
            return False
        if self._late_rebound_undecided(impact):
            return False
        return self.association.camera_settled(impact, channels.newest_s())

    def _scan_needed_s(self, overlap_end_s: float) -> float:
        """Stamp every pulse onset must be known to (ImpactFinder.onsets_known_s) before an
        impact whose overlap window ends at ``overlap_end_s`` (s) is decided: a rebound stamped
        up to ``rebound_onset_lead_s`` after that end has its onset in the window, and the
        finder makes it an impact of its own once onsets are known
        ``rebound_early_tolerance_s`` past its stamp
        (:meth:`tail_beam_id.stream.detection.ImpactFinder.find_rebound_impacts`)."""
        c = self.config.detection
        return overlap_end_s + c.rebound_onset_lead_s + c.rebound_early_tolerance_s

    def _late_rebound_undecided(self, impact: PendingImpact) -> bool:
        """A rebound this impact may claim late (ImpactAssociation.late_claimant) has come, but
        the acceleration channel has not yet been scanned past it: a pulse there would make it
        that impact's instead. The impact waits (it would otherwise be decided without the
        camera, and the rebound become an impact of its own)."""
        if (
            impact.pulse is None
            or impact.rebound is not None
            or self.config.detection.late_rebound_max_s <= 0.0
        ):
            return False
        if not self.channels.live(self.channels.acceleration_in_use(), False):
            return False
        association = self.association
        settled_s = self.finder.onsets_known_s() - self.config.detection.rebound_early_tolerance_s
        # The conditions ImpactFinder claims a late rebound on, the camera's frame as known at
        # the rebound's own stamp.
        return any(
            stamp not in association.used_rebounds
            and stamp > settled_s
            and not association.claimable(stamp)
            and self.camera.may_be_slower(stamp)
            and association.late_claimant(stamp) is impact
            for stamp, _ in association.rebounds
        )
