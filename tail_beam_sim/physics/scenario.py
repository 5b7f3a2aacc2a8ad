"""Start-up scenarios of the simulator: a YAML list of impacts, or a generated caving stream.

(A drawing opening's flow, ``source: flow``, is no list of impacts: its lumps are drawn as its
window opens and closes, :mod:`tail_beam_sim.physics.flow`; here it plans none.)

A scenario is a list of :class:`PlannedImpact`: an ``impact_cmd`` JSON object and, when the
scenario fixes it, the contact stamp (s of simulation time) it asks for. Every impact is
validated here, so a bad scenario fails at start-up with the field named.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tail_beam_sim.config import default_config_dir, read_yaml_file
from tail_beam_sim.errors import InputError, require_range
from tail_beam_sim.physics.materials import Material
from tail_beam_sim.physics.scene import Impact
from tail_beam_sim.physics.support import Support
from tail_beam_sim.spec import SCENARIO

SOURCES = SCENARIO["source"].choices
MAX_GENERATED = SCENARIO["count"].high


@dataclass(frozen=True)
class PlannedImpact:
    """One impact of a scenario: its command and the contact stamp it asks for (s, or None)."""

    command: dict[str, Any]
    contact_stamp_s: float | None = None


def load_scenario(
    params: Mapping[str, Any], materials: Mapping[str, Material], support: Support
) -> list[PlannedImpact]:
    """The scenario the ``scenario`` parameter section describes (validated)."""
    source = params.get("source", "none")
    if source not in SOURCES:
        raise InputError("scenario.source", source, f"must be one of {', '.join(SOURCES)}")
    if source in ("none", "flow"):
        return []
    if source == "file":
        planned = read_scenario_file(params.get("file", ""))
    else:
        planned = generate_caving_stream(params, materials, support)
    check_impacts([item.command for item in planned], materials, support)
    return planned


def check_impacts(
    commands: Sequence[Mapping[str, Any]],
    materials: Mapping[str, Material],
    support: Support,
    item: str = "scenario",
) -> list[Impact]:
    """Validate a list of impact_cmd objects as the simulator will (``Impact.from_mapping``),
    and refuse an impact_id used twice in it; errors name ``<item>[index].<field>``."""
    seen: set[str] = set()
    impacts = []
    for index, command in enumerate(commands):
        impact = Impact.from_mapping(command, materials, support, prefix=f"{item}[{index}].")
        if impact.impact_id in seen:
            raise InputError(
                f"{item}[{index}].impact_id",
                impact.impact_id,
                f"is used twice in the {item}; each impact_id names one impact",
            )
        seen.add(impact.impact_id or f"\0{index}")
        impacts.append(impact)
    return impacts


def resolve_scenario_file(path: str | os.PathLike[str]) -> Path:
    """A scenario file: as given (absolute, or relative to the working directory), else the
    file of that name in the shipped config directory (``scenario.file:=impacts.yaml``)."""
    given = Path(path)
    if given.is_absolute() or given.exists():
        return given
    shipped = default_config_dir() / given
    return shipped if shipped.exists() else given


def read_scenario_file(
    path: str | os.PathLike[str], field: str = "scenario.file", item: str = "scenario"
) -> list[PlannedImpact]:
    """Impacts from a YAML file: a list (or ``{impacts: [...]}``) of impact_cmd objects.

    An item may hold ``contact_stamp_s``, the contact time it asks for, s. A relative path is
    looked for in the working directory, then in the shipped config directory. Errors name the
    file as ``field`` and an item as ``<item>[index]`` (``tail-beam send`` reads the same files).
    """
    if not path:
        raise InputError(field, path, "must name a YAML file of impacts")
    data = read_yaml_file(resolve_scenario_file(path), field)
    if isinstance(data, Mapping):
        data = data.get("impacts")
    if not isinstance(data, list):
        raise InputError(field, str(path), "must hold a list of impacts (or impacts: [...])")
    planned = []
    for index, entry in enumerate(data):
        if not isinstance(entry, Mapping):
            raise InputError(f"{item}[{index}]", entry, "must be a mapping of impact fields")
        command = dict(entry)
        stamp = command.pop("contact_stamp_s", None)
        if stamp is not None:
            stamp = require_range(f"{item}[{index}].contact_stamp_s", stamp, 0.0, None, unit="s")
        planned.append(PlannedImpact(command, stamp))
    return planned


# The fields of the scenario section a generated stream reads.
GENERATED_FIELDS = (
    "count",
    "gangue_fraction",
    "radius_m",
    "drop_height_m",
    "position_m",
    "interval_s",
    "start_s",
    "seed",
)


def generate_caving_stream(
    params: Mapping[str, Any], materials: Mapping[str, Material], support: Support | None = None
) -> list[PlannedImpact]:
    """A seeded stream of falling coal and gangue particles.

    Exactly ``round(count * gangue_fraction)`` particles are gangue, in shuffled order; each
    gangue particle is one of the config's gangue materials, chosen uniformly. Radius, drop
    height and position are uniform in their ranges, restitution uniform in the material's
    ``restitution_range``, the time between contacts uniform in ``interval_s``. The support,
    when given, bounds the ranges (every impact is validated against it by :func:`load_scenario`).
    """
    bounds = (
        {
            "particle_radius_max_m": support.particle_radius_max_m,
            "drop_height_max_m": support.drop_height_max_m,
        }
        if support
        else {}
    )
    values = SCENARIO.check(params, only=GENERATED_FIELDS, context=bounds)
    count, seed, fraction = values["count"], values["seed"], values["gangue_fraction"]
    radius, height = values["radius_m"], values["drop_height_m"]
    position, interval, start = values["position_m"], values["interval_s"], values["start_s"]
    coal = sorted(name for name, m in materials.items() if m.material_class == "coal")
    gangue = sorted(name for name, m in materials.items() if m.material_class == "gangue")
    if (fraction < 1.0 and not coal) or (fraction > 0.0 and not gangue):
        raise InputError(
            "scenario.gangue_fraction", fraction, "needs coal and gangue materials in the config"
        )
    rng = np.random.default_rng(seed)
    is_gangue = np.zeros(count, dtype=bool)
    is_gangue[: int(round(count * fraction))] = True
    rng.shuffle(is_gangue)
    planned = []
    stamp = start
    for index, gangue_particle in enumerate(is_gangue):
        names = gangue if gangue_particle else coal
        material = materials[names[int(rng.integers(len(names)))]]
        command = {
            "material": material.name,
            "radius_m": float(rng.uniform(*radius)),
            "drop_height_m": float(rng.uniform(*height)),
            "position_m": float(rng.uniform(*position)),
            "restitution": float(rng.uniform(*material.restitution_range)),
            "impact_id": f"caving-{index:04d}",
        }
        planned.append(PlannedImpact(command, stamp))
        stamp += float(rng.uniform(*interval))
    return planned
