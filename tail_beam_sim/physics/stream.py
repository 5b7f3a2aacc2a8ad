"""A continuous stream simulator: simulation time and the beam's motion carried across impacts.

The offline :func:`tail_beam_sim.physics.simulate.simulate` solves one impact on a beam at rest. A
support in service is struck again and again while the beam still rings (its 40 Hz mode
decays over about half a second), and its data acquisition samples noise between impacts.
:class:`StreamSimulator` keeps that state:

* Each submitted impact is given a contact stamp (the requested one, or as soon as allowed:
  ``command_lead_s`` after the samples already produced and ``min_impact_gap_s`` after the
  previous particle left the plate), solved at once, and queued until the clock reaches it.
  The queue is bounded (``max_queued_impacts``): a command beyond it is refused with an
  :class:`InputError` that says so, never silently dropped.
* The beam's motion is linear between contacts, so each impact's trajectory is the motion
  carried in (the free response of the beam's displacement at the contact stamp) plus the
  solution of the impact with the beam's carried velocity as its initial velocity
  (:class:`CarriedTrajectory`). The particle meets the plate where the plate is at the
  contact stamp, so the solver's convention (contact at zero penetration) holds exactly.
* :meth:`StreamSimulator.advance` produces every sample of a time span at once (vectorised
  per chunk): jack pressure, IMU and accelerometer on their absolute grids ``k / rate`` (the
  accelerometer's complete blocks only: the rest of a block waits for the next span), the rebounds
  and truths whose stamps fall in the span. Noise is drawn per fixed block of sample indices, so
  the output depends only on the seed and the impacts, never on how the time was chunked
  (a real-time run and an as-fast-as-possible run give identical data).
* A caller that reads only some sensors names them (``channels``): the others are not
  simulated (the 25.6 kHz accelerometer is most of a chunk's sampling), and the channels kept
  are the same samples, bit for bit, as with every channel on.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from tail_beam_sim.config import section
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.fidelity import DEFAULT_TIER, get_tier, structure_for
from tail_beam_sim.physics.materials import Material, material_table
from tail_beam_sim.physics.result import impact_truth
from tail_beam_sim.physics.scene import Impact, Scene, SensorSpec
from tail_beam_sim.physics.sensors import (
    AntiAliasFilter,
    ImpactPoint,
    ImuLowPass,
    ImuStream,
    PressureStream,
    Rebound,
    SensorSuite,
    VibrationBlocks,
    cut_blocks,
    dense_imu_response,
    imu_samples,
    mean_specific_force_z,
)
from tail_beam_sim.physics.simulate import build_problem, histories, summarise
from tail_beam_sim.physics.solvers import DEFAULT_SOLVER, ImpactProblem, Samples, Trajectory, solve
from tail_beam_sim.physics.solvers.problem import FreeSegment
from tail_beam_sim.physics.structure import LinearStructure, load_bending_modes, rigid_beam
from tail_beam_sim.physics.support import Support
from tail_beam_sim.spec import SCENE, STREAM

NOISE_BLOCK_SAMPLES = 4096  # noise is drawn per block of this many sample indices (any size works)
_PRESSURE_NOISE_STREAM, _IMU_NOISE_STREAM, _VIBRATION_NOISE_STREAM = (
    0,
    1,
    2,
)  # keys of the noise streams under one seed
# The sampled sensors a simulator may leave out (the rebound camera is always on: it carries
# the impacts' truth with it).
CHANNELS = ("pressure", "imu", "vibration")
WITHOUT_ACCELEROMETER = ("pressure", "imu")  # a layout with no tail-beam accelerometer


class QueueFull(InputError):
    """An impact refused because ``stream.max_queued_impacts`` impacts are already waiting."""


STREAM_FIELDS = ("min_impact_gap_s", "command_lead_s", "max_queued_impacts")  # StreamParams


@dataclass(frozen=True)
class StreamParams:
    """Timing of the stream (s) and the bound of its impact queue."""

    min_impact_gap_s: float
    command_lead_s: float
    max_queued_impacts: int

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> StreamParams:
        """Validate the ``stream`` parameter section."""
        return cls(**STREAM.check(params, only=STREAM_FIELDS))


@dataclass
class CarriedTrajectory(Trajectory):
    """An impact's trajectory plus the free motion of the displacement carried in.

    The base trajectory was solved from the carried velocity with zero displacement; the
    carried displacement ``carried_q`` (generalised coordinates at t = 0) rings freely on
    top of it. The structure is linear, so the sum is the beam's exact motion.
    """

    carried_q: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @classmethod
    def carry(cls, trajectory: Trajectory, carried_q: np.ndarray) -> CarriedTrajectory:
        values = {f.name: getattr(trajectory, f.name) for f in fields(Trajectory)}
        return cls(**values, carried_q=np.asarray(carried_q, dtype=float))

    def sample(self, t_s: np.ndarray) -> Samples:
        out = super().sample(t_s)
        structure = self.problem.structure
        q, qd = structure.propagate(self.carried_q, np.zeros_like(self.carried_q), out.t_s)
        out.q = out.q + q
        out.qd = out.qd + qd
        out.qdd = out.qdd + structure.acceleration(
            q, qd, np.zeros(out.t_s.size), self.problem.contact_shape
        )
        return out


def rest_trajectory(structure: LinearStructure, gravity_mps2: float) -> Trajectory:
    """The beam at rest with no particle: the motion before the first impact."""
    zeros = np.zeros(structure.size)
    problem = ImpactProblem(
        structure=structure,
        contact_shape=zeros,
        mass_kg=0.0,
        hertz_stiffness=0.0,
        damping_factor=0.0,
        impact_speed_mps=0.0,
        gravity_mps2=gravity_mps2,
        window_s=0.0,
        q0=zeros,
        qd0=zeros,
    )
    return Trajectory(
        problem, [FreeSegment(-math.inf, math.inf, 0.0, zeros, zeros, 0.0, 0.0)], [], "rest", 0.0
    )


def _relative(stamp_s: np.ndarray, epoch_start_s: float) -> np.ndarray:
    """Stamps as times of an epoch's trajectory (the rest epoch, starting at -inf, has no
    origin)."""
    return stamp_s - epoch_start_s if math.isfinite(epoch_start_s) else stamp_s


def _split_by_epoch(
    epoch_starts: list[float], stamp_s: np.ndarray
) -> list[tuple[int, np.ndarray | slice]]:
    """The epochs (index into ``epoch_starts``, s, ascending) that stamps fall in, each with
    where its stamps are: a slice when the stamps do not decrease (every sensor's grid), else a
    mask."""
    if stamp_s.size == 0:
        return []
    if len(epoch_starts) == 1:
        return [(0, slice(None))]
    which = np.searchsorted(np.array(epoch_starts), stamp_s, side="right") - 1
    if stamp_s.size < 2 or bool((stamp_s[1:] >= stamp_s[:-1]).all()):
        first, last = int(which[0]), int(which[-1])
        if first == last:
            return [(first, slice(None))]
        edges = np.searchsorted(which, np.arange(first, last + 2)).tolist()
        return [
            (k, slice(lo, hi))
            for k, lo, hi in zip(range(first, last + 1), edges[:-1], edges[1:])
            if hi > lo
        ]
    return [(int(k), which == k) for k in np.unique(which)]


class EpochBatch:
    """Times asked of the epochs by several sensors, sampled in one pass per epoch.

    :meth:`ask` registers times (an epoch's own time) and returns a ticket; :meth:`run` samples
    each epoch once at every time asked of it (each time's state does not depend on the others
    asked with it, :meth:`Trajectory.sample_many`); :meth:`get` gives a ticket's samples."""

    def __init__(self, epochs: list[Trajectory]) -> None:
        self._epochs = epochs
        self._asked: dict[int, list[np.ndarray]] = {}
        self._results: dict[int, list[Samples]] = {}

    def ask(self, epoch: int, t_s: np.ndarray) -> tuple[int, int]:
        """Register times ``t_s`` of epoch ``epoch``; the ticket names them."""
        parts = self._asked.setdefault(epoch, [])
        parts.append(t_s)
        return epoch, len(parts) - 1

    def run(self) -> None:
        """Sample every epoch asked, once."""
        for epoch, parts in self._asked.items():
            self._results[epoch] = self._sample(self._epochs[epoch], parts)

    def _sample(self, trajectory: Trajectory, parts: list[np.ndarray]) -> list[Samples]:
        """One epoch at several sets of times, in one pass."""
        return trajectory.sample_many(parts)

    def get(self, ticket: tuple[int, int]) -> Samples:
        """The samples of the times a ticket names."""
        return self._results[ticket[0]][ticket[1]]


class BlockNoise:
    """Standard normal noise indexed by sample number, independent of how it is requested.

    Block ``k`` (indices ``k*B .. k*B+B-1``) comes from its own generator seeded with
    ``(seed, stream, k)``, so samples ``i..j`` are the same whether asked for at once or in
    pieces.
    """

    def __init__(
        self, seed: int, stream: int, width: int, block_samples: int = NOISE_BLOCK_SAMPLES
    ) -> None:
        self._key = (seed, stream)
        self._width = width
        self._block = block_samples
        self._cache: dict[int, np.ndarray] = {}

    def _get_block(self, k: int) -> np.ndarray:
        if k not in self._cache:
            if len(self._cache) > 2:
                self._cache.pop(min(self._cache))
            rng = np.random.default_rng([*self._key, k])
            self._cache[k] = rng.standard_normal((self._block, self._width))
        return self._cache[k]

    def take(self, first: int, count: int) -> np.ndarray:
        """Noise of sample indices ``first .. first+count-1``, shape (count, width)."""
        out = np.empty((count, self._width))
        done = 0
        while done < count:
            k, offset = divmod(first + done, self._block)
            n = min(count - done, self._block - offset)
            out[done : done + n] = self._get_block(k)[offset : offset + n]
            done += n
        return out


@dataclass(frozen=True)
class ScheduledImpact:
    """An impact given its contact stamp (s), solved, with its rebound and truth."""

    impact: Impact
    contact_stamp_s: float
    trajectory: CarriedTrajectory
    rebound: Rebound
    truth: dict[str, Any]
    # Where the camera saw it strike (sensors.camera_reports_impact_point), else None.
    point: ImpactPoint | None = None

    @property
    def impact_id(self) -> str:
        return self.impact.impact_id

    @property
    def free_after_s(self) -> float:
        """When the particle last left the plate, s of simulation time."""
        return self.contact_stamp_s + self.trajectory.final_separation_s

    @property
    def truth_stamp_s(self) -> float:
        """When the truth is published: the end of the impact's simulated window, s."""
        return self.contact_stamp_s + self.trajectory.problem.window_s


@dataclass
class Chunk:
    """Everything the sensors produced in the span (start_s, end_s] of simulation time."""

    start_s: float
    end_s: float
    pressure: PressureStream
    imu: ImuStream
    vibration: VibrationBlocks  # the accelerometer's blocks completed in the span, in index order
    rebounds: list[tuple[str, Rebound]]  # (impact_id, rebound), in stamp order
    truths: list[
        tuple[float, dict[str, Any]]
    ]  # (stamp s, impact_truth JSON object), in stamp order
    started: list[ScheduledImpact]  # impacts whose contact stamp fell in the span
    # (impact_id, impact point) stamped in the span, in stamp order: each with its rebound's
    # stamp (sensors.camera_reports_impact_point; empty otherwise)
    points: list[tuple[str, ImpactPoint]] = field(default_factory=list)


class StreamSimulator:
    """Simulation time, the beam's state and the impact queue of one support."""

    def __init__(
        self,
        support: Support,
        materials: Mapping[str, Material],
        sensors: SensorSpec,
        stream: StreamParams,
        contact_model: str,
        window_s: float,
        structure: LinearStructure | None = None,
        solver: str = DEFAULT_SOLVER,
        id_prefix: str = "sim",
        channels: Collection[str] = CHANNELS,
    ) -> None:
        """``channels``: the sampled sensors simulated (:data:`CHANNELS`); a chunk holds no
        samples of the others."""
        unknown = sorted(set(channels) - set(CHANNELS))
        if unknown:
            raise InputError("channels", unknown, f"must be among {', '.join(CHANNELS)}")
        self.channels = frozenset(channels)
        self.support = support
        self.materials = materials
        self.sensors = sensors
        self.params = stream
        self.contact_model = contact_model
        self.window_s = window_s
        self.structure = structure or rigid_beam(support)
        self.solver = solver
        self.id_prefix = id_prefix
        self._suite = SensorSuite(sensors)
        self._pressure_noise = BlockNoise(sensors.seed, _PRESSURE_NOISE_STREAM, 1)
        self._imu_noise = BlockNoise(sensors.seed, _IMU_NOISE_STREAM, 6)
        self._vibration_noise = BlockNoise(sensors.seed, _VIBRATION_NOISE_STREAM, 1)
        self._antialias = AntiAliasFilter(
            sensors.vibration_rate_hz,
            sensors.vibration_antialias_order,
            sensors.vibration_antialias_cutoff_fraction,
            sensors.vibration_oversample,
        )
        self._imu_lowpass = (
            ImuLowPass(sensors) if sensors.imu_antialias_order > 0 else None
        )  # None: period means
        self._next_dense_index = 0  # the accelerometer's next dense (oversampled) value
        self._vibration_tail = np.empty(0, dtype=np.float32)  # samples of the incomplete block
        self._vibration_tail_first = 0  # running index of the first of them
        self._epoch_starts: list[float] = [-math.inf]
        self._epochs: list[Trajectory] = [rest_trajectory(self.structure, support.gravity_mps2)]
        self._queue: deque[ScheduledImpact] = deque()  # solved, contact stamp not yet reached
        self._pending_events: list[ScheduledImpact] = []  # started, rebound or truth not yet out
        self._next_pressure_index = 0
        self._next_imu_index = 0
        self._time_s = 0.0
        self._count = 0
        self._last_free_after_s = (
            -math.inf
        )  # when the latest scheduled particle leaves the plate, s
        self._ids: set[str] = set()  # every impact_id of this run: each names one impact

    @classmethod
    def from_params(cls, params: Mapping[str, Any], **options: Any) -> StreamSimulator:
        """Build from merged parameters: support, materials, sensors, scene, stream sections.

        ``stream.tier`` picks the model (``tail_beam_sim.physics.fidelity.TIERS``): its structure
        (bending modes from the ``modes`` section) and its solver.
        """
        materials = material_table(params)
        support = Support.from_params(section(params, "support"), materials)
        tier = get_tier(section(params, "stream").get("tier", DEFAULT_TIER))
        scene = SCENE.check(section(params, "scene"), only=("contact_model", "window_s"))
        return cls(
            support=support,
            materials=materials,
            sensors=SensorSpec.from_params(section(params, "sensors")),
            stream=StreamParams.from_params(section(params, "stream")),
            **scene,
            structure=structure_for(tier, support, load_bending_modes(params)),
            solver=tier.default_solver,
            **options,
        )

    @property
    def time_s(self) -> float:
        """Simulation time up to which samples have been produced, s."""
        return self._time_s

    @property
    def queued(self) -> int:
        """Impacts accepted whose contact has not started yet."""
        return len(self._queue)

    @property
    def earliest_contact_s(self) -> float:
        """The earliest contact stamp a new impact can get now, s."""
        after_last = self._last_free_after_s + self.params.min_impact_gap_s
        return max(self._time_s + self.params.command_lead_s, after_last)

    def submit(
        self, command: Mapping[str, Any], contact_stamp_s: float | None = None
    ) -> ScheduledImpact:
        """Validate, schedule and solve one impact (``impact_cmd`` JSON object).

        Raises InputError naming the field for a bad command or an impact_id used before in this
        run (an id names one impact: truths and labels are matched by it), and QueueFull when
        the queue is full. ``contact_stamp_s`` asks for a contact time; it is moved later if not
        allowed yet. A missing impact_id is made up: ``<id_prefix>-<count>``, never one in use.
        """
        impact = Impact.from_mapping(command, self.materials, self.support)
        if impact.impact_id in self._ids:
            raise InputError(
                "impact_id",
                impact.impact_id,
                "already names an earlier impact of this run; give each impact its own id",
            )
        if len(self._queue) >= self.params.max_queued_impacts:
            raise QueueFull(
                "impact_cmd",
                impact.impact_id or dict(command),
                f"refused: queue full, {len(self._queue)} impacts already queued "
                "(stream.max_queued_impacts); "
                "send impacts more slowly or raise the limit",
            )
        self._count += 1
        if not impact.impact_id:
            made_up = f"{self.id_prefix}-{self._count:04d}"
            while made_up in self._ids:
                made_up += "+"
            impact = replace(impact, impact_id=made_up)
        self._ids.add(impact.impact_id)
        stamp = max(
            contact_stamp_s if contact_stamp_s is not None else -math.inf, self.earliest_contact_s
        )
        scheduled = self._solve(impact, stamp)
        self._queue.append(scheduled)
        self._last_free_after_s = scheduled.free_after_s
        return scheduled

    def _solve(self, impact: Impact, stamp_s: float) -> ScheduledImpact:
        """Solve ``impact`` at ``stamp_s`` on the beam as the previous impacts leave it."""
        before = self._epochs[-1].sample(_relative(np.array([stamp_s]), self._epoch_starts[-1]))
        q0, qd0 = before.q[:, 0], before.qd[:, 0]
        problem = build_problem(
            self.support, impact, self.contact_model, self.window_s, self.structure, qd0=qd0
        )
        trajectory = CarriedTrajectory.carry(solve(problem, self.solver), q0)
        self._epoch_starts.append(stamp_s)
        self._epochs.append(trajectory)
        rebound = self._suite.rebound(trajectory, stamp_s)
        point = self._suite.reported_point(impact.position_m, rebound, self.support)
        scene = Scene(
            self.support,
            impact,
            self.sensors,
            self.materials,
            self.contact_model,
            self.window_s,
            0.0,
        )
        summary = summarise(scene, trajectory, histories(scene, trajectory))
        return ScheduledImpact(
            impact,
            stamp_s,
            trajectory,
            rebound,
            impact_truth(scene, trajectory, stamp_s, rebound.stamp_s, summary),
            point,
        )

    def advance(self, until_s: float) -> Chunk:
        """Produce every sample, rebound and truth in (time_s, until_s]; the clock moves on."""
        start = self._time_s
        until = max(float(until_s), start)
        spec, on = self.sensors, self.channels
        pressure_index = self._grid(self._next_pressure_index, until, spec.pressure_rate_hz)
        imu_index = self._grid(self._next_imu_index, until, spec.imu_rate_hz)
        # Every sensor's instants of the span, sampled in one pass per epoch: the sensors ask
        # the same few epochs, and the work per call weighs as much as the work per instant.
        batch = self._epoch_batch()
        pressure = self._pressure(pressure_index, batch) if "pressure" in on else self._no_pressure
        imu = self._imu(imu_index, batch) if "imu" in on else self._no_imu
        vibration = self._vibration(until, batch) if "vibration" in on else self._no_vibration
        batch.run()
        pressure, imu, vibration = pressure(), imu(), vibration()
        self._next_pressure_index += pressure_index.size
        self._next_imu_index += imu_index.size
        started = []
        while self._queue and self._queue[0].contact_stamp_s <= until:
            started.append(self._queue.popleft())
        self._pending_events.extend(started)
        rebounds = [
            (s.impact_id, s.rebound)
            for s in self._pending_events
            if start < s.rebound.stamp_s <= until
        ]
        truths = [
            (s.truth_stamp_s, s.truth)
            for s in self._pending_events
            if start < s.truth_stamp_s <= until
        ]
        rebounds.sort(key=lambda r: r[1].stamp_s)
        points = [
            (s.impact_id, s.point)
            for s in self._pending_events
            if s.point is not None and start < s.point.stamp_s <= until
        ]
        points.sort(key=lambda p: p[1].stamp_s)
        truths.sort(key=lambda t: t[0])
        self._pending_events = [
            s for s in self._pending_events if max(s.rebound.stamp_s, s.truth_stamp_s) > until
        ]
        self._time_s = until
        self._prune()
        return Chunk(start, until, pressure, imu, vibration, rebounds, truths, started, points)

    def _epoch_batch(self) -> EpochBatch:
        """A batch of the times the sensors ask of the epochs kept."""
        return EpochBatch(self._epochs)

    def _no_pressure(self) -> PressureStream:
        """A chunk's jack pressure with the channel off: no sample."""
        return PressureStream(np.empty(0), np.empty(0), self._suite.noise.pressure_pa**2)

    def _no_imu(self) -> ImuStream:
        """A chunk's IMU with the channel off: no sample."""
        noise = self._suite.noise
        return ImuStream(
            np.empty(0),
            np.empty((0, 3)),
            np.empty((0, 3)),
            noise.gyro_radps**2,
            noise.accel_mps2**2,
        )

    def _no_vibration(self) -> VibrationBlocks:
        """A chunk's accelerometer blocks with the channel off: none."""
        spec = self.sensors
        return VibrationBlocks.empty(1.0 / spec.vibration_rate_hz, spec.vibration_range_mps2)

    @staticmethod
    def _grid(first_index: int, until_s: float, rate_hz: float) -> np.ndarray:
        last = math.floor(until_s * rate_hz + 1e-9)
        return np.arange(first_index, max(last + 1, first_index))

    def _by_epoch(self, stamp_s: np.ndarray) -> list[tuple[Trajectory, float, np.ndarray]]:
        """Split stamps by the epoch (trajectory and its start, s) they fall in."""
        return [
            (self._epochs[k], self._epoch_starts[k], where)
            for k, where in _split_by_epoch(self._epoch_starts, stamp_s)
        ]

    def _pressure(self, index: np.ndarray, batch: EpochBatch) -> Callable[[], PressureStream]:
        """Ask ``batch`` for the jack's states at samples ``index``; the returned function gives
        the stream once the batch has run."""
        spec = self.sensors
        stamps = index / spec.pressure_rate_hz
        asked = [
            (where, batch.ask(k, _relative(stamps[where], self._epoch_starts[k])))
            for k, where in _split_by_epoch(self._epoch_starts, stamps)
        ]

        def finish() -> PressureStream:
            clean = np.empty(stamps.size)
            for where, ticket in asked:
                state = batch.get(ticket)
                clean[where] = self.structure.pressure_pa(state.q, state.qd)
            unit = (
                self._pressure_noise.take(int(index[0]), index.size)[:, 0]
                if index.size
                else np.empty(0)
            )
            noise = self._suite.noise
            return PressureStream(stamps, noise.pressure(clean, unit), noise.pressure_pa**2)

        return finish

    def _imu(self, index: np.ndarray, batch: EpochBatch) -> Callable[[], ImuStream]:
        """Ask ``batch`` for the IMU's states at samples ``index`` and a period before; the
        returned function gives the stream once the batch has run."""
        spec = self.sensors
        stamps = index / spec.imu_rate_hz
        period = 1.0 / spec.imu_rate_hz
        asked = []
        for k, where in _split_by_epoch(self._epoch_starts, stamps):
            times = _relative(stamps[where], self._epoch_starts[k])
            asked.append((k, where, times, batch.ask(k, times), batch.ask(k, times - period)))

        def finish() -> ImuStream:
            gyro, accel = np.empty((stamps.size, 3)), np.empty((stamps.size, 3))
            for k, where, times, now, before in asked:
                gyro[where], accel[where] = imu_samples(
                    self._epochs[k], times, period, (batch.get(now), batch.get(before))
                )
            if self._imu_lowpass is not None:
                accel[:, 2], gyro[:, 1] = self._imu_lowpass(index, self._dense_imu_response)
            noise = self._suite.noise
            if index.size:
                unit = self._imu_noise.take(int(index[0]), index.size)
                gyro, accel = noise.gyro(gyro, unit[:, :3]), noise.accel(accel, unit[:, 3:])
            return ImuStream(stamps, gyro, accel, noise.gyro_radps**2, noise.accel_mps2**2)

        return finish

    def _dense_imu_response(self, stamps_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The beam's (specific force z, pitch rate) at the IMU for its low-pass filter, at
        absolute stamps."""
        dense_period = 1.0 / (self.sensors.imu_oversample * self.sensors.imu_rate_hz)
        accel, rate = np.empty(stamps_s.size), np.empty(stamps_s.size)
        for trajectory, start, mask in self._by_epoch(stamps_s):
            accel[mask], rate[mask] = dense_imu_response(
                trajectory, _relative(stamps_s[mask], start), dense_period
            )
        return accel, rate

    def _vibration(self, until_s: float, batch: EpochBatch) -> Callable[[], VibrationBlocks]:
        """Ask ``batch`` for the accelerometer's dense instants up to ``until_s``; the returned
        function gives the blocks completed once the batch has run: dense response, anti-alias
        filter, decimation, noise, clipping (block b holds indices b*N .. b*N+N-1)."""
        spec = self.sensors
        m = spec.vibration_oversample
        dense_rate = m * spec.vibration_rate_hz
        dense_index = self._grid(self._next_dense_index, until_s, dense_rate)
        self._next_dense_index += dense_index.size
        stamps = dense_index / dense_rate
        asked = []
        for k, where in _split_by_epoch(self._epoch_starts, stamps):
            # Each dense value is the mean over the period before its instant, which the
            # instant before bounds: the epoch's instants and the one before the first,
            # evaluated once each (index / rate, as every chunk cuts them).
            index = dense_index[where]
            times = np.concatenate([[index[0] - 1], index]) / dense_rate
            asked.append((k, where, batch.ask(k, _relative(times, self._epoch_starts[k]))))

        def finish() -> VibrationBlocks:
            dense = np.empty(stamps.size)
            for k, where, ticket in asked:
                states = batch.get(ticket)
                dense[where] = mean_specific_force_z(
                    self._epochs[k],
                    states.t_s[1:],
                    1.0 / dense_rate,
                    (states.take(slice(1, None)), states.take(slice(None, -1))),
                )
            return self._vibration_blocks(dense_index, dense)

        return finish

    def _vibration_blocks(self, dense_index: np.ndarray, dense: np.ndarray) -> VibrationBlocks:
        """The accelerometer's dense values through its filter, decimation, noise and
        clipping, cut into the blocks completed."""
        spec = self.sensors
        m = spec.vibration_oversample
        # Every dense value goes through the filter once, in order; sample i is the filter's
        # output at dense index m * i (stamp i / rate).
        offset = -int(dense_index[0]) % m if dense_index.size else 0  # the first at a sample
        filtered = self._antialias(dense)[offset::m]
        first = (int(dense_index[0]) + offset) // m if filtered.size else 0
        sigma = spec.vibration_noise_mps2
        if filtered.size:
            filtered = filtered + sigma * self._vibration_noise.take(first, filtered.size)[:, 0]
        clipped = np.clip(filtered, -spec.vibration_range_mps2, spec.vibration_range_mps2)
        blocks, self._vibration_tail = cut_blocks(
            np.concatenate([self._vibration_tail, clipped]), self._vibration_tail_first, spec
        )
        self._vibration_tail_first += blocks.sample_count
        return blocks

    def _prune(self) -> None:
        """Forget epochs that no future sample can fall in (keep one IMU period of history)."""
        horizon = self._time_s - 2.0 / self.sensors.imu_rate_hz
        while len(self._epoch_starts) > 1 and self._epoch_starts[1] <= horizon:
            self._epoch_starts.pop(0)
            self._epochs.pop(0)
