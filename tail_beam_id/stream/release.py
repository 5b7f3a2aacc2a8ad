"""A batch of samples in stamp order, as the arrival gate releases it to the identifier."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from tail_beam_id.stream.identifier import StreamIdentifier


@dataclass
class Release:
    """What the identifier may now be given, per stream in stamp order."""

    streams: dict[str, tuple[np.ndarray, np.ndarray]]  # name -> (stamp_s (T,), values (T, k))
    rebounds: list[tuple[float, np.ndarray]]  # (stamp_s, velocity_mps (3,))
    # impact points: (stamp_s, frame_id, point_m (3,)), in stamp order
    points: list[tuple[float, str, np.ndarray]] = field(default_factory=list)

    @property
    def empty(self) -> bool:
        return not self.streams and not self.rebounds and not self.points


def feed(identifier: StreamIdentifier, release: Release) -> None:
    """Give ``identifier`` what the gate released (each stream in stamp order, then rebounds,
    then impact points)."""
    for name, (stamps, values) in release.streams.items():
        if name == "jack_pressure":
            identifier.add_pressure(stamps, values[:, 0])
        elif name == "imu":
            identifier.add_imu(stamps, values[:, :3], values[:, 3:])
        else:
            identifier.add_vibration(stamps, values[:, 0])
    for stamp, velocity in release.rebounds:
        identifier.add_rebound(stamp, velocity)
    for stamp, frame_id, point in release.points:
        identifier.add_impact_point(stamp, point, frame_id)


__all__ = ["Release", "feed"]
