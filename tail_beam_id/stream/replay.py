"""Feed recorded or simulated sensor streams to a StreamIdentifier, as the node would receive
them: in chunks of stamp time, each topic in order, the rebound when its stamp is reached."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.label import Label
from tail_beam_sim.physics.sensors import (
    ImpactPoint,
    ImuStream,
    PressureStream,
    Rebound,
    VibrationBlocks,
)
from tail_beam_sim.topics import FRAME_PLATE

# One impact point as replay takes it: (stamp s, frame_id, (x, y, z) on the plate, m).
Point = tuple[float, str, np.ndarray]


def replay(
    identifier: StreamIdentifier,
    pressure: PressureStream | None,
    imu: ImuStream | None,
    rebounds: Sequence[Rebound] = (),
    chunk_s: float = 0.01,
    vibration: VibrationBlocks | None = None,
    progress: Callable[[float, float], None] | None = None,
    points: Sequence[Point] = (),
) -> list[Label]:
    """Every label the identifier gives for these streams (polled per chunk, then flushed).
    ``points``: where the camera saw the particles strike, (stamp s, frame_id, (x, y, z) m),
    each given with the chunk of its stamp, after the rebounds.

    A stream passed as None is absent (a sensor gone); ``chunk_s`` is the stamp-time span of
    each delivery. ``vibration`` (blocks in index order) goes to ``identifier.add_vibration``
    sample by sample stamp, each chunk's samples with the other streams'. ``progress(done_s,
    total_s)`` is called about every PROGRESS_STEP of the streams' stamp time and at the end.
    """
    pressure, imu = _in_stamp_order(pressure), _in_stamp_order(imu)
    vib_stamps = vibration.sample_stamps_s() if vibration is not None and vibration.count else None
    # The span of every continuous stream, the accelerometer's too: one that starts earlier, runs
    # on after the others or is alone must not lose its samples outside theirs.
    spans = [s.stamp_s for s in (pressure, imu) if s is not None]
    if vib_stamps is not None:
        spans.append(vib_stamps)
    spans = [stamps[np.isfinite(stamps)] for stamps in spans]  # a stamp not finite: refused
    spans = [stamps for stamps in spans if stamps.size]
    starts = [float(np.min(stamps)) for stamps in spans]
    ends = [float(np.max(stamps)) for stamps in spans]
    labels: list[Label] = []
    if not starts:
        for rebound in rebounds:
            identifier.add_rebound(rebound.stamp_s, rebound.velocity_mps)
        for stamp, frame_id, point in points:
            identifier.add_impact_point(stamp, point, frame_id)
        return identifier.flush()
    first, last = min(starts), max(ends)
    # The chunks cover the streams' span; a rebound after it (or not finite) is given at the end.
    end_edge = first + chunk_s * (int((last - first) / chunk_s) + 2)
    pending = sorted(
        (r for r in rebounds if math.isfinite(r.stamp_s) and r.stamp_s < end_edge),
        key=lambda r: r.stamp_s,
    )
    after = [r for r in rebounds if not (math.isfinite(r.stamp_s) and r.stamp_s < end_edge)]
    pending_points = sorted(
        (p for p in points if math.isfinite(p[0]) and p[0] < end_edge), key=lambda p: p[0]
    )
    points_after = [p for p in points if not (math.isfinite(p[0]) and p[0] < end_edge)]
    streams = [
        (pressure.stamp_s, _deliver_pressure(identifier, pressure))
        if pressure is not None
        else None,
        (imu.stamp_s, _deliver_imu(identifier, imu)) if imu is not None else None,
        (vib_stamps, _deliver_vibration(identifier, vib_stamps, vibration))
        if vib_stamps is not None
        else None,
    ]
    streams = [s for s in streams if s is not None]
    done = [0] * len(streams)  # per stream, the samples delivered
    limit = [int(np.searchsorted(stamps, end_edge)) for stamps, _ in streams]
    step = max(chunk_s, PROGRESS_STEP * (last - first))
    reported = -math.inf
    k = 0  # the chunk [edge(k), edge(k + 1)), edge(k) = first + chunk_s * k
    while True:
        # A chunk that holds nothing changes nothing: go straight to the one holding the next
        # sample or rebound, so a stamp far ahead (a clock gone wrong, a new time base) costs
        # no walk across the stretch before it.
        upcoming = [
            float(stamps[done[n]]) for n, (stamps, _) in enumerate(streams) if done[n] < limit[n]
        ]
        if pending:
            upcoming.append(pending[0].stamp_s)
        if pending_points:
            upcoming.append(pending_points[0][0])
        if not upcoming:
            break
        k = _chunk_of(min(upcoming), first, chunk_s, k)
        high = first + chunk_s * (k + 1)
        for n, (stamps, deliver) in enumerate(streams):
            end = min(limit[n], int(np.searchsorted(stamps, high)))
            if end > done[n]:
                deliver(done[n], end)
                done[n] = end
        while pending and pending[0].stamp_s < high:
            rebound = pending.pop(0)
            identifier.add_rebound(rebound.stamp_s, rebound.velocity_mps)
        while pending_points and pending_points[0][0] < high:
            stamp, frame_id, point = pending_points.pop(0)
            identifier.add_impact_point(stamp, point, frame_id)
        labels += identifier.poll()
        if progress is not None and high - reported >= step:
            progress(min(high, last) - first, last - first)
            reported = high
        k += 1
    for rebound in after:
        identifier.add_rebound(rebound.stamp_s, rebound.velocity_mps)
    for stamp, frame_id, point in points_after:
        identifier.add_impact_point(stamp, point, frame_id)
    labels += identifier.flush()
    if progress is not None:
        progress(last - first, last - first)
    return labels


def _chunk_of(stamp_s: float, first_s: float, chunk_s: float, at_least: int) -> int:
    """The chunk ``k`` (not before ``at_least``) whose edges ``first_s + chunk_s * k`` and
    ``... * (k + 1)`` hold ``stamp_s``, by the same float product that cuts the chunks."""
    if not math.isfinite(stamp_s):
        return at_least
    k = max(at_least, int((stamp_s - first_s) // chunk_s))
    while k > at_least and first_s + chunk_s * k > stamp_s:
        k -= 1
    while first_s + chunk_s * (k + 1) <= stamp_s:
        k += 1
    return k


def _deliver_pressure(identifier: StreamIdentifier, stream: PressureStream) -> Callable:
    def deliver(start: int, end: int) -> None:
        identifier.add_pressure(stream.stamp_s[start:end], stream.pressure_pa[start:end])

    return deliver


def _deliver_imu(identifier: StreamIdentifier, stream: ImuStream) -> Callable:
    def deliver(start: int, end: int) -> None:
        identifier.add_imu(
            stream.stamp_s[start:end],
            stream.angular_velocity_radps[start:end],
            stream.linear_acceleration_mps2[start:end],
        )

    return deliver


def _deliver_vibration(
    identifier: StreamIdentifier, stamps: np.ndarray, blocks: VibrationBlocks
) -> Callable:
    def deliver(start: int, end: int) -> None:
        identifier.add_vibration(stamps[start:end], blocks.accel_mps2[start:end].astype(float))

    return deliver


def point_tuples(points: Sequence[ImpactPoint]) -> list[Point]:
    """Simulated impact points as :func:`replay` takes them (in the plate frame)."""
    return [(p.stamp_s, FRAME_PLATE, p.point_m) for p in points]


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
