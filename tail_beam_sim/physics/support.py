"""The support's tail beam and jack: geometry, jack stiffness and the beam's linear dynamics."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from tail_beam_sim.errors import InputError, require_range
from tail_beam_sim.physics.materials import Material
from tail_beam_sim.spec import SUPPORT


@dataclass(frozen=True)
class Support:
    """A tail beam turning about its hinge, held by the tail-beam jack. SI units throughout."""

    gravity_mps2: float
    beam_length_m: float
    beam_mass_kg: float
    beam_inertia_about_hinge_kgm2: float
    plate: Material
    plate_thickness_m: float
    jack_pin_from_hinge_m: float
    jack_angle_to_beam_deg: float
    jack_bore_m: float
    jack_oil_column_m: float
    jack_wall_thickness_m: float
    jack_wall_youngs_modulus_pa: float
    oil_bulk_modulus_pa: float
    jack_damping_nspm: float
    jack_extra_compliance_mpn: float
    setting_pressure_pa: float
    imu_from_hinge_m: float
    impact_zone_min_m: float
    impact_zone_max_m: float
    # The impacts the model is built for (config/support.yaml): radius m, drop height m, speed m/s.
    particle_radius_min_m: float
    particle_radius_max_m: float
    drop_height_min_m: float
    drop_height_max_m: float
    impact_speed_min_mps: float
    impact_speed_max_mps: float
    # Multiplies the contact law's hysteresis factor chi (dimensionless; 1 = the law as
    # published): how much more or less than the law says a particle's contact with this
    # support's wear plate dissipates (config/support.yaml).
    contact_damping_scale: float = 1.0
    # Width of the impact plate across the beam, m: where the camera may see a particle strike
    # (impact_point.point.y within +- half of it).
    plate_width_m: float = 1.5

    @property
    def piston_area_m2(self) -> float:
        """Piston area S of the jack's piston chamber, m^2."""
        return math.pi * self.jack_bore_m**2 / 4.0

    @property
    def effective_bulk_modulus_pa(self) -> float:
        """Oil bulk modulus softened by the hoop expansion of a thin wall, Pa."""
        wall = self.jack_bore_m / (self.jack_wall_thickness_m * self.jack_wall_youngs_modulus_pa)
        return 1.0 / (1.0 / self.oil_bulk_modulus_pa + wall)

    @property
    def jack_stiffness_npm(self) -> float:
        """Axial stiffness K_Q of the jack: oil column, wall and extra compliance in series,
        N/m."""
        column = self.effective_bulk_modulus_pa * self.piston_area_m2 / self.jack_oil_column_m
        return 1.0 / (1.0 / column + self.jack_extra_compliance_mpn)

    @property
    def jack_lever_arm_m(self) -> float:
        """Perpendicular distance d from the hinge to the jack axis, m."""
        return self.jack_pin_from_hinge_m * math.sin(math.radians(self.jack_angle_to_beam_deg))

    @property
    def rotational_stiffness_nmprad(self) -> float:
        """K_Q d^2: the jack's restoring moment per radian of beam rotation, N m/rad."""
        return self.jack_stiffness_npm * self.jack_lever_arm_m**2

    @property
    def rotational_damping_nmsprad(self) -> float:
        """c_Q d^2: the jack's damping moment per rad/s of beam rotation, N m s/rad."""
        return self.jack_damping_nspm * self.jack_lever_arm_m**2

    @property
    def rigid_mode_frequency_hz(self) -> float:
        """Undamped frequency of the rigid beam on its jack, sqrt(K_Q d^2 / I_C) / 2 pi, Hz."""
        return math.sqrt(self.rotational_stiffness_nmprad / self.beam_inertia_about_hinge_kgm2) / (
            2 * math.pi
        )

    @property
    def rigid_mode_damping_ratio(self) -> float:
        """Damping ratio of the rigid beam mode (dimensionless)."""
        return self.rotational_damping_nmsprad / (
            2.0 * math.sqrt(self.rotational_stiffness_nmprad * self.beam_inertia_about_hinge_kgm2)
        )

    def check_position(
        self, position_m: object, field: str = "position_m", allow_text: bool = True
    ) -> float:
        """Validate an impact position along the plate (0 .. beam length), m. Position 0 is over
        the hinge, where the plate cannot move: the particle rebounds as off a rigid wall."""
        return require_range(
            field,
            position_m,
            0.0,
            self.beam_length_m,
            unit="m (on the plate, from the hinge)",
            allow_text=allow_text,
        )

    @classmethod
    def from_params(cls, params: Mapping[str, Any], materials: Mapping[str, Material]) -> Support:
        """Build and validate the support from the ``support`` parameter section."""
        if not isinstance(params, Mapping):
            raise InputError("support", params, "missing parameter section")

        plate_name = params.get("plate_material")
        if plate_name not in materials:
            raise InputError(
                "support.plate_material", plate_name, f"must be one of {sorted(materials)}"
            )
        values = SUPPORT.check(params)
        values["plate"] = materials[values.pop("plate_material")]
        support = cls(**values)
        if support.impact_zone_min_m > support.impact_zone_max_m:
            raise InputError(
                "support.impact_zone_min_m",
                support.impact_zone_min_m,
                "must not exceed impact_zone_max_m",
            )
        return support


def support_indices() -> Callable[[Support], int]:
    """A function giving each support the index of the first equal one it was given: equal
    supports one index, each object hashed once (a support's hash walks all its fields; the
    scenes of a batch mostly share one object). The supports must outlive the function."""
    by_id: dict[int, int] = {}
    by_value: dict[Support, int] = {}

    def index(support: Support) -> int:
        known = by_id.get(id(support))
        if known is None:
            known = by_id[id(support)] = by_value.setdefault(support, len(by_value))
        return known

    return index
