"""A scene: the support, one impact, the sensors and the time window to simulate.

:meth:`Impact.from_mapping` validates an impact from any mapping: the ``impact_cmd`` JSON of
the simulator node and the command line's options alike, so both give the same errors.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

from tail_beam_sim.contact import CONTACT_LAWS, DEFAULT_CONTACT_LAW
from tail_beam_sim.errors import InputError, require_range
from tail_beam_sim.materials import Material, material_table, particle_material_names
from tail_beam_sim.support import Support

MAX_RADIUS_M = 0.5
MAX_DROP_HEIGHT_M = 50.0
MAX_IMPACT_SPEED_MPS = 30.0
IMPACT_FIELDS = ("material", "radius_m", "drop_height_m", "impact_speed_mps", "position_m", "impact_id", "restitution")


@dataclass(frozen=True)
class Impact:
    """One particle striking the plate: what it is, how fast, and where.

    ``restitution`` is the particle's coefficient of restitution on steel; by default the
    material's nominal value. ``drop_height_m`` is None when the speed was commanded directly.
    """

    material: Material
    radius_m: float
    impact_speed_mps: float
    position_m: float
    restitution: float
    drop_height_m: float | None = None
    impact_id: str = ""

    @property
    def mass_kg(self) -> float:
        """Mass of the equivalent sphere, kg."""
        return self.material.density_kgpm3 * 4.0 / 3.0 * math.pi * self.radius_m**3

    @classmethod
    def from_mapping(
        cls,
        data: Mapping[str, Any],
        materials: Mapping[str, Material],
        support: Support,
        prefix: str = "",
    ) -> Impact:
        """Validate an impact given as a mapping (``impact_cmd`` JSON or CLI options)."""
        if not isinstance(data, Mapping):
            raise InputError(prefix.rstrip(".") or "impact", data, "must be a JSON object")
        unknown = sorted(set(data) - set(IMPACT_FIELDS))
        if unknown:
            raise InputError(f"{prefix}{unknown[0]}", data[unknown[0]], f"unknown field; allowed: {', '.join(IMPACT_FIELDS)}")
        names = particle_material_names(materials)
        name = data.get("material")
        if name is None:
            raise InputError(f"{prefix}material", None, f"required; one of {', '.join(names)}")
        if name not in names:
            raise InputError(f"{prefix}material", name, f"must be one of {', '.join(names)}")
        material = materials[name]
        if data.get("radius_m") is None:
            raise InputError(f"{prefix}radius_m", None, f"required; in (0, {MAX_RADIUS_M:g}] m")
        radius = require_range(f"{prefix}radius_m", data["radius_m"], 0.0, MAX_RADIUS_M, low_open=True, unit="m")
        height, speed = data.get("drop_height_m"), data.get("impact_speed_mps")
        if (height is None) == (speed is None):
            raise InputError(
                f"{prefix}drop_height_m/impact_speed_mps",
                {"drop_height_m": height, "impact_speed_mps": speed},
                "give exactly one of the two",
            )
        if height is not None:
            height = require_range(f"{prefix}drop_height_m", height, 0.0, MAX_DROP_HEIGHT_M, low_open=True, unit="m")
            speed = math.sqrt(2.0 * support.gravity_mps2 * height)
            if speed <= 0.0:
                raise InputError(f"{prefix}drop_height_m", height, "needs gravity_mps2 > 0 to give a speed")
        else:
            speed = require_range(f"{prefix}impact_speed_mps", speed, 0.0, MAX_IMPACT_SPEED_MPS, low_open=True, unit="m/s")
        if data.get("position_m") is None:
            raise InputError(f"{prefix}position_m", None, f"required; in [0, {support.beam_length_m:g}] m from the hinge")
        position = support.check_position(data["position_m"], f"{prefix}position_m")
        restitution = data.get("restitution")
        restitution = material.restitution if restitution is None else require_range(
            f"{prefix}restitution", restitution, 0.0, 1.0, low_open=True
        )
        impact_id = data.get("impact_id") or ""
        if not isinstance(impact_id, str):
            raise InputError(f"{prefix}impact_id", impact_id, "must be a string")
        return cls(material, radius, float(speed), position, restitution, height, impact_id)


@dataclass(frozen=True)
class SensorSpec:
    """Sample rates (Hz) and noise (RMS, in each signal's unit) of the support's sensors."""

    seed: int
    pressure_rate_hz: float
    pressure_noise_pa: float
    pressure_range_min_pa: float
    pressure_range_max_pa: float
    imu_rate_hz: float
    imu_noise_nominal_rate_hz: float
    imu_accel_noise_mps2: float
    imu_gyro_noise_radps: float
    camera_frame_rate_hz: float
    camera_velocity_noise_mps: float
    camera_velocity_noise_fraction: float

    @property
    def imu_noise_scale(self) -> float:
        """Noise grows with sqrt(bandwidth): RMS at this rate over RMS at the nominal rate."""
        return math.sqrt(self.imu_rate_hz / self.imu_noise_nominal_rate_hz)

    def scaled_noise(self, factor: float) -> SensorSpec:
        """The same sensors with every noise RMS multiplied by ``factor``."""
        return replace(
            self,
            pressure_noise_pa=self.pressure_noise_pa * factor,
            imu_accel_noise_mps2=self.imu_accel_noise_mps2 * factor,
            imu_gyro_noise_radps=self.imu_gyro_noise_radps * factor,
            camera_velocity_noise_mps=self.camera_velocity_noise_mps * factor,
            camera_velocity_noise_fraction=self.camera_velocity_noise_fraction * factor,
        )

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> SensorSpec:
        """Build and validate the sensors from the ``sensors`` parameter section."""
        if not isinstance(params, Mapping):
            raise InputError("sensors", params, "missing parameter section")

        def rate(name: str) -> float:
            return require_range(f"sensors.{name}", params.get(name), 1.0, 1e6, unit="Hz")

        def noise(name: str, unit: str) -> float:
            return require_range(f"sensors.{name}", params.get(name), 0.0, None, unit=unit)

        seed = params.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise InputError("sensors.seed", seed, "must be an integer >= 0")
        low = require_range("sensors.pressure_range_min_pa", params.get("pressure_range_min_pa"), unit="Pa")
        return cls(
            seed=seed,
            pressure_rate_hz=rate("pressure_rate_hz"),
            pressure_noise_pa=noise("pressure_noise_pa", "Pa"),
            pressure_range_min_pa=low,
            pressure_range_max_pa=require_range("sensors.pressure_range_max_pa", params.get("pressure_range_max_pa"), low, None, low_open=True, unit="Pa"),
            imu_rate_hz=rate("imu_rate_hz"),
            imu_noise_nominal_rate_hz=rate("imu_noise_nominal_rate_hz"),
            imu_accel_noise_mps2=noise("imu_accel_noise_mps2", "m/s^2"),
            imu_gyro_noise_radps=noise("imu_gyro_noise_radps", "rad/s"),
            camera_frame_rate_hz=rate("camera_frame_rate_hz"),
            camera_velocity_noise_mps=noise("camera_velocity_noise_mps", "m/s"),
            camera_velocity_noise_fraction=require_range("sensors.camera_velocity_noise_fraction", params.get("camera_velocity_noise_fraction"), 0.0, 1.0),
        )


@dataclass(frozen=True)
class Scene:
    """Everything one offline simulation needs. Times in s, measured from first contact."""

    support: Support
    impact: Impact
    sensors: SensorSpec
    materials: Mapping[str, Material]
    contact_model: str = DEFAULT_CONTACT_LAW
    window_s: float = 0.05
    pre_contact_s: float = 0.005

    def with_impact(self, **changes: Any) -> Scene:
        """A copy of the scene with some impact fields changed (no re-validation)."""
        return replace(self, impact=replace(self.impact, **changes))

    @classmethod
    def from_params(cls, params: Mapping[str, Any], overrides: Mapping[str, Any] | None = None) -> Scene:
        """Build a scene from merged parameters, with ``overrides`` of ``scene.*`` values.

        ``overrides`` takes impact fields (``material``, ``radius_m``, ``drop_height_m`` or
        ``impact_speed_mps``, ``position_m``, ``restitution``) and ``contact_model``,
        ``window_s``, ``pre_contact_s``, ``seed``; None values are ignored.
        """
        materials = material_table(params)
        support = Support.from_params(params.get("support"), materials)
        scene_params = dict(params.get("scene") or {})
        given = {k: v for k, v in (overrides or {}).items() if v is not None}
        if "drop_height_m" in given or "impact_speed_mps" in given:
            scene_params.pop("drop_height_m", None)
            scene_params.pop("impact_speed_mps", None)
        scene_params.update(given)
        sensor_params = dict(params.get("sensors") or {})
        if "seed" in scene_params:
            sensor_params["seed"] = scene_params.pop("seed")
        impact = Impact.from_mapping({k: scene_params.get(k) for k in IMPACT_FIELDS if k in scene_params}, materials, support)
        contact_model = scene_params.get("contact_model", DEFAULT_CONTACT_LAW)
        if contact_model not in CONTACT_LAWS:
            raise InputError("contact_model", contact_model, f"must be one of {', '.join(CONTACT_LAWS)}")
        return cls(
            support=support,
            impact=impact,
            sensors=SensorSpec.from_params(sensor_params),
            materials=materials,
            contact_model=contact_model,
            window_s=require_range("window_s", scene_params.get("window_s", 0.05), 0.0, 10.0, low_open=True, unit="s"),
            pre_contact_s=require_range("pre_contact_s", scene_params.get("pre_contact_s", 0.005), 0.0, 10.0, unit="s"),
        )
