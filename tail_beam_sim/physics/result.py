"""What simulating one scene produces (:class:`SimulationResult`), and the ``impact_truth``
object of an impact (contract: docs/interface.md), built by one function for the offline
simulation and the stream alike."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.sensors import (
    ImpactPoint,
    ImuStream,
    PressureStream,
    Rebound,
    VibrationBlocks,
)
from tail_beam_sim.physics.solvers import Trajectory

# Summary keys the truth already carries under their own names (from the impact itself).
_IMPACT_KEYS = ("material", "radius_m", "position_m", "impact_speed_mps")


def impact_truth(
    scene: Scene,
    trajectory: Trajectory,
    contact_stamp_s: float,
    rebound_stamp_s: float,
    summary: dict[str, Any],
) -> dict[str, Any]:
    """The ``impact_truth`` JSON object of the impact of ``scene``: what was dropped, when its
    contact started and ended and when the camera saw it leave (s, simulation time), and the
    noise-free ``summary`` figures."""
    impact = scene.impact
    first = trajectory.contacts[0]
    return {
        "impact_id": impact.impact_id,
        "material": impact.material.name,
        "material_class": impact.material.material_class,
        "label": "coal" if impact.material.is_coal else "gangue",
        "radius_m": impact.radius_m,
        "drop_height_m": impact.drop_height_m,
        "impact_speed_mps": impact.impact_speed_mps,
        "position_m": impact.position_m,
        "restitution_material": impact.restitution,
        "contact_model": scene.contact_model,
        "contact_start_stamp": contact_stamp_s,
        "contact_end_stamp": contact_stamp_s + first.end_s,
        "final_separation_stamp": contact_stamp_s + trajectory.final_separation_s,
        "rebound_stamp": rebound_stamp_s,
        **{k: v for k, v in summary.items() if k not in _IMPACT_KEYS},
    }


class LazyHistory(Mapping[str, np.ndarray]):
    """A result's noise-free histories, computed by ``compute`` when first read: a data set's
    users read the streams and the summary, seldom the histories, which cost as much as all
    the streams together."""

    def __init__(self, compute: Callable[[], dict[str, np.ndarray]]) -> None:
        self._compute: Callable[[], dict[str, np.ndarray]] | None = compute
        self._values: dict[str, np.ndarray] | None = None

    def _get(self) -> dict[str, np.ndarray]:
        if self._values is None:
            assert self._compute is not None
            self._values, self._compute = self._compute(), None
        return self._values

    def __getitem__(self, key: str) -> np.ndarray:
        return self._get()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._get())

    def __len__(self) -> int:
        return len(self._get())


@dataclass
class SimulationResult:
    """Everything one scene produced: the trajectory (time from first contact), its noise-free
    ``history`` (arrays sharing ``history['time_s']``), the sensor streams (absolute simulation
    time, as the topics stamp them; the contact at ``contact_stamp_s``) and the summary."""

    scene: Scene
    trajectory: Trajectory
    contact_stamp_s: float
    history: Mapping[str, np.ndarray]
    pressure: PressureStream
    imu: ImuStream
    rebound: Rebound
    summary: dict[str, Any] = field(default_factory=dict)
    vibration: VibrationBlocks = field(
        default_factory=lambda: VibrationBlocks.empty()
    )  # the accelerometer's blocks
    # Where the camera saw the particle strike (sensors.camera_reports_impact_point), else None.
    point: ImpactPoint | None = None

    def truth(self) -> dict[str, Any]:
        """The ``impact_truth`` JSON object of this impact (contract: docs/interface.md)."""
        return impact_truth(
            self.scene, self.trajectory, self.contact_stamp_s, self.rebound.stamp_s, self.summary
        )


__all__ = ["LazyHistory", "SimulationResult", "impact_truth"]
