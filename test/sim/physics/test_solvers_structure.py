"""The beam with bending modes: the finite-element generator, the shipped table, the coupled
model."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from scipy.linalg import eigh

from tail_beam_sim.config import deep_merge, load_parameters
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.fidelity import shipped_settings
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.simulate import simulate
from tail_beam_sim.physics.structure import (
    beam_with_modes,
    euler_bernoulli_modes,
    load_bending_modes,
    rigid_beam,
)


def test_generator_matches_simply_supported_beam_closed_form():
    """Held at both ends, f_k = (k pi / L)^2 sqrt(EI / rho A) / 2 pi (any beam handbook); modal
    mass of sin(k pi x / L) normalised to 1 is rho A L / 2."""
    length, ei, rho_a = 2.0, 1.0e6, 100.0
    modes = euler_bernoulli_modes(length, [0.0, length], ei, rho_a, 3, 40)
    for k, mode in enumerate(modes, start=1):
        expected = (k * math.pi / length) ** 2 * math.sqrt(ei / rho_a) / (2 * math.pi)
        assert mode["frequency_hz"] == pytest.approx(expected, rel=1e-4)
        assert mode["modal_mass_kg"] == pytest.approx(rho_a * length / 2, rel=1e-3)


def test_shipped_modes_are_what_the_documented_beam_gives(params):
    """config/modes.yaml holds the generator's output for the inputs it records (6 digits)."""
    section = params["modes"]
    source = section["derived_from"]
    generated = euler_bernoulli_modes(
        source["beam_length_m"],
        source["held_at_m"],
        source["bending_stiffness_nm2"],
        source["mass_per_length_kgpm"],
        3,
        source["elements"],
    )
    shipped = load_bending_modes(deep_merge(copy.deepcopy(params), {"modes": {"count": 3}}))
    for mode, reference in zip(shipped, generated):
        assert mode.frequency_hz == pytest.approx(reference["frequency_hz"], rel=1e-5)
        assert mode.modal_mass_kg == pytest.approx(reference["modal_mass_kg"], rel=1e-5)
        assert mode.rigid_coupling_kgm == pytest.approx(reference["rigid_coupling_kgm"], rel=1e-5)
        np.testing.assert_allclose(mode.shape, reference["shape"], atol=1e-5)
    # the distributed mass reproduces the beam's inertia about the hinge: 3 I_C / L^3
    support = Scene.from_params(params).support
    assert source["mass_per_length_kgpm"] == pytest.approx(
        3 * support.beam_inertia_about_hinge_kgm2 / support.beam_length_m**3, rel=1e-5
    )


def _full_beam_on_jack_spring_hz(params, count: int) -> np.ndarray:
    """Independent model: the whole beam in finite elements, pinned at the hinge, the jack a
    transverse spring K_Q sin^2(angle) at its pin (no modal reduction, no coupling terms)."""
    support = Scene.from_params(params).support
    source = params["modes"]["derived_from"]
    elements, length = 64, support.beam_length_m
    h = length / elements
    ei, rho_a = source["bending_stiffness_nm2"], source["mass_per_length_kgpm"]
    k_el = (
        ei
        / h**3
        * np.array(
            [
                [12, 6 * h, -12, 6 * h],
                [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                [-12, -6 * h, 12, -6 * h],
                [6 * h, 2 * h * h, -6 * h, 4 * h * h],
            ]
        )
    )
    m_el = (
        rho_a
        * h
        / 420
        * np.array(
            [
                [156, 22 * h, 54, -13 * h],
                [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                [54, 13 * h, 156, -22 * h],
                [-13 * h, -3 * h * h, -22 * h, 4 * h * h],
            ]
        )
    )
    n = 2 * (elements + 1)
    stiffness, mass = np.zeros((n, n)), np.zeros((n, n))
    for e in range(elements):
        stiffness[2 * e : 2 * e + 4, 2 * e : 2 * e + 4] += k_el
        mass[2 * e : 2 * e + 4, 2 * e : 2 * e + 4] += m_el
    pin = 2 * round(support.jack_pin_from_hinge_m / h)
    stiffness[pin, pin] += (
        support.jack_stiffness_npm * math.sin(math.radians(support.jack_angle_to_beam_deg)) ** 2
    )
    free = np.arange(1, n)
    eigenvalues = eigh(stiffness[np.ix_(free, free)], mass[np.ix_(free, free)], eigvals_only=True)
    return np.sqrt(eigenvalues[: count + 1]) / (2 * math.pi)


def test_coupled_model_matches_full_finite_element_beam(params):
    """Rigid rotation + 2 held modes (Rayleigh-Ritz) gives the jack mode and the first two bending
    modes of the full beam on its jack within 1 %."""
    support = Scene.from_params(params).support
    structure = beam_with_modes(support, shipped_settings().modes)
    reference = _full_beam_on_jack_spring_hz(params, 2)
    np.testing.assert_allclose(structure.natural_frequencies_hz(), reference, rtol=0.01)
    # the jack mode is the study's 39 Hz rigid mode
    assert structure.natural_frequencies_hz()[0] == pytest.approx(
        rigid_beam(support).natural_frequencies_hz()[0], rel=0.005
    )


def test_bending_modes_leave_rebound_and_add_imu_vibration(params):
    """A 25 mm particle is 1e-4 of the beam's effective mass: the modes change the rebound by
    well under 1 %, while the IMU, 0.5 m from the jack pin, feels the 695 Hz mode strongly."""
    scene = Scene.from_params(params)
    rigid = simulate(scene).summary
    modal = simulate(scene, tier="modal").summary
    assert modal["tier"] == "modal" and rigid["tier"] == "rigid"
    assert modal["rebound_speed_mps"] == pytest.approx(rigid["rebound_speed_mps"], rel=0.01)
    assert modal["peak_imu_dynamic_accel_mps2"] > 1.3 * rigid["peak_imu_dynamic_accel_mps2"]


def test_contact_shapes_of_many_positions_are_each_positions_own(params):
    """The shapes of many positions at once (the group path's) are exactly those of each alone,
    on the stations, between them and at the plate's ends; a position off the plate is an
    InputError naming the mode."""
    support = Scene.from_params(params).support
    modes = shipped_settings().modes
    stations = modes[0].stations_m
    inside = np.random.default_rng(3).uniform(stations[0], stations[-1], 500)
    positions = np.concatenate([inside, stations, [stations[0] - 1e-9, stations[-1] + 1e-9]])
    for structure in (rigid_beam(support), beam_with_modes(support, modes)):
        alone = np.array([structure.contact_shape(x) for x in positions.tolist()])
        together = structure.contact_shapes(positions.tolist())
        assert together.shape == (positions.size, structure.size)
        assert np.array_equal(together, alone)
    with pytest.raises(InputError, match="modes.bending_1"):
        beam_with_modes(support, modes).contact_shapes([0.5, float(stations[-1]) + 0.1])


def test_mode_table_errors_name_the_field(params):
    """Too many modes or a negative mode frequency is an InputError naming modes.count or the
    mode's field."""
    bad = deep_merge(load_parameters(), {"modes": {"count": 9}})
    with pytest.raises(InputError, match="modes.count"):
        load_bending_modes(bad)
    bad = deep_merge(load_parameters(), {"modes": {"bending_1": {"frequency_hz": -3.0}}})
    with pytest.raises(InputError, match="modes.bending_1.frequency_hz"):
        load_bending_modes(bad)


def test_sections_scale_the_modes_as_a_uniform_beam_would():
    """Every element's bending stiffness x4 doubles each frequency and leaves the shapes; mass
    per length x4 halves it and multiplies the modal masses and couplings by 4 (a uniform beam:
    omega ~ sqrt(EI / m)); a tip mass lowers the first mode."""
    from tail_beam_sim.physics.structure import euler_bernoulli_modes

    base = dict(
        length_m=1.6,
        held_at_m=[0.0, 0.7],
        bending_stiffness_nm2=4.13e8,
        mass_per_length_kgpm=805.664,
        count=2,
        elements=32,
    )
    plain = euler_bernoulli_modes(**base)
    stiff = euler_bernoulli_modes(**base, element_stiffness_scale=[4.0] * 32)
    heavy = euler_bernoulli_modes(**base, element_mass_scale=[4.0] * 32)
    tipped = euler_bernoulli_modes(**base, tip_mass_kg=100.0)
    for p, s, h in zip(plain, stiff, heavy):
        assert s["frequency_hz"] == pytest.approx(2.0 * p["frequency_hz"], rel=1e-9)
        assert s["shape"] == pytest.approx(p["shape"], abs=1e-9)
        assert h["frequency_hz"] == pytest.approx(0.5 * p["frequency_hz"], rel=1e-9)
        assert h["modal_mass_kg"] == pytest.approx(4.0 * p["modal_mass_kg"], rel=1e-9)
        assert h["rigid_coupling_kgm"] == pytest.approx(4.0 * p["rigid_coupling_kgm"], rel=1e-9)
    assert tipped[0]["frequency_hz"] < plain[0]["frequency_hz"]
    with pytest.raises(InputError):
        euler_bernoulli_modes(**base, element_stiffness_scale=[1.0] * 31)
