"""Energy budget of one sphere-on-plate impact: where a falling particle's kinetic energy can go
besides the contact's hysteresis, and how much each place can take at most.

It answers one question about the seed study (docs/physics.md, "The radius series: an energy
budget"): can a mechanism of the real support take the energy that separates the suite's
restitution (0.68 at every radius) from the study's finite-element one (0.676, 0.474, 0.427,
0.333 at R = 25, 30, 35, 40 mm)? Mechanisms, each with the most it can take:

* plate (flexural) waves radiated from the contact into the top plate, treated as infinite:
  Zener (1941), "The intrinsic inelasticity of large plates", Phys. Rev. 59:669, and Hunter
  (1957), J. Mech. Phys. Solids 5:162. A thin infinite plate answers a point force F with the
  velocity F / (8 sqrt(D rho h)) at the load point (Cremer & Heckl, "Structure-Borne Sound",
  point mobility of an infinite plate), i.e. it is a dashpot in series with the Hertz spring.
  :func:`sphere_on_plate` integrates that model with the suite's hysteresis law; in Zener's
  units (penetration over (m v^2/K)^(2/5), time over that length / v) its one parameter is
  Zener's lambda (:func:`zener_parameter`, closed form :func:`zener_parameter_of`);
* local flexure of the top plate between the ribs: a clamped circular panel under a central
  point force is a spring of stiffness 16 pi D / a^2 (Timoshenko & Woinowsky-Krieger, "Theory
  of Plates and Shells", clamped circular plate, central load). It holds F_peak^2 / (2 k) at
  the peak force and gives it back when the contact is slower than the panel;
* the panel's own (fundamental) mode, 10.216 / a^2 sqrt(D / (rho h)) rad/s (Leissa, "Vibration
  of Plates", NASA SP-160, clamped circular plate): the pulse leaves |F^(omega_1)|^2 / (2 M_1)
  in it, never more than J^2 / (2 M_1) (J the contact's impulse);
* crushing of the coal at the contact (Johnson, "Contact Mechanics", ch. 11 on plastic impact;
  Thornton 1997, as in :class:`tail_beam_sim.physics.contact.CrushingContact`): on a rigid wall
  it leaves the rebound energy ratio the crushing law gives.

Energies are in J, forces N, lengths m, times s. Gravity is left out of the contact (it changes
a 0.5 ms contact's rebound by about g t / v, under 0.1 %).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from tail_beam_sim.physics.contact import (
    CrushingContact,
    calibrated_chi,
    effective_modulus_pa,
    hertz_constant,
)
from tail_beam_sim.physics.materials import Material, sphere_mass_kg

# Fundamental eigenvalue lambda^2 of a clamped circular plate: omega_1 = 10.2158 / a^2
# sqrt(D / (rho h)) (Leissa, NASA SP-160, table 2.1).
CLAMPED_CIRCULAR_PLATE_EIGENVALUE = 10.2158
# Zener's lambda = ZENER_PREFACTOR (R/h)^2 (v/c_p)^(1/5) (rho1/rho2)^(3/5) (E*(1-nu2^2)/E2)^(2/5).
ZENER_PREFACTOR = math.pi**0.6 / math.sqrt(3.0)


def plate_bending_stiffness_nm(
    youngs_modulus_pa: float, poisson_ratio: float, thickness_m: float
) -> float:
    """Flexural rigidity D = E h^3 / (12 (1 - nu^2)) of a plate, N m."""
    return youngs_modulus_pa * thickness_m**3 / (12.0 * (1.0 - poisson_ratio**2))


def plate_point_damping_nspm(plate: Material, thickness_m: float) -> float:
    """The dashpot an infinite thin plate is to a point force, 8 sqrt(D rho h), N s/m: the
    inverse of its point mobility (the load point moves at F / (8 sqrt(D rho h)) while the
    flexural waves carry the work away)."""
    rigidity = plate_bending_stiffness_nm(
        plate.youngs_modulus_pa, plate.poisson_ratio, thickness_m
    )
    return 8.0 * math.sqrt(rigidity * plate.density_kgpm3 * thickness_m)


def hertz_scales(mass_kg: float, stiffness: float, speed_mps: float) -> tuple[float, float]:
    """Zener's units of the contact: length (m v^2 / K)^(2/5), m, and that length over v, s."""
    length_m = (mass_kg * speed_mps**2 / stiffness) ** 0.4
    return length_m, length_m / speed_mps


def zener_parameter(
    mass_kg: float, stiffness: float, speed_mps: float, plate_damping_nspm: float
) -> float:
    """Zener's inelasticity parameter lambda = m / (c t0), dimensionless: the plate's dashpot
    time m / c over the contact's time unit t0 (0 for a rigid plate)."""
    _, time_s = hertz_scales(mass_kg, stiffness, speed_mps)
    return mass_kg / (plate_damping_nspm * time_s)


def zener_parameter_of(
    particle: Material, plate: Material, radius_m: float, thickness_m: float, speed_mps: float
) -> float:
    """Zener's lambda in his closed form, pi^(3/5)/sqrt(3) (R/h)^2 (v/c_p)^(1/5)
    (rho1/rho2)^(3/5) (E* (1 - nu2^2) / E2)^(2/5), with c_p = sqrt(E2 / (rho2 (1 - nu2^2))) the
    plate's longitudinal wave speed: grows as R^2 / h^2 and barely with the speed."""
    plate_speed_mps = math.sqrt(
        plate.youngs_modulus_pa / (plate.density_kgpm3 * (1.0 - plate.poisson_ratio**2))
    )
    modulus_ratio = (
        effective_modulus_pa(particle, plate)
        * (1.0 - plate.poisson_ratio**2)
        / plate.youngs_modulus_pa
    )
    return (
        ZENER_PREFACTOR
        * (radius_m / thickness_m) ** 2
        * (speed_mps / plate_speed_mps) ** 0.2
        * (particle.density_kgpm3 / plate.density_kgpm3) ** 0.6
        * modulus_ratio**0.4
    )


@dataclass(frozen=True)
class ImpactEnergies:
    """One sphere-on-plate impact: the rebound and where the impact energy went, J.

    ``impact_energy_j`` = ``rebound_energy_j`` + ``contact_dissipated_j`` (the hysteresis law)
    + ``plate_radiated_j`` (flexural waves), to the integration's tolerance. ``spectrum_ns`` is
    the contact force's Fourier transform |F^(omega)|, N s, at the probe frequencies asked for.
    """

    restitution: float
    impact_energy_j: float
    rebound_energy_j: float
    contact_dissipated_j: float
    plate_radiated_j: float
    peak_force_n: float
    duration_s: float
    impulse_ns: float
    spectrum_ns: tuple[float, ...]


def sphere_on_plate(
    mass_kg: float,
    stiffness: float,
    speed_mps: float,
    chi: float = 0.0,
    plate_damping_nspm: float = math.inf,
    probe_angular_frequencies_radps: Sequence[float] = (),
) -> ImpactEnergies:
    """A sphere of ``mass_kg`` meeting a plate at ``speed_mps`` through the contact
    F = K delta^1.5 (1 + chi delta' / v), never pulling, the plate's load point a dashpot
    (``plate_damping_nspm``; inf: a rigid plate, the suite's contact on a rigid wall).

    Integrated in Zener's units (u = delta / l0, s = t / t0): x'' = -f, w' = lambda f,
    f = u^1.5 (1 + chi (x' - w')), solved for f in closed form, until the penetration returns
    to zero. The energies are integrated alongside (f times the contact's rate, lambda f^2),
    so that their sum checks the integration.
    """
    length_m, time_s = hertz_scales(mass_kg, stiffness, speed_mps)
    lam = 0.0 if math.isinf(plate_damping_nspm) else mass_kg / (plate_damping_nspm * time_s)
    omegas = np.asarray(probe_angular_frequencies_radps, dtype=float) * time_s

    def force(u: float, v: float) -> float:
        load = max(u, 0.0) ** 1.5
        return max(0.0, load * (1.0 + chi * v) / (1.0 + chi * lam * load))

    def rates(s: float, y: np.ndarray) -> np.ndarray:
        # y = [x, x', w, contact work, plate work, the force's Fourier integrals (cos, sin)]
        f = force(y[0] - y[2], y[1])
        plate_rate = lam * f
        phase = omegas * s
        return np.concatenate(
            (
                [y[1], -f, plate_rate, f * (y[1] - plate_rate), plate_rate * f],
                f * np.cos(phase),
                -f * np.sin(phase),
            )
        )

    def separated(s: float, y: np.ndarray) -> float:
        return y[0] - y[2]

    separated.terminal = True
    separated.direction = -1.0
    start = np.zeros(5 + 2 * omegas.size)
    start[1] = 1.0
    solution = solve_ivp(
        rates,
        (0.0, 400.0),
        start,
        method="DOP853",
        rtol=1e-10,
        atol=1e-12,
        events=separated,
        dense_output=True,
    )
    if solution.status != 1:
        raise RuntimeError(f"the contact did not end within 400 time units ({solution.message})")
    end = solution.y[:, -1]
    grid = np.linspace(0.0, solution.t[-1], 2001)
    states = solution.sol(grid)
    peak = max(force(u, v) for u, v in zip(states[0] - states[2], states[1]))
    energy_unit_j = mass_kg * speed_mps**2
    n = omegas.size
    spectrum = np.hypot(end[5 : 5 + n], end[5 + n :]) * mass_kg * speed_mps
    return ImpactEnergies(
        restitution=float(-end[1]),
        impact_energy_j=0.5 * energy_unit_j,
        rebound_energy_j=0.5 * energy_unit_j * end[1] ** 2,
        contact_dissipated_j=energy_unit_j * end[3],
        plate_radiated_j=energy_unit_j * end[4],
        peak_force_n=peak * mass_kg * length_m / time_s**2,
        duration_s=solution.t[-1] * time_s,
        impulse_ns=mass_kg * speed_mps * (1.0 - end[1]),
        spectrum_ns=tuple(float(a) for a in spectrum),
    )


def panel_stiffness_npm(plate: Material, thickness_m: float, panel_radius_m: float) -> float:
    """Central-point-load stiffness 16 pi D / a^2 of a clamped circular panel of radius a, N/m."""
    rigidity = plate_bending_stiffness_nm(
        plate.youngs_modulus_pa, plate.poisson_ratio, thickness_m
    )
    return 16.0 * math.pi * rigidity / panel_radius_m**2


def panel_mode(plate: Material, thickness_m: float, panel_radius_m: float) -> tuple[float, float]:
    """The clamped circular panel's fundamental mode: (angular frequency, rad/s; modal mass at
    the centre, kg). The modal mass is the central stiffness over omega^2, so that the mode alone
    reproduces the panel's static compliance under the load."""
    rigidity = plate_bending_stiffness_nm(
        plate.youngs_modulus_pa, plate.poisson_ratio, thickness_m
    )
    omega = (
        CLAMPED_CIRCULAR_PLATE_EIGENVALUE
        / panel_radius_m**2
        * math.sqrt(rigidity / (plate.density_kgpm3 * thickness_m))
    )
    return omega, panel_stiffness_npm(plate, thickness_m, panel_radius_m) / omega**2


@dataclass(frozen=True)
class RadiusBudget:
    """The energy budget at one radius, J: what the study's restitution asks the sphere to lose
    beyond the suite's, and the most each mechanism of the support can take."""

    radius_m: float
    suite_restitution: float
    study_restitution: float
    impact_energy_j: float
    to_remove_j: float
    plate_waves_j: float
    restitution_with_plate_waves: float
    zener_lambda: float
    panel_flexure_stored_j: float
    panel_mode_j: float
    panel_mode_bound_j: float
    crushing_j: float
    crushing_restitution: float
    thickness_for_study_m: float


def energy_to_remove_j(
    mass_kg: float, speed_mps: float, suite_restitution: float, study_restitution: float
) -> float:
    """Kinetic energy the sphere must lose beyond the suite's for the study's restitution:
    (e_suite^2 - e_study^2) m v^2 / 2, J."""
    return 0.5 * mass_kg * speed_mps**2 * (suite_restitution**2 - study_restitution**2)


def thickness_for_restitution_m(
    particle: Material,
    plate: Material,
    radius_m: float,
    speed_mps: float,
    chi: float,
    restitution: float,
) -> float:
    """The plate thickness at which plate waves plus the suite's hysteresis ``chi`` deliver
    ``restitution``, m (nan if none between 4 mm and 1 m)."""
    mass = sphere_mass_kg(particle.density_kgpm3, radius_m)
    stiffness = hertz_constant(effective_modulus_pa(particle, plate), radius_m)

    def miss(thickness_m: float) -> float:
        damping = plate_point_damping_nspm(plate, thickness_m)
        return sphere_on_plate(mass, stiffness, speed_mps, chi, damping).restitution - restitution

    low, high = 4e-3, 1.0
    if miss(low) * miss(high) > 0.0:
        return math.nan
    return brentq(miss, low, high, xtol=1e-6)


def radius_budget(
    particle: Material,
    plate: Material,
    radius_m: float,
    speed_mps: float,
    suite_restitution: float,
    study_restitution: float,
    thickness_m: float,
    panel_radius_m: float,
    crushing_pressure_pa: float,
) -> RadiusBudget:
    """The energy budget of a ``particle`` sphere of ``radius_m`` on the support's top plate.

    The suite's loss is its calibrated hysteresis (chi delivering ``suite_restitution`` on a
    rigid wall); each mechanism is measured on top of it: plate waves by integrating both
    together, the panel from that contact's force, crushing as the rebound energy it would
    leave instead of the hysteresis (the energy beyond the suite's; never below 0).
    """
    mass = sphere_mass_kg(particle.density_kgpm3, radius_m)
    stiffness = hertz_constant(effective_modulus_pa(particle, plate), radius_m)
    chi = calibrated_chi(suite_restitution)
    omega, modal_mass = panel_mode(plate, thickness_m, panel_radius_m)
    wall = sphere_on_plate(
        mass, stiffness, speed_mps, chi, probe_angular_frequencies_radps=[omega]
    )
    damping = plate_point_damping_nspm(plate, thickness_m)
    waves = sphere_on_plate(mass, stiffness, speed_mps, chi, damping)
    crushing = CrushingContact(
        effective_modulus_pa(particle, plate), radius_m, crushing_pressure_pa
    )
    crushed_ratio = crushing.rebound_energy_ratio(wall.impact_energy_j)
    return RadiusBudget(
        radius_m=radius_m,
        suite_restitution=suite_restitution,
        study_restitution=study_restitution,
        impact_energy_j=wall.impact_energy_j,
        to_remove_j=energy_to_remove_j(mass, speed_mps, suite_restitution, study_restitution),
        plate_waves_j=waves.plate_radiated_j,
        restitution_with_plate_waves=waves.restitution,
        zener_lambda=zener_parameter(mass, stiffness, speed_mps, damping),
        panel_flexure_stored_j=wall.peak_force_n**2
        / (2.0 * panel_stiffness_npm(plate, thickness_m, panel_radius_m)),
        panel_mode_j=wall.spectrum_ns[0] ** 2 / (2.0 * modal_mass),
        panel_mode_bound_j=wall.impulse_ns**2 / (2.0 * modal_mass),
        crushing_j=max(0.0, (suite_restitution**2 - crushed_ratio) * wall.impact_energy_j),
        crushing_restitution=math.sqrt(crushed_ratio),
        thickness_for_study_m=thickness_for_restitution_m(
            particle, plate, radius_m, speed_mps, chi, study_restitution
        ),
    )
