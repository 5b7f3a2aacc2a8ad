"""A drawing opening's flow of coal and gangue on the tail beam: lumps, sensors and the truth.

:class:`FlowRun` joins the pieces for one support: a :class:`~tail_beam_sim.physics.lumps.
LumpSource` (the lumps a window lets fall, from the ``flow`` section), a
:class:`~tail_beam_sim.physics.superpose.FlowSimulator` (their contacts superposed on the
linear support; sensors exactly as the stream simulator produces them) and a
:class:`ShareTally` (the true gangue share per interval). ``sim_node`` drives one live
(``scenario.source: flow``, ``window_cmd``); :func:`simulate_flow` runs one offline into a
:class:`FlowRecord`, which :func:`tail_beam_sim.bags.flow_bag.write_flow_bag` writes as a bag.

The true share of an interval counts the lumps whose contact stamp falls in it
([start, end) of simulation time; intervals k * ``flow.interval_s``): by mass (gangue mass /
mass) and by count (gangue lumps / lumps); None when no lump struck in it. An interval is
reported once the simulation has passed its end, if it holds a lump or overlaps a time the
flow reaches the beam (from a window's opening to its closing plus ``onset_delay_s``).
"""

from __future__ import annotations

import json
import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tail_beam_sim.config import section
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.lumps import FlowParams, Lump, LumpSource, WindowStateError
from tail_beam_sim.physics.sensors import (
    ImpactPoint,
    ImuStream,
    PressureStream,
    Rebound,
    VibrationBlocks,
)
from tail_beam_sim.physics.share_curve import ShareCurve
from tail_beam_sim.physics.solvers import SolverError
from tail_beam_sim.physics.stream import CHANNELS, Chunk
from tail_beam_sim.physics.superpose import FlowSimulator

__all__ = [
    "FlowChunk",
    "FlowParams",
    "FlowRecord",
    "FlowRun",
    "Lump",
    "ShareCurve",
    "ShareInterval",
    "ShareTally",
    "WindowStateError",
    "parse_window_command",
    "simulate_flow",
]

WINDOW_ACTIONS = ("open", "close")


@dataclass(frozen=True)
class ShareInterval:
    """The true gangue share of the lumps that struck in [start_stamp_s, end_stamp_s)."""

    start_stamp_s: float
    end_stamp_s: float
    lumps: int
    gangue_lumps: int
    mass_kg: float
    gangue_mass_kg: float
    drawn_mass_kg: float  # mass of every lump struck before end_stamp_s since the first opening

    @property
    def share_by_mass(self) -> float | None:
        return self.gangue_mass_kg / self.mass_kg if self.lumps else None

    @property
    def share_by_count(self) -> float | None:
        return self.gangue_lumps / self.lumps if self.lumps else None

    def to_json(self) -> dict[str, Any]:
        """The ``gangue_share_truth`` JSON object (docs/interface.md)."""
        return {
            "start_stamp_s": self.start_stamp_s,
            "end_stamp_s": self.end_stamp_s,
            "share_by_mass": self.share_by_mass,
            "share_by_count": self.share_by_count,
            "lumps": self.lumps,
            "gangue_lumps": self.gangue_lumps,
            "mass_kg": self.mass_kg,
            "gangue_mass_kg": self.gangue_mass_kg,
            "drawn_mass_kg": self.drawn_mass_kg,
        }


class ShareTally:
    """Counts the lumps per interval of ``interval_s`` (k * interval_s .. (k+1) * interval_s)
    and reports each interval once the clock has passed its end."""

    def __init__(
        self, interval_s: float, onset_delay_s: float, windows: list[tuple[float, float]]
    ) -> None:
        """``windows``: the (opened, closed) stamps of the window, s (read as they change)."""
        self.interval_s = interval_s
        self.onset_delay_s = onset_delay_s
        self._windows = windows
        self._bins: dict[int, list[float]] = {}  # k -> [lumps, gangue lumps, mass, gangue mass]
        self._next_k: int | None = None  # the first interval not yet reported
        self._drawn_kg = 0.0

    def _index(self, stamp_s: float) -> int:
        return math.floor(stamp_s / self.interval_s + 1e-9)

    def _flowing(self, start_s: float, end_s: float) -> bool:
        """Whether lumps may reach the beam in [start_s, end_s): a window was open from
        ``onset_delay_s`` before it to its end."""
        delay = self.onset_delay_s
        return any(a + delay < end_s and b + delay > start_s for a, b in self._windows)

    def add(self, stamp_s: float, mass_kg: float, is_gangue: bool) -> None:
        """One lump struck at ``stamp_s``."""
        k = self._index(stamp_s)
        counts = self._bins.setdefault(k, [0, 0, 0.0, 0.0])
        counts[0] += 1
        counts[2] += mass_kg
        if is_gangue:
            counts[1] += 1
            counts[3] += mass_kg
        if self._next_k is None or k < self._next_k:
            self._next_k = k

    def report(self, until_s: float) -> list[ShareInterval]:
        """Every interval ending at or before ``until_s`` not reported yet (those with no lump
        and no flow left out)."""
        if self._next_k is None and self._windows:
            self._next_k = self._index(self._windows[0][0])
        if self._next_k is None:
            return []
        out = []
        last = self._index(until_s)  # intervals k < last have ended
        for k in range(self._next_k, last):
            start, end = k * self.interval_s, (k + 1) * self.interval_s
            lumps, gangue, mass, gangue_mass = self._bins.pop(k, [0, 0, 0.0, 0.0])
            self._drawn_kg += mass
            if lumps or self._flowing(start, end):
                out.append(
                    ShareInterval(start, end, lumps, gangue, mass, gangue_mass, self._drawn_kg)
                )
        self._next_k = max(self._next_k, last)
        return out


@dataclass
class FlowChunk:
    """What one step of a flow produced: the stream's chunk (sensors, rebounds, truths) and the
    share intervals that ended in it."""

    chunk: Chunk
    shares: list[ShareInterval]
    lumps: list[Lump]  # lumps submitted in this step (contact stamps ahead of the clock)


class FlowRun:
    """One support under one drawing opening: window commands in, sensor chunks out."""

    def __init__(
        self,
        params: Mapping[str, Any],
        seed: int | None = None,
        share: ShareCurve | None = None,
        id_prefix: str = "flow",
        simulator: FlowSimulator | None = None,
    ) -> None:
        """``params``: merged parameters with the physics sections, ``stream`` and ``flow``;
        ``seed`` replaces ``flow.seed``, ``share`` the config's share curve."""
        self.sim = simulator or FlowSimulator.from_params(params, id_prefix=id_prefix)
        self.flow = FlowParams.from_params(
            section(params, "flow"), self.sim.materials, self.sim.support, share
        )
        if self.sim.solver == "hybrid":
            self.sim.solver_options = {"contact": self.flow.contact}
        self.source = LumpSource(self.flow, self.sim.materials, seed, id_prefix)
        self.tally = ShareTally(self.flow.interval_s, self.flow.onset_delay_s, self.source.windows)
        self.lumps_submitted = 0
        self.skipped: list[tuple[Lump, str]] = []  # lumps the simulator refused, with why

    @property
    def time_s(self) -> float:
        return self.sim.time_s

    @property
    def is_open(self) -> bool:
        return self.source.is_open

    def command(self, action: str, stamp_s: float | None = None) -> float:
        """Open or close the window at ``stamp_s`` (default: the simulation time reached);
        returns the stamp. WindowStateError for a window already in that state, InputError for
        an action that is neither."""
        if action not in WINDOW_ACTIONS:
            raise InputError("window_cmd.action", action, "must be open or close")
        stamp = self.sim.time_s if stamp_s is None else float(stamp_s)
        return self.source.open(stamp) if action == "open" else self.source.close(stamp)

    def feed(self, until_s: float) -> list[Lump]:
        """Submit every lump striking at or before ``until_s`` to the simulator."""
        lumps = []
        for lump in self.source.take_until(until_s):
            try:
                scheduled = self.sim.submit(lump.command(), lump.contact_stamp_s)
            except (InputError, SolverError) as exc:  # an impact_id taken, a failed solve
                self.skipped.append((lump, str(exc)))
                continue
            scheduled.truth["drawn_mass_kg"] = lump.drawn_mass_kg
            self.tally.add(scheduled.contact_stamp_s, lump.mass_kg, lump.is_gangue)
            lumps.append(lump)
        self.lumps_submitted += len(lumps)
        return lumps

    def advance(self, until_s: float, lead_s: float | None = None) -> FlowChunk:
        """Feed the lumps up to ``until_s`` plus ``lead_s`` (default: the stream's command lead),
        then produce everything in (time_s, until_s]."""
        lead = self.sim.params.command_lead_s if lead_s is None else lead_s
        lumps = self.feed(until_s + lead)
        chunk = self.sim.advance(until_s)
        return FlowChunk(chunk, self.tally.report(chunk.end_s), lumps)


@dataclass
class FlowRecord:
    """An offline flow run: the sensor streams as the stream simulator gives them (absolute
    simulation time), the rebounds (with the camera's impact points when it reports them), each
    lump's ``impact_truth``, the share intervals and the window commands."""

    pressure: PressureStream
    imu: ImuStream
    vibration: VibrationBlocks
    rebounds: list[tuple[str, Rebound]]  # (impact_id, rebound), in stamp order
    truths: list[tuple[float, dict[str, Any]]]  # (publish stamp s, impact_truth), stamp order
    shares: list[ShareInterval]
    lumps: list[Lump]
    windows: list[tuple[float, str]]  # (stamp s, "open" | "close")
    duration_s: float
    params: dict[str, Any] = field(default_factory=dict)  # the flow parameters used
    # (impact_id, point) in stamp order, each stamped as its rebound
    # (sensors.camera_reports_impact_point; empty otherwise)
    points: list[tuple[str, ImpactPoint]] = field(default_factory=list)

    @property
    def lumps_per_s(self) -> float:
        return len(self.lumps) / self.duration_s if self.duration_s > 0 else 0.0


def simulate_flow(
    params: Mapping[str, Any],
    duration_s: float,
    seed: int | None = None,
    share: ShareCurve | None = None,
    windows: Sequence[tuple[float, float]] | None = None,
    step_s: float = 0.05,
    channels: Collection[str] = CHANNELS,
) -> FlowRecord:
    """Run a flow offline for ``duration_s`` of simulation time, sampling the sensors
    ``channels`` (:data:`tail_beam_sim.physics.stream.CHANNELS`; the others left out).

    ``windows``: (open s, close s) pairs (close may be inf); by default one window from
    ``flow.open_at_s`` (0 when -1) lasting ``flow.duration_s`` (0: to the end). ``seed``
    replaces ``flow.seed`` (the sensors' noise follows ``sensors.seed``). Deterministic: the
    same arguments give the same record, whatever ``step_s``.
    """
    if not (isinstance(duration_s, (int, float)) and 0.0 < duration_s <= 1e5):
        raise InputError("duration_s", duration_s, "must be in (0, 1e5] s")
    simulator = FlowSimulator.from_params(params, id_prefix="flow", channels=channels)
    run = FlowRun(params, seed=seed, share=share, simulator=simulator)
    if windows is None:
        opening = max(run.flow.open_at_s, 0.0)
        closing = opening + run.flow.duration_s if run.flow.duration_s > 0 else math.inf
        windows = [(opening, closing)]
    done_events: list[tuple[float, str]] = []
    for k, (opening, closing) in enumerate(windows):
        after = 0.0 if not done_events else done_events[-1][0]
        after = math.inf if done_events and done_events[-1][1] == "open" else after
        if not (math.isfinite(opening) and opening >= after and closing > opening):
            raise InputError(
                f"windows[{k}]",
                (opening, closing),
                f"must be (open s, close s) with {after:g} <= open < close: windows in order, "
                "not overlapping",
            )
        done_events.append((run.command("open", opening), "open"))
        if math.isfinite(closing):
            done_events.append((run.command("close", closing), "close"))
    pressure, imu, vibration, rebounds, truths, shares, lumps = [], [], [], [], [], [], []
    points: list[tuple[str, ImpactPoint]] = []
    t = 0.0
    while t < duration_s:
        step_end = min(t + step_s, duration_s)
        part = run.advance(step_end)
        _collect(part, pressure, imu, vibration, rebounds, truths, shares, lumps, points)
        t = step_end
    spec = run.sim.sensors
    return FlowRecord(
        pressure=PressureStream(
            np.concatenate([p.stamp_s for p in pressure]),
            np.concatenate([p.pressure_pa for p in pressure]),
            pressure[0].variance_pa2,
        ),
        imu=ImuStream(
            np.concatenate([i.stamp_s for i in imu]),
            np.concatenate([i.angular_velocity_radps for i in imu]),
            np.concatenate([i.linear_acceleration_mps2 for i in imu]),
            imu[0].gyro_variance,
            imu[0].accel_variance,
        ),
        vibration=VibrationBlocks.concatenate(vibration)
        if any(v.count for v in vibration)
        else VibrationBlocks.empty(1.0 / spec.vibration_rate_hz, spec.vibration_range_mps2),
        rebounds=rebounds,
        truths=truths,
        shares=shares,
        lumps=lumps,
        windows=[e for e in done_events if e[0] <= duration_s],
        duration_s=float(duration_s),
        params={**dict(section(params, "flow")), **({"seed": seed} if seed is not None else {})},
        points=points,
    )


def _collect(
    part: FlowChunk,
    pressure: list,
    imu: list,
    vibration: list,
    rebounds: list,
    truths: list,
    shares: list,
    lumps: list,
    points: list,
) -> None:
    chunk = part.chunk
    pressure.append(chunk.pressure)
    imu.append(chunk.imu)
    vibration.append(chunk.vibration)
    rebounds.extend(chunk.rebounds)
    truths.extend(chunk.truths)
    shares.extend(part.shares)
    lumps.extend(part.lumps)
    points.extend(chunk.points)


MAX_WINDOW_CMD_CHARS = 1024  # a window command is about 20 characters


def parse_window_command(text: str) -> str:
    """The action of one ``window_cmd`` text: a JSON object ``{"action": "open" | "close"}``.
    InputError naming ``window_cmd`` (not a JSON object, too long, other fields) or
    ``window_cmd.action``."""
    if len(text) > MAX_WINDOW_CMD_CHARS:
        raise InputError(
            "window_cmd", text, f"must be at most {MAX_WINDOW_CMD_CHARS} characters of JSON"
        )
    try:
        value = json.loads(text)
    except (json.JSONDecodeError, RecursionError, ValueError) as exc:
        reason = f"{exc.msg} at char {exc.pos}" if isinstance(exc, json.JSONDecodeError) else ""
        raise InputError(
            "window_cmd", text, f'must be JSON {{"action": "open" | "close"}} ({reason or exc})'
        ) from None
    if not isinstance(value, dict):
        raise InputError("window_cmd", text, 'must be a JSON object {"action": "open" | "close"}')
    extra = sorted(set(value) - {"action"})
    if extra:
        raise InputError("window_cmd", text, f"unknown field(s) {', '.join(extra)}: only action")
    action = value.get("action")
    if action not in WINDOW_ACTIONS:
        raise InputError("window_cmd.action", action, "must be open or close")
    return action
