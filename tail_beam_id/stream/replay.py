"""Feed recorded or simulated sensor streams to a StreamIdentifier, as the node would receive
them: in chunks of stamp time, each topic in order, the rebound when its stamp is reached."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.label import Label
from tail_beam_sim.physics.sensors import ImuStream, PressureStream, Rebound, VibrationBlocks


def replay(
    identifier: StreamIdentifier,
    pressure: PressureStream | None,
    imu: ImuStream | None,
    rebounds: Sequence[Rebound] = (),
    chunk_s: float = 0.01,
    vibration: VibrationBlocks | None = None,
    progress: Callable[[float, float], None] | None = None,
) -> list[Label]:
    """Every label the identifier gives for these streams (polled per chunk, then flushed).

    A stream passed as None is absent (a sensor gone); ``chunk_s`` is the stamp-time span of
    each delivery. ``vibration`` (blocks in index order) goes to ``identifier.add_vibration``
    sample by sample stamp, each chunk's samples with the other streams'. ``progress(done_s,
    total_s)`` is called about every PROGRESS_STEP of the streams' stamp time and at the end.
    """
    pressure, imu = _in_stamp_order(pressure), _in_stamp_order(imu)
    vib_stamps = vibration.sample_stamps_s() if vibration is not None and vibration.count else None
    # The span of every continuous stream, the accelerometer's too: one that starts earlier, runs
    # on after the others or is alone must not lose its samples outside theirs.
    spans = [s.stamp_s for s in (pressure, imu) if s is not None and s.stamp_s.size]
    if vib_stamps is not None and vib_stamps.size:
        spans.append(vib_stamps)
    starts = [float(np.min(stamps)) for stamps in spans]
    ends = [float(np.max(stamps)) for stamps in spans]
    labels: list[Label] = []
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
    # Each stream cut at the chunk edges once (searchsorted on the sorted stamps): a per-chunk
    # mask over the whole stream would cost samples x chunks on a long recording.
    every = max(1, int(count * PROGRESS_STEP))
    p_cut = np.searchsorted(pressure.stamp_s, edges) if pressure is not None else None
    i_cut = np.searchsorted(imu.stamp_s, edges) if imu is not None else None
    v_cut = np.searchsorted(vib_stamps, edges) if vib_stamps is not None else None
    for k, high in enumerate(edges[1:]):
        if p_cut is not None and p_cut[k + 1] > p_cut[k]:
            take = slice(p_cut[k], p_cut[k + 1])
            identifier.add_pressure(pressure.stamp_s[take], pressure.pressure_pa[take])
        if i_cut is not None and i_cut[k + 1] > i_cut[k]:
            take = slice(i_cut[k], i_cut[k + 1])
            identifier.add_imu(
                imu.stamp_s[take],
                imu.angular_velocity_radps[take],
                imu.linear_acceleration_mps2[take],
            )
        if v_cut is not None and v_cut[k + 1] > v_cut[k]:
            take = slice(v_cut[k], v_cut[k + 1])
            identifier.add_vibration(vib_stamps[take], vibration.accel_mps2[take].astype(float))
        while pending and pending[0].stamp_s < high:
            rebound = pending.pop(0)
            identifier.add_rebound(rebound.stamp_s, rebound.velocity_mps)
        labels += identifier.poll()
        if progress is not None and k % every == 0:
            progress(min(high, last) - first, last - first)
    for rebound in pending:
        identifier.add_rebound(rebound.stamp_s, rebound.velocity_mps)
    labels += identifier.flush()
    if progress is not None:
        progress(last - first, last - first)
    return labels


PROGRESS_STEP = 0.02  # replay reports its progress about every this fraction of the stream


def _in_stamp_order(stream: Any) -> Any:
    """``stream`` (PressureStream, ImuStream or None) with its samples in stamp order (a bag
    written out of order is read as recorded; the chunks are cut on sorted stamps)."""
    if stream is None or np.all(np.diff(stream.stamp_s) >= 0.0):
        return stream
    order = np.argsort(stream.stamp_s, kind="stable")
    fields = {f.name: getattr(stream, f.name) for f in dataclasses.fields(stream)}
    return dataclasses.replace(
        stream,
        **{
            k: v[order]
            for k, v in fields.items()
            if isinstance(v, np.ndarray) and v.shape[:1] == order.shape
        },
    )


def stream_arrays(result: Any) -> tuple[PressureStream, ImuStream, list[Rebound]]:
    """The sensor streams of a SimulationResult, for :func:`replay`."""
    return result.pressure, result.imu, [result.rebound]
