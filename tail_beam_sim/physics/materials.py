"""Materials of particles and plate, read from the ``materials`` parameter section."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from tail_beam_sim.errors import InputError
from tail_beam_sim.spec import MATERIAL

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
        values = MATERIAL.check(params, where=field)
        low_high = values.pop("restitution_range") or (values["restitution"],) * 2
        return cls(
            name=name,
            material_class=values.pop("class"),
            restitution_range=low_high,
            **values,
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
