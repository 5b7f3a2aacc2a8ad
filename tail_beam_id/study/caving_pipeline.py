"""The caving study's ``identified`` sources: each window's drawn flow through the physics core,
the sensors of a layout and the identifier, its labels and ``gangue_share`` fed to the rule.

For every window the face opens (:mod:`tail_beam_sim.physics.face`), the opening's support gets
a fresh :class:`~tail_beam_sim.physics.superpose.FlowSimulator` (the flow scene's physics:
contacts superposed on the linear support, the stream simulator's sensors) and a fresh
:class:`~tail_beam_id.stream.share_reader.SharingIdentifier` (the identifier with its gangue
share read-out, uncalibrated: the nominal support, as id_node and ``tail-beam identify
--no-calibrate`` run). Each cell the drawing model draws becomes lumps of the cell's material
striking the tail beam within the cell's time:

- ``struck`` (``caving.pipeline.lumps``): the lumps that strike the beam,
  ``caving.labels.impacts_per_tonne`` per tonne drawn (Poisson): the same counts and stamps as
  the ``truth`` source's lumps on the same face (one generator, drawn alike), so the sources
  differ only by what the sensors and the identifier make of them;
- ``drawn``: the cell's whole mass as lumps of the ``flow`` section's size distribution (the
  face's mass rate, hundreds of lumps a second).

A lump's size, drop height, strike position and restitution follow the ``flow`` section
(truncated log-normal radius, uniform ranges), its gangue material uniform among
``flow.gangue_materials``. After each cell the simulator is advanced to the cell's end, the
sensors' samples of the layout go to the identifier, and its labels (known their
``data_latency_ms`` after their impact) and share estimates (known at their interval's end) are
fed to the rule in the order they become known, as the ``truth`` and ``stand-in`` sources are.

Layouts (:data:`LAYOUTS`): ``shipped`` (jack pressure, IMU, the tail-beam accelerometer, the
rebound camera), ``imu`` (the same without the accelerometer), ``pressure`` (jack pressure and
the rebound camera: no sensor of the beam's vibration), ``impact_point`` (shipped, the camera
also reporting where each lump struck). A layout's simulator samples only the sensors the layout
has (:data:`LAYOUT_CHANNELS`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from tail_beam_id.caving.events import ShareEstimate
from tail_beam_id.caving.feed import label_event, share_event
from tail_beam_id.caving.rule_feed import RuleFeed
from tail_beam_id.caving.rules import Rule
from tail_beam_id.methods import build_method
from tail_beam_id.stream.identifier import IdentifierConfig
from tail_beam_id.stream.share import load_score_model
from tail_beam_id.stream.share_reader import SharingIdentifier
from tail_beam_sim.config import default_config_dir, load_parameters
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.drawing import GANGUE
from tail_beam_sim.physics.face import DrawnCell, ShareMeter
from tail_beam_sim.physics.lumps import FlowParams, lump_radius_m
from tail_beam_sim.physics.materials import material_table, sphere_mass_kg
from tail_beam_sim.physics.solvers import SolverError
from tail_beam_sim.physics.stream import CHANNELS, WITHOUT_ACCELEROMETER, Chunk
from tail_beam_sim.physics.superpose import FlowSimulator
from tail_beam_sim.topics import FRAME_PLATE

__all__ = [
    "LAYOUTS",
    "LAYOUT_CHANNELS",
    "LUMP_MODES",
    "SOURCE_PREFIX",
    "IdentifiedWindowFeed",
    "Pipeline",
    "layout_of",
    "pipeline_parameters",
]

LAYOUTS = ("shipped", "imu", "pressure", "impact_point")
# The sampled sensors of each layout (the rebound camera besides): its simulator leaves the
# others out, and its identifier gets these.
LAYOUT_CHANNELS: dict[str, tuple[str, ...]] = {
    "shipped": CHANNELS,
    "imu": WITHOUT_ACCELEROMETER,
    "pressure": ("pressure",),
    "impact_point": CHANNELS,
}
LUMP_MODES = ("struck", "drawn")
SOURCE_PREFIX = "identified:"  # a source name: identified:<layout>
LEAD_S = 0.25  # quiet beam before a window's first lump (the detectors learn the noise), s


def layout_of(source: str) -> str | None:
    """The layout of an ``identified:<layout>`` source (None for another source); InputError
    naming the source for a layout that is none of :data:`LAYOUTS`."""
    if not source.startswith(SOURCE_PREFIX):
        return None
    layout = source[len(SOURCE_PREFIX) :]
    if layout not in LAYOUTS:
        raise InputError(
            "source", source, f"layout must be one of {', '.join(LAYOUTS)} (identified:<layout>)"
        )
    return layout


def pipeline_parameters(extra_files: tuple[str, ...] = ()) -> dict[str, Any]:
    """The physics and identification parameters a pipeline runs on: the shipped defaults,
    config/sim_node.yaml (``stream``) and config/flow.yaml (``flow``), then ``extra_files``."""
    config = default_config_dir()
    return load_parameters([config / "sim_node.yaml", config / "flow.yaml", *extra_files])


class Pipeline:
    """What every window of one layout shares: the merged parameters (the layout's sensors
    set), the checked ``flow`` section, the identification method built once, the share model."""

    def __init__(
        self,
        params: Mapping[str, Any],
        layout: str,
        lumps: str = "struck",
        impacts_per_tonne: float = 50.0,
    ) -> None:
        if layout not in LAYOUTS:
            raise InputError("layout", layout, f"must be one of {', '.join(LAYOUTS)}")
        if lumps not in LUMP_MODES:
            raise InputError("caving.pipeline.lumps", lumps, f"must be one of {LUMP_MODES}")
        if not (math.isfinite(impacts_per_tonne) and impacts_per_tonne > 0.0):
            raise InputError("caving.labels.impacts_per_tonne", impacts_per_tonne, "must be > 0")
        self.layout, self.lumps, self.impacts_per_tonne = layout, lumps, impacts_per_tonne
        merged = {k: (dict(v) if isinstance(v, Mapping) else v) for k, v in params.items()}
        for name in ("stream", "flow", "sensors", "identification"):
            if not isinstance(merged.get(name), Mapping):
                raise InputError(name, None, "missing parameter section in the config files")
        merged["sensors"]["camera_reports_impact_point"] = layout == "impact_point"
        merged["stream"].update(
            {"min_impact_gap_s": 0.0, "command_lead_s": 0.001, "max_queued_impacts": 1_000_000}
        )
        self.params = merged
        probe = FlowSimulator.from_params(merged)
        self.flow = FlowParams.from_params(merged["flow"], probe.materials, probe.support)
        table = material_table(merged)
        self.coal = table[self.flow.coal_material]
        self.gangue = [table[name] for name in self.flow.gangue_materials]
        section = dict(merged["identification"])
        self.method = build_method(IdentifierConfig.from_params(section).method, merged, None)
        self.share_model = load_score_model()

    def command(self, gangue: bool, u: np.ndarray, impact_id: str) -> tuple[dict[str, Any], float]:
        """One lump's ``impact_cmd`` object from five uniform draws, and its mass (kg)."""
        f = self.flow
        if gangue:
            material = self.gangue[min(int(u[0] * len(self.gangue)), len(self.gangue) - 1)]
        else:
            material = self.coal
        radius = lump_radius_m(self.flow, float(u[1]))
        low, high = material.restitution_range
        (h0, h1), (x0, x1) = f.drop_height_m, f.position_m
        command = {
            "material": material.name,
            "radius_m": radius,
            "drop_height_m": float(h0 + u[2] * (h1 - h0)),
            "position_m": float(x0 + u[3] * (x1 - x0)),
            "restitution": float(low + u[4] * (high - low)),
            "impact_id": impact_id,
        }
        return command, float(sphere_mass_kg(material.density_kgpm3, radius))

    def simulator(self, sensor_seed: int) -> FlowSimulator:
        """A fresh support for one window: the flow simulator, its sensors' noise seeded."""
        params = dict(self.params)
        params["sensors"] = {**params["sensors"], "seed": int(sensor_seed) % (2**31)}
        sim = FlowSimulator.from_params(params, channels=LAYOUT_CHANNELS[self.layout])
        if sim.solver == "hybrid":
            sim.solver_options = {"contact": self.flow.contact}
        return sim

    def identifier(self) -> SharingIdentifier:
        """A fresh identifier for one window, uncalibrated (id_node's), the method reused."""
        return SharingIdentifier(
            None,
            params=self.params["identification"],
            model_params=self.params,
            prebuilt=self.method,
            share_model=self.share_model,
        )


@dataclass
class WindowTally:
    """What one window's pipeline saw: lumps simulated, labels and share estimates given."""

    lumps: int = 0
    gangue_lumps: int = 0
    labels: int = 0
    shares: int = 0
    skipped: int = 0  # lumps whose contact the solver failed on (as FlowRun skips them)


class IdentifiedWindowFeed(RuleFeed):
    """A window's controller on the identified source: asked after each drawn cell, it strikes
    the cell's lumps on the support's beam, advances the sensors to the cell's end, hands their
    samples to the identifier and feeds the rule every label, share estimate, true share and
    tick known by then; it says whether the rule decided."""

    def __init__(
        self,
        rule: Rule,
        pipeline: Pipeline,
        rngs: tuple[np.random.Generator, np.random.Generator],
        window_kg: float,
        opened_s: float,
        sensor_seed: int,
        window: int,
    ) -> None:
        self.pipeline = pipeline
        self.lumps_rng, self.props_rng = rngs  # the lumps' count and stamps; their properties
        self.meter = ShareMeter(window_kg)
        self.opened_s = opened_s
        self.offset_s = opened_s - LEAD_S  # face stamp = simulation stamp + offset
        self.sim = pipeline.simulator(sensor_seed)
        self.identifier = pipeline.identifier()
        self.window = window
        self.tally = WindowTally()
        super().__init__(rule, opened_s)
        self._deliver(self.sim.advance(LEAD_S - 1e-9))

    def _strike(self, cell: DrawnCell) -> None:
        """Submit the lumps of ``cell`` to the support's simulator: ``struck``, the lumps that
        strike the beam (Poisson count, uniform stamps over the cell's time); ``drawn``, lumps
        until the cell's mass is used up, spread evenly over its time."""
        p = self.pipeline
        gangue = cell.material == GANGUE
        first = self.tally.lumps + self.tally.skipped
        commands: list[dict[str, Any]] = []
        if p.lumps == "struck":
            n = self.lumps_rng.poisson(p.impacts_per_tonne * cell.mass_kg / 1000.0)
            stamps = np.sort(self.lumps_rng.uniform(cell.start_s, cell.end_s, n)).tolist()
            for k in range(n):
                lump_id = f"w{self.window}-{first + k + 1:06d}"
                commands.append(p.command(gangue, self.props_rng.random(5), lump_id)[0])
        else:
            left = cell.mass_kg
            while left > 0.0:
                lump_id = f"w{self.window}-{first + len(commands) + 1:06d}"
                command, mass_kg = p.command(gangue, self.props_rng.random(5), lump_id)
                commands.append(command)
                left -= mass_kg
            span = (cell.end_s - cell.start_s) / len(commands)
            stamps = [cell.start_s + span * (k + 0.5) for k in range(len(commands))]
        for stamp, command in zip(stamps, commands):
            try:
                self.sim.submit(command, contact_stamp_s=stamp - self.offset_s)
            except SolverError:  # a contact the solver could not take: counted, left out
                self.tally.skipped += 1
                continue
            self.tally.lumps += 1
            self.tally.gangue_lumps += gangue

    def _deliver(self, chunk: Chunk) -> None:
        """The chunk's samples of the layout's sensors to the identifier; labels and shares out
        as events on the face's clock."""
        ident = self.identifier  # the simulator samples the layout's channels alone
        if chunk.pressure.stamp_s.size:
            ident.add_pressure(chunk.pressure.stamp_s, chunk.pressure.pressure_pa)
        if chunk.imu.stamp_s.size:
            ident.add_imu(
                chunk.imu.stamp_s,
                chunk.imu.angular_velocity_radps,
                chunk.imu.linear_acceleration_mps2,
            )
        if chunk.vibration.count:
            ident.add_vibration(
                chunk.vibration.sample_stamps_s(), chunk.vibration.accel_mps2.astype(float)
            )
        for _, rebound in chunk.rebounds:
            ident.add_rebound(rebound.stamp_s, rebound.velocity_mps)
        for _, point in chunk.points:
            ident.add_impact_point(point.stamp_s, point.point_m, FRAME_PLATE)
        offset = self.offset_s
        for label in ident.poll():
            event = label_event(label)
            if event is None:
                continue
            self.tally.labels += 1
            self._push(
                type(event)(
                    event.stamp_s + offset,
                    event.material,
                    event.confidence,
                    event.known_s + offset,
                )
            )
        for share in ident.take_shares():
            estimate = share_event(share)
            if estimate is None:
                continue
            self.tally.shares += 1
            self._push(
                ShareEstimate(
                    estimate.stamp_s + offset,
                    estimate.share,
                    estimate.low,
                    estimate.high,
                    estimate.interval_s,
                    standard_error=estimate.standard_error,
                )
            )

    def __call__(self, cell: DrawnCell) -> bool:
        share = self.meter.add(cell.material, cell.mass_kg)
        self._strike(cell)
        self._deliver(self.sim.advance(cell.end_s - self.offset_s))
        return self._end_cell(cell.end_s, share)
