"""The lumps a drawing opening lets fall onto the tail beam: when, how big, of what, where.

:class:`FlowParams` is the checked ``flow`` section; :class:`LumpSource` draws the lumps of a
window that opens and closes, one seeded draw per lump in release order, so the lumps depend
only on the seed and the opening and closing times:

* Release times form a Poisson stream while the window is open, the first as it opens: gaps are
  exponential with mean 1 / ``lumps_per_s`` (``rate_kind: lumps``) or with mean
  (this lump's mass / ``mass_rate_kgps``) (``rate_kind: mass``: the mean mass rate is met
  whatever the lumps weigh). A lump strikes the beam ``onset_delay_s`` after its release, so
  lumps released before the window closes still land after it.
* Radius: log-normal (median ``radius_median_m``, ``radius_log_sigma`` of ln radius)
  truncated to ``radius_m`` by inverse transform; drop height and strike position uniform in
  their ranges; restitution uniform in the material's ``restitution_range``.
* Material: gangue with the probability that gives the share curve's gangue share *by mass* at
  the mass drawn so far (coal and gangue lumps share the size distribution, so a gangue lump
  outweighs a coal lump by the density ratio: p = s rho_c / (s rho_c + (1 - s) rho_g), rho_g
  the mean density of the gangue materials); the gangue material uniform among
  ``gangue_materials``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.special import ndtr, ndtri

from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.materials import Material, sphere_mass_kg
from tail_beam_sim.physics.share_curve import ShareCurve
from tail_beam_sim.physics.support import Support
from tail_beam_sim.spec import FLOW

_DRAWS_PER_LUMP = 7  # uniform draws per lump: material, gangue kind, radius, height, position,
# restitution, gap


@dataclass(frozen=True)
class FlowParams:
    """The checked ``flow`` section (units in the names; docs/parameters.md)."""

    rate_kind: str
    lumps_per_s: float
    mass_rate_kgps: float
    radius_median_m: float
    radius_log_sigma: float
    radius_m: tuple[float, float]
    drop_height_m: tuple[float, float]
    position_m: tuple[float, float]
    coal_material: str
    gangue_materials: tuple[str, ...]
    share: ShareCurve
    interval_s: float
    onset_delay_s: float
    seed: int
    contact: str
    open_at_s: float
    duration_s: float

    @classmethod
    def from_params(
        cls,
        section: Mapping[str, Any],
        materials: Mapping[str, Material],
        support: Support,
        share: ShareCurve | None = None,
    ) -> FlowParams:
        """Validate the ``flow`` section against the support's bounds and the materials;
        ``share`` replaces the section's share curve. InputError names the field."""
        values = FLOW.check(
            section,
            context={
                "particle_radius_min_m": support.particle_radius_min_m,
                "particle_radius_max_m": support.particle_radius_max_m,
                "drop_height_max_m": support.drop_height_max_m,
                "impact_zone_max_m": support.impact_zone_max_m,
            },
        )
        lo, hi = values["radius_m"]
        if not lo <= values["radius_median_m"] <= hi:
            raise InputError(
                "flow.radius_median_m",
                values["radius_median_m"],
                f"must lie in flow.radius_m [{lo:g}, {hi:g}] m",
            )
        coal = values["coal_material"]
        if coal not in materials or materials[coal].material_class != "coal":
            names = sorted(n for n, m in materials.items() if m.material_class == "coal")
            raise InputError("flow.coal_material", coal, f"must be one of {', '.join(names)}")
        gangue = values["gangue_materials"]
        allowed = sorted(n for n, m in materials.items() if m.material_class == "gangue")
        if not gangue:
            raise InputError("flow.gangue_materials", gangue, "must name at least one material")
        for k, name in enumerate(gangue):
            if name not in allowed:
                raise InputError(
                    f"flow.gangue_materials[{k}]", name, f"must be one of {', '.join(allowed)}"
                )
        curve = share or ShareCurve.of(values["share_drawn_mass_kg"], values["share_gangue"])
        values.pop("share_drawn_mass_kg"), values.pop("share_gangue")
        values["gangue_materials"] = tuple(gangue)
        return cls(**values, share=curve)


@dataclass(frozen=True)
class Lump:
    """One lump: what it is, where and when it strikes (contact stamp, s of simulation time)
    and the mass drawn before it (kg since the window first opened)."""

    impact_id: str
    material: str
    is_gangue: bool
    radius_m: float
    mass_kg: float
    drop_height_m: float
    position_m: float
    restitution: float
    contact_stamp_s: float
    drawn_mass_kg: float

    def command(self) -> dict[str, Any]:
        """The ``impact_cmd`` JSON object of this lump."""
        return {
            "material": self.material,
            "radius_m": self.radius_m,
            "drop_height_m": self.drop_height_m,
            "position_m": self.position_m,
            "restitution": self.restitution,
            "impact_id": self.impact_id,
        }


class WindowStateError(InputError):
    """A window command for a window already in that state."""


class LumpSource:
    """The lumps of one drawing opening, drawn as its window opens and closes."""

    def __init__(
        self,
        params: FlowParams,
        materials: Mapping[str, Material],
        seed: int | None = None,
        id_prefix: str = "flow",
    ) -> None:
        self.params = params
        self.id_prefix = id_prefix
        self._coal = materials[params.coal_material]
        self._gangue = [materials[name] for name in params.gangue_materials]
        self._gangue_density = float(np.mean([m.density_kgpm3 for m in self._gangue]))
        if seed is not None:  # a caller's seed meets the flow.seed's own range
            seed = FLOW.check({"seed": seed}, only=["seed"])["seed"]
        self._rng = np.random.default_rng(params.seed if seed is None else seed)
        self.windows: list[tuple[float, float]] = []  # (opened, closed) s; closed inf while open
        self._span = 0  # the window the release process is in
        self._next_release_s: float | None = None  # None: the window's opening
        self.drawn_mass_kg = 0.0
        self.count = 0

    @property
    def is_open(self) -> bool:
        """Whether the window is open (its last command was open)."""
        return bool(self.windows) and self.windows[-1][1] == math.inf

    def open(self, stamp_s: float) -> float:
        """Open the window at ``stamp_s`` (not before the last closing): lumps are released from
        then on. Returns the stamp; WindowStateError if it is open already."""
        if self.is_open:
            raise WindowStateError(
                "window_cmd.action", "open", "refused: the window is already open"
            )
        stamp = max(float(stamp_s), self.windows[-1][1] if self.windows else -math.inf)
        self.windows.append((stamp, math.inf))
        return stamp

    def close(self, stamp_s: float) -> float:
        """Close the window at ``stamp_s`` (not before its opening): no lump is released from
        then on; those already falling still land. Returns the stamp; WindowStateError if it is
        closed already."""
        if not self.is_open:
            raise WindowStateError(
                "window_cmd.action", "close", "refused: the window is already closed"
            )
        opened = self.windows[-1][0]
        stamp = max(float(stamp_s), opened)
        self.windows[-1] = (opened, stamp)
        return stamp

    @property
    def exhausted(self) -> bool:
        """No lump will be released unless the window opens again."""
        return self._span >= len(self.windows)

    def take_until(self, until_s: float) -> list[Lump]:
        """Every lump not yet taken that strikes the beam at or before ``until_s``."""
        latest_release = until_s - self.params.onset_delay_s
        lumps = []
        while self._span < len(self.windows):
            opened, closed = self.windows[self._span]
            release = opened if self._next_release_s is None else self._next_release_s
            if release >= closed:
                self._span += 1
                self._next_release_s = None
                continue
            if release > latest_release:
                self._next_release_s = release
                break
            lump, gap = self._draw(release)
            lumps.append(lump)
            self._next_release_s = release + gap
        return lumps

    def _draw(self, release_s: float) -> tuple[Lump, float]:
        """The lump released at ``release_s`` and the gap to the next release, s."""
        p = self.params
        u = self._rng.random(_DRAWS_PER_LUMP)
        share = float(p.share.at(self.drawn_mass_kg))
        rho_c, rho_g = self._coal.density_kgpm3, self._gangue_density
        denominator = share * rho_c + (1.0 - share) * rho_g
        p_gangue = share * rho_c / denominator if denominator > 0 else 0.0
        is_gangue = bool(u[0] < p_gangue)
        material = (
            self._gangue[min(int(u[1] * len(self._gangue)), len(self._gangue) - 1)]
            if is_gangue
            else self._coal
        )
        radius = lump_radius_m(self.params, float(u[2]))
        mass = float(sphere_mass_kg(material.density_kgpm3, radius))
        height = p.drop_height_m[0] + u[3] * (p.drop_height_m[1] - p.drop_height_m[0])
        position = p.position_m[0] + u[4] * (p.position_m[1] - p.position_m[0])
        low, high = material.restitution_range
        restitution = low + u[5] * (high - low)
        mean_gap = 1.0 / p.lumps_per_s if p.rate_kind == "lumps" else mass / p.mass_rate_kgps
        gap = -mean_gap * math.log1p(-float(u[6]))
        self.count += 1
        lump = Lump(
            impact_id=f"{self.id_prefix}-{self.count:06d}",
            material=material.name,
            is_gangue=is_gangue,
            radius_m=radius,
            mass_kg=mass,
            drop_height_m=float(height),
            position_m=float(position),
            restitution=float(restitution),
            contact_stamp_s=release_s + p.onset_delay_s,
            drawn_mass_kg=self.drawn_mass_kg,
        )
        self.drawn_mass_kg += mass
        return lump, gap


def lump_radius_m(params: FlowParams, u: float) -> float:
    """A lump radius from one uniform draw ``u`` in [0, 1): the flow's log-normal radius
    (median ``radius_median_m``, log-sigma ``radius_log_sigma``) truncated to ``radius_m``, by
    inverting its distribution function (m)."""
    lo, hi = params.radius_m
    median, sigma = params.radius_median_m, params.radius_log_sigma
    if sigma == 0.0:
        return min(max(median, lo), hi)
    a, b = (float(ndtr(math.log(r / median) / sigma)) for r in (lo, hi))
    z = float(ndtri(a + u * (b - a)))
    return min(max(median * math.exp(sigma * z), lo), hi)
