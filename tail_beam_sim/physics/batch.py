"""Many impacts at once, vectorised with numpy: summaries and full sensor streams for data sets.

Each impact's contact comes from the pre-integrated pulse table (interpolated in chi for every
impact at once): duration, peak force and the relative restitution the contact law delivers,
so the impulse J = mu (1 + e) v. Summaries take the structure's response to J as an impulse
(the peak jack pressure is the rigid mode's, which sees any 0.1-1 ms pulse as one). Streams
feed each mode the pulse's own spectrum at that mode (:func:`pulse_spectrum`), so that bending
modes as fast as the contact ring after it exactly as the pulse leaves them. Both evaluate the
structure in closed form on its eigenvalues; the response is linear in J and in the contact
shape, so the per-impact work is a handful of array operations and one small complex matrix
product per signal.

What the batch leaves out: re-contacts (flagged in ``recontact_possible``, by the same bound on
the plate's speed as the hybrid solver uses: re-run those with ``simulate``) and the crushing
contact. Its summaries agree with the hybrid solver within the impulse tier's error estimate.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.contact import damping_factor, effective_modulus_pa, hertz_constant
from tail_beam_sim.physics.materials import Material, sphere_mass_kg
from tail_beam_sim.physics.scene import Impact, SensorSpec
from tail_beam_sim.physics.sensors import SensorNoise
from tail_beam_sim.physics.solvers.pulse import SERIES_RADIUS, pulse_table
from tail_beam_sim.physics.structure import LinearStructure, reduced_mass_kg
from tail_beam_sim.physics.support import Support

POSITION_STATIONS = (
    257  # positions tabulated along the impact zone (linear interpolation, 1e-5 of smooth shapes)
)
PEAK_TIME_SAMPLES = (
    4000  # samples of the unit pressure response over the window (12.5 us at 0.05 s)
)


@dataclass(frozen=True)
class ImpactBatch:
    """N impacts as arrays (SI): particle mass (kg), Hertz constant (N/m^1.5), restitution,
    approach speed (m/s), position along the plate (m), and each impact's material name."""

    mass_kg: np.ndarray
    hertz_stiffness: np.ndarray
    restitution: np.ndarray
    impact_speed_mps: np.ndarray
    position_m: np.ndarray
    material: np.ndarray

    @property
    def size(self) -> int:
        return int(self.mass_kg.size)

    @classmethod
    def from_arrays(
        cls,
        support: Support,
        materials: Mapping[str, Material],
        material: Sequence[str] | np.ndarray,
        radius_m: np.ndarray,
        impact_speed_mps: np.ndarray,
        position_m: np.ndarray,
        restitution: np.ndarray | None = None,
    ) -> ImpactBatch:
        """Validated batch (InputError names the field and the first bad impact)."""
        names = np.asarray(material)
        radius = np.asarray(radius_m, dtype=float)
        speed = np.asarray(impact_speed_mps, dtype=float)
        position = np.asarray(position_m, dtype=float)
        unknown = sorted(set(names.tolist()) - set(materials))
        if unknown:
            raise InputError(
                "material", unknown[0], f"must be one of {', '.join(sorted(materials))}"
            )
        density = (
            np.array([materials[m].density_kgpm3 for m in names.tolist()])
            if names.size
            else np.empty(0)
        )
        modulus = (
            np.array([effective_modulus_pa(materials[m], support.plate) for m in names.tolist()])
            if names.size
            else np.empty(0)
        )
        nominal = (
            np.array([materials[m].restitution for m in names.tolist()])
            if names.size
            else np.empty(0)
        )
        e = nominal if restitution is None else np.asarray(restitution, dtype=float)
        for field, values, low, high in (
            ("radius_m", radius, 0.0, 0.5),
            ("impact_speed_mps", speed, 0.0, 30.0),
            ("position_m", position, -1e-12, support.beam_length_m),
            ("restitution", e, 0.0, 1.0),
        ):
            bad = np.nonzero(~((values > low) & (values <= high)))[0]
            if bad.size:
                raise InputError(
                    f"{field}[{bad[0]}]",
                    float(values[bad[0]]),
                    f"must be in ({max(low, 0):g}, {high:g}]",
                )
        return cls(
            mass_kg=sphere_mass_kg(density, radius),
            hertz_stiffness=hertz_constant(modulus, radius),
            restitution=e,
            impact_speed_mps=speed,
            position_m=position,
            material=names,
        )

    @classmethod
    def from_impacts(
        cls, support: Support, materials: Mapping[str, Material], impacts: Sequence[Impact]
    ) -> ImpactBatch:
        """A batch of already validated impacts."""
        return cls.from_arrays(
            support,
            materials,
            [i.material.name for i in impacts],
            np.array([i.radius_m for i in impacts]),
            np.array([i.impact_speed_mps for i in impacts]),
            np.array([i.position_m for i in impacts]),
            np.array([i.restitution for i in impacts]),
        )


@dataclass(frozen=True)
class Contacts:
    """The contact of every impact of a batch (arrays over impacts)."""

    chi: np.ndarray
    reduced_mass_kg: np.ndarray
    duration_s: np.ndarray
    peak_force_n: np.ndarray
    relative_restitution: np.ndarray
    impulse_ns: np.ndarray
    rebound_mps: np.ndarray
    table_row: np.ndarray
    table_weight: np.ndarray


def contacts(
    structure: LinearStructure,
    batch: ImpactBatch,
    contact_model: str = "calibrated",
    positions: PositionTable | None = None,
    damping_scale: float = 1.0,
) -> Contacts:
    """Every impact's contact from the pulse table's per-chi figures, vectorised
    (``damping_scale``:
    the support's contact_damping_scale)."""
    table = pulse_table()
    # chi of every impact by one impact's own formulas (contact.damping_factor), times the
    # support's scale.
    chi = damping_factor(contact_model, np.asarray(batch.restitution, dtype=float), damping_scale)
    if np.any(chi > table.chi[-1]):
        raise InputError(
            "restitution",
            float(batch.restitution[np.argmax(chi)]),
            f"too low for {contact_model}: chi beyond {table.chi[-1]:g}",
        )
    i = np.clip(np.searchsorted(table.chi, chi, side="right") - 1, 0, table.chi.size - 2)
    w = (chi - table.chi[i]) / (table.chi[i + 1] - table.chi[i])

    def blend(values: np.ndarray) -> np.ndarray:
        return (1 - w) * values[i] + w * values[i + 1]

    positions = positions or PositionTable(structure, batch.position_m)
    reduced = reduced_mass_kg(batch.mass_kg, positions.compliance(batch.position_m))
    speed = batch.impact_speed_mps
    length = (reduced * speed**2 / batch.hertz_stiffness) ** 0.4
    duration = blend(table.duration) * length / speed
    relative = blend(table.restitution)
    impulse = reduced * (1 + relative) * speed
    return Contacts(
        chi=chi,
        reduced_mass_kg=reduced,
        duration_s=duration,
        peak_force_n=blend(table.peak_force) * batch.hertz_stiffness * length**1.5,
        relative_restitution=relative,
        impulse_ns=impulse,
        rebound_mps=impulse / batch.mass_kg - speed,
        table_row=i,
        table_weight=w,
    )


class PositionTable:
    """What depends on the impact position only, tabulated along the plate and interpolated:
    contact shape (m per unit q) and compliance at the contact point (1/kg, the inverse of its
    effective mass); on demand, the peak jack pressure change (Pa) and a bound on the plate's later
    speed (m/s), both per unit impulse (N s), the peak read off a fine time grid over the
    window."""

    def __init__(
        self, structure: LinearStructure, position_m: np.ndarray, window_s: float = 0.05
    ) -> None:
        low, high = (
            (float(position_m.min()), float(position_m.max())) if position_m.size else (0.0, 0.0)
        )
        self.stations_m = (
            np.linspace(low, high, POSITION_STATIONS)
            if high > low
            else np.array([low, low + 1e-9])
        )
        self.shapes = np.array([structure.contact_shape(float(x)) for x in self.stations_m])
        self.compliance_per_kg = np.einsum(
            "si,ij,sj->s", self.shapes, structure.inv_mass, self.shapes
        )  # 1/effective mass
        self.structure, self.window_s = structure, window_s

    @cached_property
    def _unit_modal(self) -> np.ndarray:
        """(S, 2n): modal amplitudes of the state [0, M^-1 b] per unit impulse at each station."""
        return self.shapes @ self.structure.modal_input.T

    @cached_property
    def peak_pressure_per_impulse(self) -> np.ndarray:
        structure = self.structure
        eigenvalues, vectors, _ = structure._eigen
        n = structure.size
        times = np.linspace(0.0, self.window_s, PEAK_TIME_SAMPLES)
        jack = structure.jack_stiffness_npm * (
            structure.jack_shape @ vectors[:n]
        ) + structure.jack_damping_nspm * (structure.jack_shape @ vectors[n:])
        pressure = (
            (self._unit_modal * jack) @ np.exp(np.outer(eigenvalues, times))
        ).real / structure.piston_area_m2
        return pressure.max(axis=1)

    @cached_property
    def plate_speed_per_impulse(self) -> np.ndarray:
        vectors = self.structure._eigen[1]
        return np.abs(self._unit_modal * (self.shapes @ vectors[self.structure.size :])).sum(
            axis=1
        )

    def _at(self, values: np.ndarray, position_m: np.ndarray) -> np.ndarray:
        return np.interp(position_m, self.stations_m, values)

    def compliance(self, position_m: np.ndarray) -> np.ndarray:
        """b^T M^-1 b at each position, 1/kg (0 over the hinge)."""
        return self._at(self.compliance_per_kg, position_m)

    def shape(self, position_m: np.ndarray) -> np.ndarray:
        return np.stack(
            [self._at(self.shapes[:, j], position_m) for j in range(self.shapes.shape[1])], axis=1
        )


def pulse_spectrum(c: Contacts, eigenvalues: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """(N, 2n): int F(s) e^{-lambda_k s} ds / int F(s) ds over each impact's pulse (s from contact
    start). A mode fed this instead of the bare impulse J rings after the contact exactly as the
    pulse leaves it (1 for slow modes, less for modes as fast as the contact). The power series
    over the table's moments (Horner) where |lambda T| <= SERIES_RADIUS, the quadrature beyond."""
    table = pulse_table()
    rows, w = c.table_row, c.table_weight[:, None]
    coefficients = (1 - w) * table.moments[rows] + w * table.moments[rows + 1]  # (N, moments)
    mu = np.outer(c.duration_s, eigenvalues)
    total = coefficients[:, -1:].astype(complex)
    for m in range(coefficients.shape[1] - 2, -1, -1):
        total = total * -mu + coefficients[:, m : m + 1]
    out = total / coefficients[:, :1]
    far = np.nonzero(np.abs(mu).max(axis=1) > SERIES_RADIUS)[0]
    for start in range(0, far.size, chunk):
        k = far[start : start + chunk]
        force = (1 - w[k]) * table.rows[rows[k], 2] + w[k] * table.rows[rows[k] + 1, 2]
        times = c.duration_s[k, None] * table.fractions[None, :]
        phase = np.exp(-eigenvalues[None, :, None] * times[:, None, :])
        out[k] = np.einsum("nj,nkj->nk", force, phase) / force.sum(axis=1)[:, None]
    return out


def _modal_start(
    structure: LinearStructure, shapes: np.ndarray, impulse: np.ndarray
) -> np.ndarray:
    """Modal amplitudes (N, 2n) of the state [0, M^-1 b J] just after each impulse."""
    return shapes @ structure.modal_input.T * impulse[:, None]


def summaries(
    support: Support,
    structure: LinearStructure,
    batch: ImpactBatch,
    contact_model: str = "calibrated",
    window_s: float = 0.05,
) -> dict[str, np.ndarray]:
    """Rebound, restitution, contact duration and peak force, peak jack pressure change (Pa)
    and whether a re-contact may follow, for every impact (arrays over impacts)."""
    positions = PositionTable(structure, batch.position_m, window_s)
    c = contacts(structure, batch, contact_model, positions, support.contact_damping_scale)
    x = batch.position_m
    plate_speed = c.impulse_ns * positions._at(positions.plate_speed_per_impulse, x)
    rebound = np.maximum(c.rebound_mps, 0.0)
    return {
        "rebound_speed_mps": rebound,
        "restitution": rebound / batch.impact_speed_mps,
        "contact_duration_s": c.duration_s,
        "peak_contact_force_n": c.peak_force_n,
        "peak_jack_pressure_change_pa": c.impulse_ns
        * positions._at(positions.peak_pressure_per_impulse, x),
        "recontact_possible": c.rebound_mps - plate_speed <= 0.5 * support.gravity_mps2 * window_s,
    }


def streams(
    support: Support,
    structure: LinearStructure,
    batch: ImpactBatch,
    sensors: SensorSpec,
    contact_model: str = "calibrated",
    window_s: float = 0.05,
    seed: int = 0,
) -> dict[str, np.ndarray]:
    """Noisy sensor streams of every impact over ``window_s`` after its contact (arrays (N, T)).

    Each impact's contact falls at a seeded instant ``contact_offset_s`` (N,) within one sample
    period after its clock's zero, as in ``simulate``; samples are taken at k / rate, k >= 0.
    Keys: ``pressure_pa`` (N, T), ``imu_accel_mps2`` and ``imu_gyro_radps`` (N, T, 3, each the
    mean over the period before its stamp), ``pressure_time_s`` and ``imu_time_s`` (T,).
    """
    rng = np.random.default_rng(seed)
    positions = PositionTable(structure, batch.position_m, window_s)
    c = contacts(structure, batch, contact_model, positions, support.contact_damping_scale)
    shapes = positions.shape(batch.position_m)
    eigenvalues, vectors, _ = structure._eigen
    n = structure.size
    modal = _modal_start(structure, shapes, c.impulse_ns)
    slowest_period = 1.0 / min(sensors.pressure_rate_hz, sensors.imu_rate_hz)
    offset = rng.uniform(0.0, slowest_period, batch.size)
    contact_end = offset + c.duration_s
    shifted = (
        modal * pulse_spectrum(c, eigenvalues) * np.exp(np.outer(-offset, eigenvalues))
    )  # (N, 2n): each impact's own clock

    def rows(weights: np.ndarray, times: np.ndarray) -> np.ndarray:
        """sum_k weights_k x_k(t) of every impact at ``times``, (N, T): exact after its contact,
        zero before it, and during it (0.1-1 ms) the response as if the contact had ended."""
        values = ((shifted * weights) @ np.exp(np.outer(eigenvalues, times))).real
        return values * (times[None, :] >= contact_end[:, None] - c.duration_s[:, None])

    out: dict[str, np.ndarray] = {"contact_offset_s": offset}
    times = np.arange(int(round(window_s * sensors.pressure_rate_hz))) / sensors.pressure_rate_hz
    jack = structure.jack_stiffness_npm * (
        structure.jack_shape @ vectors[:n]
    ) + structure.jack_damping_nspm * (structure.jack_shape @ vectors[n:])
    pressure = structure.setting_pressure_pa + rows(jack, times) / structure.piston_area_m2
    # noise drawn in float32 (ample for sensor noise, about twice as fast to draw)
    noise = SensorNoise.of(sensors)
    out["pressure_pa"] = noise.pressure(
        pressure, rng.standard_normal(pressure.shape, dtype=np.float32)
    )
    out["pressure_time_s"] = times
    rate = sensors.imu_rate_hz
    times = (
        np.arange(-1, int(round(window_s * rate))) / rate
    )  # one extra sample: each reading averages the period before it
    angle = rows(structure.imu_slope_shape @ vectors[:n], times)
    velocity = rows(structure.imu_shape @ vectors[n:], times)
    angular_rate = rows(structure.imu_slope_shape @ vectors[n:], times[1:])
    g = structure.gravity_mps2
    accel = np.zeros((batch.size, times.size - 1, 3))
    gyro = np.zeros_like(accel)
    gyro[:, :, 1] = np.diff(angle, axis=1) * rate
    accel[:, :, 0] = -structure.imu_from_hinge_m * angular_rate**2 - g * np.sin(angle[:, 1:])
    accel[:, :, 2] = g * np.cos(angle[:, 1:]) - np.diff(velocity, axis=1) * rate
    accel = noise.accel(accel, rng.standard_normal(accel.shape, dtype=np.float32))
    gyro = noise.gyro(gyro, rng.standard_normal(gyro.shape, dtype=np.float32))
    out["imu_accel_mps2"], out["imu_gyro_radps"], out["imu_time_s"] = accel, gyro, times[1:]
    return out
