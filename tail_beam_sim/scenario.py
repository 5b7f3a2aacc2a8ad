"""Start-up scenarios of the simulator: a YAML list of impacts, or a generated caving stream.

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
import yaml

from tail_beam_sim.errors import InputError, require_range
from tail_beam_sim.materials import Material
from tail_beam_sim.scene import MAX_DROP_HEIGHT_M, MAX_RADIUS_M, Impact
from tail_beam_sim.support import Support

SOURCES = ("none", "file", "generated")
MAX_GENERATED = 100_000


@dataclass(frozen=True)
class PlannedImpact:
    """One impact of a scenario: its command and the contact stamp it asks for (s, or None)."""

    command: dict[str, Any]
    contact_stamp_s: float | None = None


def load_scenario(params: Mapping[str, Any], materials: Mapping[str, Material], support: Support) -> list[PlannedImpact]:
    """The scenario the ``scenario`` parameter section describes (validated)."""
    source = params.get("source", "none")
    if source not in SOURCES:
        raise InputError("scenario.source", source, f"must be one of {', '.join(SOURCES)}")
    if source == "none":
        return []
    if source == "file":
        planned = read_scenario_file(params.get("file", ""))
    else:
        planned = generate_caving_stream(params, materials)
    for index, item in enumerate(planned):
        Impact.from_mapping(item.command, materials, support, prefix=f"scenario[{index}].")
    return planned


def read_scenario_file(path: str | os.PathLike[str]) -> list[PlannedImpact]:
    """Impacts from a YAML file: a list (or ``{impacts: [...]}``) of impact_cmd objects.

    An item may hold ``contact_stamp_s``, the contact time it asks for, s.
    """
    if not path:
        raise InputError("scenario.file", path, "must name a YAML file when scenario.source is file")
    try:
        data = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError("scenario.file", str(path), f"must be a readable file ({exc.strerror})") from None
    except yaml.YAMLError as exc:
        raise InputError("scenario.file", str(path), f"must be valid YAML ({str(exc).splitlines()[0]})") from None
    if isinstance(data, Mapping):
        data = data.get("impacts")
    if not isinstance(data, list):
        raise InputError("scenario.file", str(path), "must hold a list of impacts (or impacts: [...])")
    planned = []
    for index, item in enumerate(data):
        if not isinstance(item, Mapping):
            raise InputError(f"scenario[{index}]", item, "must be a mapping of impact fields")
        command = dict(item)
        stamp = command.pop("contact_stamp_s", None)
        if stamp is not None:
            stamp = require_range(f"scenario[{index}].contact_stamp_s", stamp, 0.0, None, unit="s")
        planned.append(PlannedImpact(command, stamp))
    return planned


def _range(params: Mapping[str, Any], name: str, low: float, high: float | None, unit: str) -> tuple[float, float]:
    value = params.get(name)
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != 2:
        raise InputError(f"scenario.{name}", value, f"must be [low, high] in {unit}")
    lo = require_range(f"scenario.{name}[0]", value[0], low, high, low_open=True, unit=unit)
    hi = require_range(f"scenario.{name}[1]", value[1], lo, high, unit=unit)
    return lo, hi


def generate_caving_stream(params: Mapping[str, Any], materials: Mapping[str, Material]) -> list[PlannedImpact]:
    """A seeded stream of falling coal and gangue particles.

    Exactly ``round(count * gangue_fraction)`` particles are gangue, in shuffled order; each
    gangue particle is one of the config's gangue materials, chosen uniformly. Radius, drop
    height and position are uniform in their ranges, restitution uniform in the material's
    ``restitution_range``, the time between contacts uniform in ``interval_s``.
    """
    count = params.get("count")
    if isinstance(count, bool) or not isinstance(count, int) or not 0 <= count <= MAX_GENERATED:
        raise InputError("scenario.count", count, f"must be an integer in [0, {MAX_GENERATED}]")
    seed = params.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InputError("scenario.seed", seed, "must be an integer >= 0")
    fraction = require_range("scenario.gangue_fraction", params.get("gangue_fraction"), 0.0, 1.0)
    radius = _range(params, "radius_m", 0.0, MAX_RADIUS_M, "m")
    height = _range(params, "drop_height_m", 0.0, MAX_DROP_HEIGHT_M, "m")
    position = _range(params, "position_m", 0.0, None, "m")
    interval = _range(params, "interval_s", 0.0, 3600.0, "s")
    start = require_range("scenario.start_s", params.get("start_s", 0.0), 0.0, None, unit="s")
    coal = sorted(name for name, m in materials.items() if m.material_class == "coal")
    gangue = sorted(name for name, m in materials.items() if m.material_class == "gangue")
    if (fraction < 1.0 and not coal) or (fraction > 0.0 and not gangue):
        raise InputError("scenario.gangue_fraction", fraction, "needs coal and gangue materials in the config")
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
