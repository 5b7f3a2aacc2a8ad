"""A scene: the support, one impact, the sensors and the time window to simulate.

:meth:`Impact.from_mapping` validates an impact from any mapping: the ``impact_cmd`` JSON of
the simulator node and the command line's options alike, so both give the same errors.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

from tail_beam_sim.errors import InputError, require_range
from tail_beam_sim.physics.contact import DEFAULT_CONTACT_LAW
from tail_beam_sim.physics.materials import (
    Material,
    material_table,
    particle_material_names,
    sphere_mass_kg,
)
from tail_beam_sim.physics.support import Support
from tail_beam_sim.spec import SCENE, SENSORS

MAX_IMPACT_ID_CHARS = (
    128  # docs/interface.md: an impact_id is a printable string of 1..128 characters
)
IMPACT_FIELDS = (
    "material",
    "radius_m",
    "drop_height_m",
    "impact_speed_mps",
    "position_m",
    "impact_id",
    "restitution",
)


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
        return sphere_mass_kg(self.material.density_kgpm3, self.radius_m)

    @classmethod
    def from_mapping(
        cls,
        data: Mapping[str, Any],
        materials: Mapping[str, Material],
        support: Support,
        prefix: str = "",
        text_numbers: bool = False,
    ) -> Impact:
        """Validate an impact given as a mapping (``impact_cmd`` JSON or CLI options).

        Numbers must be numbers (``"0.03"`` is refused) unless ``text_numbers``: command-line
        options arrive as text. The ranges are the support's (config/support.yaml).
        """
        if not isinstance(data, Mapping):
            raise InputError(prefix.rstrip(".") or "impact", data, "must be a JSON object")
        unknown = sorted(set(data) - set(IMPACT_FIELDS))
        if unknown:
            raise InputError(
                f"{prefix}{unknown[0]}",
                data[unknown[0]],
                f"unknown field; allowed: {', '.join(IMPACT_FIELDS)}",
            )
        names = particle_material_names(materials)
        name = data.get("material")
        if name is None:
            raise InputError(f"{prefix}material", None, f"required; one of {', '.join(names)}")
        if name not in names:
            raise InputError(f"{prefix}material", name, f"must be one of {', '.join(names)}")
        material = materials[name]

        def number(
            field: str, low: float, high: float, unit: str, low_open: bool = False
        ) -> float:
            return require_range(
                f"{prefix}{field}",
                data[field],
                low,
                high,
                low_open=low_open,
                unit=unit,
                allow_text=text_numbers,
            )

        s = support
        if data.get("radius_m") is None:
            raise InputError(
                f"{prefix}radius_m",
                None,
                f"required; in [{s.particle_radius_min_m:g}, {s.particle_radius_max_m:g}] m",
            )
        radius = number("radius_m", s.particle_radius_min_m, s.particle_radius_max_m, "m")
        height, speed = data.get("drop_height_m"), data.get("impact_speed_mps")
        if (height is None) == (speed is None):
            raise InputError(
                f"{prefix}drop_height_m/impact_speed_mps",
                {"drop_height_m": height, "impact_speed_mps": speed},
                "give exactly one of the two",
            )
        if height is not None:
            height = number("drop_height_m", s.drop_height_min_m, s.drop_height_max_m, "m")
            speed = math.sqrt(2.0 * support.gravity_mps2 * height)
            if speed <= 0.0:
                raise InputError(
                    f"{prefix}drop_height_m", height, "needs gravity_mps2 > 0 to give a speed"
                )
        else:
            speed = number(
                "impact_speed_mps", s.impact_speed_min_mps, s.impact_speed_max_mps, "m/s"
            )
        if data.get("position_m") is None:
            raise InputError(
                f"{prefix}position_m",
                None,
                f"required; in [0, {support.beam_length_m:g}] m from the hinge",
            )
        position = support.check_position(
            data["position_m"], f"{prefix}position_m", allow_text=text_numbers
        )
        restitution = (
            material.restitution
            if data.get("restitution") is None
            else number("restitution", 0.0, 1.0, "", low_open=True)
        )
        impact_id = check_impact_id(data.get("impact_id"), f"{prefix}impact_id")
        return cls(material, radius, float(speed), position, restitution, height, impact_id)


def check_impact_id(value: object, field: str = "impact_id") -> str:
    """An impact_id as given ("" when absent: the simulator then makes one). It must be a
    printable string of 1..MAX_IMPACT_ID_CHARS characters: 0, false, [] or "" are not ids, and
    a lone surrogate or a control character could not be logged or recorded as it is."""
    if value is None:
        return ""
    allowed = f"must be a printable string of 1..{MAX_IMPACT_ID_CHARS} characters (or left out)"
    if (
        not isinstance(value, str)
        or not 1 <= len(value) <= MAX_IMPACT_ID_CHARS
        or not value.isprintable()
    ):
        raise InputError(field, value, allowed)
    return value


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
    # The tail-beam accelerometer (topic ``vibration``; tail_beam_sim.physics.sensors,
    # docs/physics.md).
    vibration_rate_hz: float = 25600.0
    vibration_block_samples: int = 128
    vibration_noise_density_mps2_rthz: float = 0.002  # white noise, m/s^2 per sqrt(Hz)
    vibration_range_mps2: float = (
        2000.0  # measuring range +-, m/s^2: beyond it the sensor saturates
    )
    vibration_antialias_order: int = 4  # Butterworth low-pass before sampling
    vibration_antialias_cutoff_fraction: float = 0.4  # its cut-off over the sample rate
    vibration_oversample: int = 4  # the beam's response is computed this many times per sample
    # How each IMU sample is made: 0 = the mean over its sample period (a boxcar); N >= 1 = a
    # Butterworth low-pass of order N at imu_antialias_cutoff_fraction x the rate, then the value
    # at the sample instant (a MEMS IMU's digital low-pass filter), the beam's response computed
    # imu_oversample times per sample for it.
    imu_antialias_order: int = 0
    imu_antialias_cutoff_fraction: float = 0.25
    imu_oversample: int = 4
    # The rebound camera also reports where the particle struck (topic ``impact_point``), each
    # coordinate with Gaussian noise of this RMS, m.
    camera_reports_impact_point: bool = False
    impact_point_noise_m: float = 0.01

    @property
    def vibration_noise_mps2(self) -> float:
        """RMS noise of one accelerometer sample, m/s^2: the density over the anti-alias
        filter's pass band (cut-off x sample rate)."""
        bandwidth_hz = self.vibration_antialias_cutoff_fraction * self.vibration_rate_hz
        return self.vibration_noise_density_mps2_rthz * math.sqrt(bandwidth_hz)

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
            vibration_noise_density_mps2_rthz=self.vibration_noise_density_mps2_rthz * factor,
            imu_gyro_noise_radps=self.imu_gyro_noise_radps * factor,
            camera_velocity_noise_mps=self.camera_velocity_noise_mps * factor,
            camera_velocity_noise_fraction=self.camera_velocity_noise_fraction * factor,
            impact_point_noise_m=self.impact_point_noise_m * factor,
        )

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> SensorSpec:
        """Build and validate the sensors from the ``sensors`` parameter section."""
        if not isinstance(params, Mapping):
            raise InputError("sensors", params, "missing parameter section")

        return cls(**SENSORS.check(params))


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
    def from_params(
        cls, params: Mapping[str, Any], overrides: Mapping[str, Any] | None = None
    ) -> Scene:
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
        impact = Impact.from_mapping(
            {k: scene_params.get(k) for k in IMPACT_FIELDS if k in scene_params},
            materials,
            support,
            text_numbers=True,
        )
        # Named without the section: these values may come from a command line.
        scene = SCENE.check(
            scene_params, where="", only=("contact_model", "window_s", "pre_contact_s")
        )
        return cls(
            support=support,
            impact=impact,
            sensors=SensorSpec.from_params(sensor_params),
            materials=materials,
            **scene,
        )
