"""Flow recordings for the gangue-share evaluation and training: a drawing opening's stream of
coal and gangue lumps at a given rate, pure coal until the coal-gangue boundary arrives and the
gangue share then rising, on one support, with the truth of every lump and of the share per
interval.

The flow is the suite's own (:func:`tail_beam_sim.physics.flow.simulate_flow`, the ``flow``
section of config/flow.yaml: lumps of its size distribution, drop heights and strike positions,
their contacts superposed on the linear support), run at ``rate_per_s`` lumps a second with the
share curve placed in time (:func:`record_sim_flow`), so at tens of lumps a second and more the
beam's responses overlap and every response rings on under the next ones.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tail_beam_id.study.supports import SupportDraw
from tail_beam_sim.config import default_config_dir, load_parameters
from tail_beam_sim.errors import require_range
from tail_beam_sim.physics.flow import ShareCurve as MassShareCurve
from tail_beam_sim.physics.flow import simulate_flow
from tail_beam_sim.physics.materials import material_table
from tail_beam_sim.physics.stream import CHANNELS, WITHOUT_ACCELEROMETER


@dataclass(frozen=True)
class ShareCurve:
    """The true gangue share by count of the flow against time since the window opened: 0 until
    ``boundary_s``, rising linearly to ``final_share`` over ``ramp_s`` (s), then held."""

    boundary_s: float
    ramp_s: float
    final_share: float

    def __post_init__(self) -> None:
        require_range("boundary_s", self.boundary_s, 0.0, 3600.0)
        require_range("ramp_s", self.ramp_s, 0.0, 3600.0)
        require_range("final_share", self.final_share, 0.0, 1.0)


@dataclass
class FlowRecording:
    """One support's recording of a flow: its sensor streams (as sim_node publishes them), the
    truth of every lump (``impact_truth`` objects) and the share curve; stamps in s, the window
    opening at ``open_s``."""

    params: dict[str, Any]
    rate_per_s: float
    open_s: float
    duration_s: float
    curve: ShareCurve
    pressure: Any
    imu: Any
    rebounds: list[Any]
    truths: list[dict[str, Any]]
    vibration: Any = None  # VibrationBlocks; None when the support has no accelerometer
    support: SupportDraw | None = None
    # The camera's impact points (ImpactPoint, stamped as their rebounds) when it reports them
    points: list[Any] = field(default_factory=list)

    def lump_stamps_s(self) -> np.ndarray:
        return np.array([t["contact_start_stamp"] for t in self.truths])

    def gangue(self) -> np.ndarray:
        return np.array([t["label"] == "gangue" for t in self.truths])


def true_shares(
    recording: FlowRecording, intervals: Sequence[tuple[float, float]]
) -> list[tuple[float, int]]:
    """The true gangue share by count of the lumps that struck in each interval [start, end)
    (s), with their number (nan share where none struck)."""
    stamps = recording.lump_stamps_s()
    gangue = recording.gangue()
    out = []
    for start, end in intervals:
        inside = (stamps >= start) & (stamps < end)
        n = int(inside.sum())
        out.append((float(gangue[inside].mean()) if n else math.nan, n))
    return out


def flow_parameters(params: Mapping[str, Any]) -> dict[str, Any]:
    """``params`` with the shipped ``flow`` and ``stream`` sections (config/flow.yaml,
    config/sim_node.yaml) where it has none."""
    merged = dict(params)
    if "flow" not in merged or "stream" not in merged:
        config = default_config_dir()
        shipped = load_parameters([config / "sim_node.yaml", config / "flow.yaml"])
        for name in ("flow", "stream"):
            merged.setdefault(name, shipped[name])
    return merged


def mean_coal_lump_kg(params: Mapping[str, Any], draws: int = 20000) -> float:
    """The mean mass of the flow section's coal lumps (its truncated log-normal radius), kg."""
    flow = params["flow"]
    rng = np.random.default_rng(0)
    radius = np.exp(
        math.log(float(flow["radius_median_m"]))
        + float(flow["radius_log_sigma"]) * rng.standard_normal(draws)
    )
    low, high = (float(v) for v in flow["radius_m"])
    radius = radius[(radius >= low) & (radius <= high)]
    density = material_table(params)[flow["coal_material"]].density_kgpm3
    return float(np.mean(density * 4.0 / 3.0 * math.pi * radius**3))


def record_sim_flow(
    params: Mapping[str, Any],
    rate_per_s: float,
    duration_s: float,
    boundary_s: float,
    ramp_s: float,
    final_share_by_mass: float,
    seed: int,
    support: SupportDraw | None = None,
    vibration: bool = True,
) -> FlowRecording:
    """One flow of the suite's flow simulator (:func:`tail_beam_sim.physics.flow.
    simulate_flow`, ``flow`` section of config/flow.yaml): the window open from 0, ``rate_per_s``
    lumps a second, pure coal until about ``boundary_s`` (s of simulation time) and the share
    by mass then rising linearly to ``final_share_by_mass`` over about ``ramp_s``: the curve is
    given against drawn mass, placed in time with the mean coal lump's mass. ``vibration``:
    simulate and keep the accelerometer (the shipped layout), or leave it out (the IMU alone)."""
    base = flow_parameters(params)
    varied = support.apply(base) if support is not None else {k: v for k, v in base.items()}
    flow = dict(varied["flow"])
    onset = float(flow["onset_delay_s"])
    per_s_kg = rate_per_s * mean_coal_lump_kg(varied)
    start_kg = max(boundary_s - onset, 0.0) * per_s_kg
    masses = [0.0, start_kg + 1e-6, start_kg + max(ramp_s, 1e-3) * per_s_kg + 2e-6]
    shares = [0.0, 0.0, float(final_share_by_mass)]
    if start_kg <= 0.0:
        masses, shares = masses[1:], shares[1:]
    flow.update(
        {
            "rate_kind": "lumps",
            "lumps_per_s": float(rate_per_s),
            "open_at_s": 0.0,
            "duration_s": 0.0,
        }
    )
    varied["flow"] = flow
    varied["sensors"] = {**varied["sensors"], "seed": int(seed) % (2**31)}
    record = simulate_flow(
        varied,
        duration_s,
        seed=int(seed),
        share=MassShareCurve.of(masses, shares),
        channels=CHANNELS if vibration else WITHOUT_ACCELEROMETER,
    )
    truths = [t for _, t in record.truths]
    gangue_count = (
        float(final_share_by_mass)
        / (final_share_by_mass + (1 - final_share_by_mass) * _density_ratio(varied))
        if final_share_by_mass > 0
        else 0.0
    )
    return FlowRecording(
        varied,
        rate_per_s,
        0.0,
        duration_s,
        ShareCurve(boundary_s, ramp_s, gangue_count),
        record.pressure,
        record.imu,
        [r for _, r in record.rebounds],
        truths,
        record.vibration if vibration and record.vibration.count else None,
        support,
        [p for _, p in record.points],
    )


def _density_ratio(params: Mapping[str, Any]) -> float:
    """Mean gangue density over coal density of the flow section's materials."""
    table = material_table(params)
    flow = params["flow"]
    gangue = np.mean([table[n].density_kgpm3 for n in flow["gangue_materials"]])
    return float(gangue / table[flow["coal_material"]].density_kgpm3)
