"""Materials of particles and plate, read from the ``materials`` parameter section."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from tail_beam_sim.errors import InputError, require_range

MATERIAL_CLASSES = ("coal", "gangue", "structure")
Number = TypeVar("Number", float, np.ndarray)


def sphere_mass_kg(density_kgpm3: Number, radius_m: Number) -> Number:
    """Mass of a sphere of ``radius_m`` (m) and ``density_kgpm3`` (kg/m^3), kg: rho 4/3 pi R^3
    (floats, or arrays for a batch of particles)."""
    return density_kgpm3 * 4.0 / 3.0 * math.pi * radius_m**3


@dataclass(frozen=True)
class Material:
    """An isotropic elastic material with its restitution on steel.

    ``restitution`` is the nominal coefficient of restitution (dimensionless) and
    ``restitution_range`` the (low, high) a realistic scene draws from.
    """

    name: str
    material_class: str
    density_kgpm3: float
    youngs_modulus_pa: float
    poisson_ratio: float
    restitution: float
    restitution_range: tuple[float, float]
    crushing_strength_pa: float

    @property
    def is_coal(self) -> bool:
        return self.material_class == "coal"

    @classmethod
    def from_params(cls, name: str, params: Mapping[str, Any]) -> Material:
        """Build and validate one material from its parameter mapping."""
        field = f"materials.{name}"
        if not isinstance(params, Mapping):
            raise InputError(field, params, "must be a mapping of material properties")
        material_class = params.get("class")
        if material_class not in MATERIAL_CLASSES:
            raise InputError(
                f"{field}.class", material_class, f"must be one of {MATERIAL_CLASSES}"
            )
        low_high = params.get(
            "restitution_range", [params.get("restitution"), params.get("restitution")]
        )
        if not isinstance(low_high, (list, tuple)) or len(low_high) != 2:
            raise InputError(f"{field}.restitution_range", low_high, "must be [low, high]")
        low = require_range(f"{field}.restitution_range[0]", low_high[0], 0.0, 1.0, low_open=True)
        high = require_range(f"{field}.restitution_range[1]", low_high[1], low, 1.0)
        return cls(
            name=name,
            material_class=str(material_class),
            density_kgpm3=require_range(
                f"{field}.density_kgpm3",
                params.get("density_kgpm3"),
                0.0,
                30000.0,
                low_open=True,
                unit="kg/m^3",
            ),
            youngs_modulus_pa=require_range(
                f"{field}.youngs_modulus_pa",
                params.get("youngs_modulus_pa"),
                0.0,
                2e12,
                low_open=True,
                unit="Pa",
            ),
            poisson_ratio=require_range(
                f"{field}.poisson_ratio", params.get("poisson_ratio"), -1.0, 0.5, low_open=True
            ),
            restitution=require_range(
                f"{field}.restitution", params.get("restitution"), 0.0, 1.0, low_open=True
            ),
            restitution_range=(low, high),
            crushing_strength_pa=require_range(
                f"{field}.crushing_strength_pa",
                params.get("crushing_strength_pa", 1e12),
                0.0,
                None,
                low_open=True,
                unit="Pa",
            ),
        )


def material_table(params: Mapping[str, Any]) -> dict[str, Material]:
    """All materials of the ``materials`` parameter section, by name."""
    section = params.get("materials")
    if not isinstance(section, Mapping) or not section:
        raise InputError("materials", section, "the config must define at least one material")
    return {name: Material.from_params(name, body) for name, body in section.items()}


def particle_material_names(table: Mapping[str, Material]) -> list[str]:
    """Names of materials a particle may be made of (coal or gangue, not structure)."""
    return sorted(name for name, m in table.items() if m.material_class != "structure")
