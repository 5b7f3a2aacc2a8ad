"""The energy budget of a sphere on the top plate (tail_beam_sim.physics.energy_budget) against
references independent of its integrator: Zener's plate model in its limits, Hertz's closed
form, the energy balance, and the study's radius series it is built to weigh."""

from __future__ import annotations

import math

import pytest
from scipy.special import beta

from tail_beam_sim.config import load_parameters
from tail_beam_sim.physics.contact import (
    CrushingContact,
    calibrated_chi,
    effective_modulus_pa,
    hertz_constant,
    hertz_elastic_impact,
)
from tail_beam_sim.physics.energy_budget import (
    panel_mode,
    panel_stiffness_npm,
    plate_point_damping_nspm,
    radius_budget,
    sphere_on_plate,
    zener_parameter,
    zener_parameter_of,
)
from tail_beam_sim.physics.materials import Material, sphere_mass_kg

STUDY_SPEED_MPS = 8.368


@pytest.fixture(scope="module")
def materials() -> dict[str, Material]:
    """The shipped materials, by name."""
    table = load_parameters()["materials"]
    return {name: Material.from_params(name, table[name]) for name in table}


def test_small_zener_lambda_loses_energy_at_the_first_order_rate():
    """Small lambda: 1 - e^2 = 1.6 (5/4)^(8/5) B(8/5, 1/2) lambda (Zener's e = 1 - 1.73 lambda),
    the elastic Hertz pulse's integral of F^2 over the plate's dashpot, within 1 %."""
    lam = 1e-3
    result = sphere_on_plate(1.0, 1.0, 1.0, chi=0.0, plate_damping_nspm=1.0 / lam)
    first_order = 1.6 * 1.25**1.6 * beta(1.6, 0.5)
    assert first_order == pytest.approx(3.46, abs=0.01)
    assert (1.0 - result.restitution**2) / lam == pytest.approx(first_order, rel=0.01)


def test_thick_plate_gives_back_the_hertz_and_suite_restitution(materials):
    """A plate thick enough (lambda -> 0) returns the wall's value: e = 1 for Hertz, the calibrated
    law's 0.68 with the suite's hysteresis."""
    coal, steel = materials["coal"], materials["q345_steel"]
    mass = sphere_mass_kg(coal.density_kgpm3, 0.03)
    stiffness = hertz_constant(effective_modulus_pa(coal, steel), 0.03)
    thick = plate_point_damping_nspm(steel, 3.0)
    elastic = sphere_on_plate(mass, stiffness, STUDY_SPEED_MPS, 0.0, thick)
    hysteretic = sphere_on_plate(mass, stiffness, STUDY_SPEED_MPS, calibrated_chi(0.68), thick)
    assert elastic.restitution == pytest.approx(1.0, abs=1e-4)
    assert hysteretic.restitution == pytest.approx(0.68, abs=2e-3)


def test_energy_in_equals_rebound_plus_contact_plus_plate():
    """Kinetic energy in = rebound + hysteresis + plate waves, each integrated on its own, to 1e-8
    of the impact energy, with both losses large (lambda 0.15, e 0.5 on a wall)."""
    result = sphere_on_plate(0.2, 1e9, 8.0, calibrated_chi(0.5), plate_damping_nspm=1.5e4)
    assert result.plate_radiated_j > 0.1 * result.impact_energy_j
    assert result.contact_dissipated_j > 0.1 * result.impact_energy_j
    total = result.rebound_energy_j + result.contact_dissipated_j + result.plate_radiated_j
    assert total == pytest.approx(result.impact_energy_j, rel=1e-8)
    assert result.impact_energy_j == pytest.approx(0.5 * 0.2 * 64.0)


def test_rigid_wall_contact_is_the_hertz_closed_form():
    """No hysteresis, rigid plate: peak force and duration are Hertz's closed form (to 1e-3) and
    the spectrum at zero frequency is the impulse 2 m v (units: N s)."""
    mass, stiffness, speed = 0.15, 8.7e8, 8.368
    result = sphere_on_plate(mass, stiffness, speed, probe_angular_frequencies_radps=[1e-3])
    closed = hertz_elastic_impact(stiffness, mass, speed)
    assert result.peak_force_n == pytest.approx(closed["peak_force_n"], rel=1e-3)
    assert result.duration_s == pytest.approx(closed["duration_s"], rel=1e-3)
    assert result.spectrum_ns[0] == pytest.approx(2.0 * mass * speed, rel=1e-6)
    assert result.impulse_ns == pytest.approx(2.0 * mass * speed, rel=1e-6)


def test_zener_lambda_closed_form_matches_the_plate_dashpot(materials):
    """Zener's closed form of lambda equals m / (8 sqrt(D rho h) t0) computed in SI units, and
    grows as (R / h)^2."""
    coal, steel = materials["coal"], materials["q345_steel"]
    for radius_m, thickness_m in ((0.03, 0.03), (0.04, 0.012), (0.1, 0.05)):
        mass = sphere_mass_kg(coal.density_kgpm3, radius_m)
        stiffness = hertz_constant(effective_modulus_pa(coal, steel), radius_m)
        dashpot = plate_point_damping_nspm(steel, thickness_m)
        assert zener_parameter(mass, stiffness, STUDY_SPEED_MPS, dashpot) == pytest.approx(
            zener_parameter_of(coal, steel, radius_m, thickness_m, STUDY_SPEED_MPS), rel=1e-12
        )
    ratio = zener_parameter_of(coal, steel, 0.04, 0.03, 8.0) / zener_parameter_of(
        coal, steel, 0.02, 0.03, 8.0
    )
    assert ratio == pytest.approx(4.0, rel=1e-12)


def test_panel_mode_is_the_clamped_plate_fundamental(materials):
    """A 30 mm steel panel clamped on a 0.25 m radius rings at 1210 Hz (10.2158 / a^2
    sqrt(D / rho h)), with a modal mass of 0.153 times the panel's (16 pi / 10.2158^2 / pi)."""
    steel = materials["q345_steel"]
    omega, modal_mass = panel_mode(steel, 0.03, 0.25)
    assert omega / (2.0 * math.pi) == pytest.approx(1210.0, rel=2e-3)
    panel_mass = steel.density_kgpm3 * 0.03 * math.pi * 0.25**2
    assert modal_mass / panel_mass == pytest.approx(16.0 / 10.2158**2, rel=1e-9)
    assert panel_stiffness_npm(steel, 0.03, 0.25) == pytest.approx(modal_mass * omega**2)


def test_crushing_leaves_the_same_restitution_at_every_radius(materials):
    """Crushing coal (Thornton, 3 x 20 MPa) on a rigid wall: the same restitution at 25 and 40 mm
    (its yield speed does not depend on the size), lower at a higher speed: not the study's
    radius series, whose restitution falls with the radius and barely with the speed."""
    coal, steel = materials["coal"], materials["q345_steel"]

    def restitution(radius_m: float, speed_mps: float) -> float:
        contact = CrushingContact(effective_modulus_pa(coal, steel), radius_m, 60e6)
        energy = 0.5 * sphere_mass_kg(coal.density_kgpm3, radius_m) * speed_mps**2
        return math.sqrt(contact.rebound_energy_ratio(energy))

    assert restitution(0.025, STUDY_SPEED_MPS) == pytest.approx(
        restitution(0.04, STUDY_SPEED_MPS), rel=1e-9
    )
    assert restitution(0.025, 6.261) > restitution(0.025, 8.854) + 0.02


def test_no_elastic_mechanism_of_the_support_takes_the_series_energy(materials):
    """30 and 40 mm coal at 8.368 m/s on the 30 mm plate: plate waves, the panel's stored flexure
    and the bound on its mode each take under 45 % of the energy the study's restitution asks;
    plate waves would need a plate under 9 mm."""
    coal, steel = materials["coal"], materials["q345_steel"]
    for radius_m, study in ((0.03, 0.474), (0.04, 0.333)):
        row = radius_budget(coal, steel, radius_m, STUDY_SPEED_MPS, 0.68, study, 0.03, 0.25, 60e6)
        assert row.to_remove_j == pytest.approx(
            0.5 * sphere_mass_kg(coal.density_kgpm3, radius_m) * STUDY_SPEED_MPS**2
            * (0.68**2 - study**2)
        )
        for taken in (row.plate_waves_j, row.panel_flexure_stored_j, row.panel_mode_bound_j):
            assert taken < 0.45 * row.to_remove_j
        assert row.panel_mode_j <= row.panel_mode_bound_j
        assert row.restitution_with_plate_waves > study + 0.15
        assert 0.006 < row.thickness_for_study_m < 0.009
