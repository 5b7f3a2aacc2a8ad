"""Feed recorded or simulated sensor streams to a StreamIdentifier, as the node would receive
them: in chunks of stamp time, each topic in order, the rebound when its stamp is reached."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np



from tail_beam_id.identifier import StreamIdentifier
from tail_beam_sim.physics.sensors import ImuStream, PressureStream, Rebound, VibrationBlocks


def replay(
    identifier: StreamIdentifier,
    pressure: PressureStream | None,
    imu: ImuStream | None,
    rebounds: Sequence[Rebound] = (),
    chunk_s: float = 0.01,
    vibration: VibrationBlocks | None = None,
) -> list[dict[str, Any]]:
    """Every label the identifier gives for these streams (polled per chunk, then flushed).

    A stream passed as None is absent (a sensor gone); ``chunk_s`` is the stamp-time span of
    each delivery. ``vibration`` (blocks in index order) goes to ``identifier.add_vibration``
    sample by sample stamp, each chunk's samples with the other streams'.
    """
    vib_stamps = vibration.sample_stamps_s() if vibration is not None and vibration.count else None
    starts = [s.stamp_s[0] for s in (pressure, imu) if s is not None and s.stamp_s.size]
    ends = [s.stamp_s[-1] for s in (pressure, imu) if s is not None and s.stamp_s.size]
    labels: list[dict[str, Any]] = []
    if not starts:
        for rebound in rebounds:
            identifier.add_rebound(rebound.stamp_s, rebound.velocity_mps)
        return identifier.flush()
    pending = sorted(rebounds, key=lambda r: r.stamp_s)
    first, last = min(starts), max(ends)
    count = int((last - first) / chunk_s) + 2
    # Chunk edges by multiplication, so consecutive chunks share one float edge exactly: no
    # sample is delivered twice or lost between them.
    edges = first + chunk_s * np.arange(count + 1)
    for low, high in zip(edges[:-1], edges[1:]):
        if pressure is not None:
            take = (pressure.stamp_s >= low) & (pressure.stamp_s < high)
            if take.any():
                identifier.add_pressure(pressure.stamp_s[take], pressure.pressure_pa[take])
        if imu is not None:
            take = (imu.stamp_s >= low) & (imu.stamp_s < high)
            if take.any():
                identifier.add_imu(imu.stamp_s[take], imu.angular_velocity_radps[take], imu.linear_acceleration_mps2[take])
        if vib_stamps is not None:
            take = (vib_stamps >= low) & (vib_stamps < high)
            if take.any():
                identifier.add_vibration(vib_stamps[take], vibration.accel_mps2[take].astype(float))
        while pending and pending[0].stamp_s < high:
            rebound = pending.pop(0)
            identifier.add_rebound(rebound.stamp_s, rebound.velocity_mps)
        labels += identifier.poll()
    for rebound in pending:
        identifier.add_rebound(rebound.stamp_s, rebound.velocity_mps)
    return labels + identifier.flush()


def stream_arrays(result: Any) -> tuple[PressureStream, ImuStream, list[Rebound]]:
    """The sensor streams of a SimulationResult, for :func:`replay`."""
    return result.pressure, result.imu, [result.rebound]



