"""A face of drawing openings over one cut's top coal: the windows in their sequence, what each
draws over time, and the recovery and gangue content of a round.

The drawing model is :mod:`tail_beam_sim.physics.drawing` (a stochastic medium, void
diffusion); the parameters are the ``face`` section (``config/face.yaml``). A window draws
cell by cell at ``mass_rate_kgps`` from a column of its opening; whoever drives it (a closing
rule, :func:`close_at_true_share`) is asked after each cell and, once it says close, the window
still draws for ``close_delay_s`` while it closes.

Each window's record gives the flow at its opening as the share-versus-drawn-mass curve
(:meth:`WindowRecord.share_curve`) and mass rate (``mass_rate_kgps``) that the one-opening
flow simulation takes (its ``share_drawn_mass_kg``, ``share_gangue`` and ``mass_rate_kgps``).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tail_beam_sim.config import deep_merge, default_config_dir, read_parameter_file
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.drawing import COAL, GANGUE, VoidGrid
from tail_beam_sim.spec import FACE

__all__ = [
    "DrawnCell",
    "Face",
    "FaceParams",
    "FaceResult",
    "ShareMeter",
    "Visit",
    "WindowRecord",
    "close_at_true_share",
    "draw_window",
    "load_face_parameters",
    "run_face",
    "schedule",
]


@dataclass(frozen=True)
class FaceParams:
    """The ``face`` section, validated (units in the names; docs/parameters.md)."""

    supports: int
    support_width_m: float
    cut_depth_m: float
    top_coal_height_m: float
    cell_size_m: float
    lateral_step_probability: float
    margin_supports: int
    coal_density_kgpm3: float
    gangue_density_kgpm3: float
    mass_rate_kgps: float
    close_delay_s: float
    max_window_s: float
    share_window_kg: float
    sequence: str
    group_size: int
    rounds: int
    round_draw_fraction: float
    seed: int

    @classmethod
    def from_params(cls, params: Mapping[str, Any], **overrides: Any) -> FaceParams:
        """The ``face`` section of merged parameters, with ``overrides`` (a command line's)
        checked as the config's values are; InputError naming the field."""
        body = dict(params.get("face") or {}) if isinstance(params, Mapping) else {}
        body.update({k: v for k, v in overrides.items() if v is not None})
        return cls(**FACE.check(body))

    def with_changes(self, **changes: Any) -> FaceParams:
        """A copy with ``changes``, checked again."""
        values = {name: getattr(self, name) for name in self.__dataclass_fields__}
        values.update(changes)
        return FaceParams(**FACE.check(values))


def load_face_parameters(extra_files: tuple[str, ...] = ()) -> dict[str, Any]:
    """config/face.yaml merged with ``extra_files`` (later files win)."""
    params = read_parameter_file(Path(default_config_dir()) / "face.yaml")
    for path in extra_files:
        deep_merge(params, read_parameter_file(path))
    return params


@dataclass(frozen=True)
class DrawnCell:
    """One cell out of an opening: its material (:data:`COAL`, :data:`GANGUE`), mass (kg),
    and the simulation time it flowed over (s)."""

    material: int
    mass_kg: float
    start_s: float
    end_s: float


@dataclass
class WindowRecord:
    """What one visit of a window drew: its opening, round, the cells in order, when the
    driver decided to close (s, None if it never did) and whether ``max_window_s`` ended it."""

    opening: int
    round: int
    opened_s: float
    cells: list[DrawnCell] = field(default_factory=list)
    decided_s: float | None = None
    closed_s: float = 0.0
    timed_out: bool = False

    def mass_kg(self, material: int | None = None) -> float:
        """Mass drawn, of ``material`` only when given (kg)."""
        return sum(c.mass_kg for c in self.cells if material is None or c.material == material)

    def share_curve(self, window_kg: float) -> tuple[np.ndarray, np.ndarray]:
        """The flow's gangue share by mass against the mass drawn since the window opened:
        (drawn mass at each cell's end, kg, strictly increasing from 0; the share over the last
        ``window_kg`` drawn at that point), the curve the opening's flow takes."""
        meter = ShareMeter(window_kg)
        mass = [0.0]
        share = [0.0]
        total = 0.0
        for cell in self.cells:
            total += cell.mass_kg
            mass.append(total)
            share.append(meter.add(cell.material, cell.mass_kg))
        if len(share) > 1:
            share[0] = share[1] if self.cells[0].material == GANGUE else 0.0
        return np.array(mass), np.array(share)

    def flow_parameters(self, window_kg: float, mass_rate_kgps: float) -> dict[str, Any]:
        """The window's flow as the one-opening flow simulation's parameters take it: its
        share curve (``share_drawn_mass_kg``, ``share_gangue``) and mass rate
        (``rate_kind: mass``, ``mass_rate_kgps``), plain lists and numbers."""
        mass, share = self.share_curve(window_kg)
        return {
            "rate_kind": "mass",
            "mass_rate_kgps": float(mass_rate_kgps),
            "share_drawn_mass_kg": mass.tolist(),
            "share_gangue": share.tolist(),
        }


class ShareMeter:
    """The instantaneous gangue share by mass: the share among the last ``window_kg`` drawn
    (the oldest cell counted in part)."""

    def __init__(self, window_kg: float) -> None:
        if not window_kg > 0.0:
            raise InputError("face.share_window_kg", window_kg, "must be > 0 kg")
        self.window_kg = window_kg
        self._cells: deque[tuple[int, float]] = deque()
        self._mass_kg = 0.0

    def add(self, material: int, mass_kg: float) -> float:
        """Count one drawn cell; the share after it."""
        self._cells.append((material, mass_kg))
        self._mass_kg += mass_kg
        while self._cells and self._mass_kg - self._cells[0][1] >= self.window_kg:
            self._mass_kg -= self._cells.popleft()[1]
        total = gangue = 0.0
        excess = max(0.0, self._mass_kg - self.window_kg)
        for k, (kind, mass) in enumerate(self._cells):
            counted = mass - excess if k == 0 else mass
            total += counted
            gangue += counted if kind == GANGUE else 0.0
        return gangue / total if total > 0.0 else 0.0


@dataclass(frozen=True)
class Visit:
    """One opening of a window in the sequence: which opening (0-based), which round (0-based),
    and the most it may draw (kg; None: until the driver closes it)."""

    opening: int
    round: int
    limit_kg: float | None


class Face:
    """The grid of cells over the face's openings, and what each opening has drawn."""

    def __init__(self, params: FaceParams) -> None:
        self.params = params
        p = params
        self.columns_per_support = max(1, round(p.support_width_m / p.cell_size_m))
        self.coal_rows = max(1, round(p.top_coal_height_m / p.cell_size_m))
        cell_width_m = p.support_width_m / self.columns_per_support
        cell_height_m = p.top_coal_height_m / self.coal_rows
        self.cell_volume_m3 = cell_width_m * cell_height_m * p.cut_depth_m
        self.margin_columns = p.margin_supports * self.columns_per_support
        columns = p.supports * self.columns_per_support + 2 * self.margin_columns
        self.grid = VoidGrid(columns, self.coal_rows, 1, p.lateral_step_probability)
        self.mass_kg = {
            COAL: self.cell_volume_m3 * p.coal_density_kgpm3,
            GANGUE: self.cell_volume_m3 * p.gangue_density_kgpm3,
        }
        self.rng = np.random.default_rng(p.seed)
        self.drawn_cells = {COAL: 0, GANGUE: 0}
        self.initial_coal_cells = self.grid.coal_cells()
        self.initial_gangue_cells = columns * self.grid.gangue_rows
        self.clock_s = 0.0

    @property
    def top_coal_there_kg(self) -> float:
        """Top coal over the drawn supports' width before drawing (kg): recovery's base."""
        p = self.params
        return p.supports * self.columns_per_support * self.coal_rows * self.mass_kg[COAL]

    @property
    def support_coal_kg(self) -> float:
        """Top coal over one support before drawing (kg)."""
        return self.columns_per_support * self.coal_rows * self.mass_kg[COAL]

    def draw(self, opening: int) -> DrawnCell:
        """Draw one cell at ``opening`` (0-based) from a column of it chosen at random; the
        face's clock moves on by the cell's mass over the mass rate."""
        if not 0 <= opening < self.params.supports:
            raise InputError("opening", opening, f"must be in [0, {self.params.supports - 1}]")
        k = self.columns_per_support
        column = self.margin_columns + opening * k + int(self.rng.integers(k))
        material = self.grid.draw(column, self.rng.random(self.grid.rows))
        self.drawn_cells[material] += 1
        mass = self.mass_kg[material]
        start = self.clock_s
        self.clock_s += mass / self.params.mass_rate_kgps
        return DrawnCell(material, mass, start, self.clock_s)

    def drawn_kg(self, material: int) -> float:
        return self.drawn_cells[material] * self.mass_kg[material]

    def recovery(self) -> float:
        """Top coal drawn over the top coal that was over the drawn supports."""
        return self.drawn_kg(COAL) / self.top_coal_there_kg

    def gangue_content(self) -> float:
        """Gangue mass over the mass drawn (0 when nothing was drawn)."""
        total = self.drawn_kg(COAL) + self.drawn_kg(GANGUE)
        return self.drawn_kg(GANGUE) / total if total > 0.0 else 0.0


def schedule(params: FaceParams) -> Iterator[Visit]:
    """The windows in drawing order: groups of ``group_size`` supports one after another;
    within a group single_round (each support once, in order), interval (every other support,
    then the rest) or multi_round (``rounds`` passes in order, each early pass drawing
    ``round_draw_fraction`` of a support's top coal, the last closing on the driver)."""
    p = params
    support_kg = p.support_width_m * p.top_coal_height_m * p.cut_depth_m * p.coal_density_kgpm3
    for first in range(0, p.supports, p.group_size):
        group = list(range(first, min(first + p.group_size, p.supports)))
        if p.sequence == "single_round":
            for opening in group:
                yield Visit(opening, 0, None)
        elif p.sequence == "interval":
            for opening in group[0::2] + group[1::2]:
                yield Visit(opening, 0, None)
        else:
            for r in range(p.rounds):
                last = r == p.rounds - 1
                for opening in group:
                    yield Visit(opening, r, None if last else p.round_draw_fraction * support_kg)


Decide = Callable[[DrawnCell], bool]


def draw_window(face: Face, visit: Visit, decide: Decide) -> WindowRecord:
    """Draw one visit: cell after cell until ``decide`` (asked after each cell) says close and
    ``close_delay_s`` has passed, or the visit's mass limit is reached (an early round:
    ``decide`` may still close it sooner), or ``max_window_s`` has passed."""
    p = face.params
    record = WindowRecord(visit.opening, visit.round, face.clock_s)
    close_at = math.inf
    drawn = 0.0
    while face.clock_s < close_at:
        if face.clock_s - record.opened_s >= p.max_window_s:
            record.timed_out = True
            break
        if visit.limit_kg is not None and drawn >= visit.limit_kg:
            break
        cell = face.draw(visit.opening)
        record.cells.append(cell)
        drawn += cell.mass_kg
        if record.decided_s is None and decide(cell):
            record.decided_s = cell.end_s
            close_at = cell.end_s + p.close_delay_s
    record.closed_s = face.clock_s
    return record


def close_at_true_share(level: float, window_kg: float) -> Callable[[], Decide]:
    """A driver factory: close when the true instantaneous gangue share (over ``window_kg``)
    first reaches ``level``."""
    if not 0.0 < level <= 1.0:
        raise InputError("level", level, "must be in (0, 1]")

    def make() -> Decide:
        meter = ShareMeter(window_kg)
        return lambda cell: meter.add(cell.material, cell.mass_kg) >= level

    return make


@dataclass
class FaceResult:
    """A round over the face: its windows, top-coal recovery and gangue content (fractions),
    the simulated drawing time (s) and the mass ledger (kg)."""

    windows: list[WindowRecord]
    recovery: float
    gangue_content: float
    drawing_s: float
    coal_there_kg: float
    coal_drawn_kg: float
    gangue_drawn_kg: float


def run_face(params: FaceParams, driver: Callable[[], Decide]) -> FaceResult:
    """Draw the face once through its schedule, each window driven by a fresh ``driver()``."""
    face = Face(params)
    windows = [draw_window(face, visit, driver()) for visit in schedule(params)]
    return FaceResult(
        windows,
        face.recovery(),
        face.gangue_content(),
        face.clock_s,
        face.top_coal_there_kg,
        face.drawn_kg(COAL),
        face.drawn_kg(GANGUE),
    )
