"""The seed study's radius series as an energy budget (docs/physics.md, "The radius series: an
energy budget"): for a coal sphere at 8.368 m/s, 1 m from the hinge, the energy the sphere must
lose beyond the suite's to fall from the suite's restitution to the study's, and the most each
mechanism of the nominal support can take (tail_beam_sim.physics.energy_budget). Then the marble
beam-rate ratio: the suite's by tier and mode count, and what each mechanism does to it.
Prints tables, asserts nothing, ships nothing.

    python test/bench/bench_radius_series.py          # about 20 s here
    python test/bench/bench_radius_series.py --rib-spacing-m 0.3
"""

from __future__ import annotations

import argparse
import math

from tail_beam_sim.config import deep_merge, load_parameters
from tail_beam_sim.physics.contact import (
    CrushingContact,
    calibrated_chi,
    effective_modulus_pa,
    hertz_constant,
)
from tail_beam_sim.physics.energy_budget import (
    plate_point_damping_nspm,
    radius_budget,
    sphere_on_plate,
)
from tail_beam_sim.physics.fidelity import FidelitySettings
from tail_beam_sim.physics.materials import Material, sphere_mass_kg
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.simulate import simulate

STUDY_SPEED_MPS = 8.368
STUDY_POSITION_M = 1.0
STUDY_RESTITUTION = {0.025: 0.676, 0.030: 0.474, 0.035: 0.427, 0.040: 0.333}
STUDY_MARBLE_RATIO = 1.91


def suite_summary(params: dict, tier: str, **impact: float | str) -> dict:
    """The suite's summary of one impact of the nominal scene with ``impact`` overrides."""
    return simulate(
        Scene.from_params(params, impact), tier=tier, settings=FidelitySettings.from_params(params)
    ).summary


def radius_table(params: dict, rib_spacing_m: float, confinement: float) -> None:
    """Print the budget at each radius of the study's series."""
    materials = params["materials"]
    coal = Material.from_params("coal", materials["coal"])
    plate_name = params["support"]["plate_material"]
    plate = Material.from_params(plate_name, materials[plate_name])
    thickness_m = params["support"]["plate_thickness_m"]
    print(f"coal sphere, {STUDY_SPEED_MPS} m/s, {STUDY_POSITION_M} m from the hinge; "
          f"{thickness_m * 1e3:.0f} mm {plate_name} plate, ribs {rib_spacing_m} m apart "
          f"(clamped panel radius {rib_spacing_m / 2} m); crushing at {confinement} x "
          f"{coal.crushing_strength_pa / 1e6:.0f} MPa")
    print("energies in J; 'e' columns are restitutions")
    header = ("R mm | e suite | e study | KE | to remove | plate waves (lambda, e) | "
              "flexure stored | panel mode (bound) | crushing (e) | h for study e mm")
    print(header)
    print("-" * len(header))
    for radius_m, study in STUDY_RESTITUTION.items():
        suite = suite_summary(params, "auto", material="coal", radius_m=radius_m,
                              impact_speed_mps=STUDY_SPEED_MPS, position_m=STUDY_POSITION_M)
        row = radius_budget(coal, plate, radius_m, STUDY_SPEED_MPS, suite["restitution"], study,
                            thickness_m, rib_spacing_m / 2.0,
                            coal.crushing_strength_pa * confinement)
        print(f"{radius_m * 1e3:4.0f} | {row.suite_restitution:.3f} | {study:.3f} | "
              f"{row.impact_energy_j:5.2f} | {row.to_remove_j:5.3f} | "
              f"{row.plate_waves_j:5.3f} ({row.zener_lambda:.4f}, "
              f"{row.restitution_with_plate_waves:.3f}) | {row.panel_flexure_stored_j:5.3f} | "
              f"{row.panel_mode_j:5.3f} ({row.panel_mode_bound_j:5.3f}) | "
              f"{row.crushing_j:5.3f} ({row.crushing_restitution:.3f}) | "
              f"{row.thickness_for_study_m * 1e3:5.1f}")


def impulse_ratio(mass_a_kg: float, e_a: float, mass_b_kg: float, e_b: float) -> float:
    """Ratio of the impulses two spheres give a rigid beam, m_a (1 + e_a) / (m_b (1 + e_b)):
    a rigid beam's peak rate is the impulse's moment over I_C."""
    return mass_a_kg * (1.0 + e_a) / (mass_b_kg * (1.0 + e_b))


def marble_table(params: dict, confinement: float) -> None:
    """Print the marble/coal peak beam angular velocity ratio: the suite's by tier and mode
    count, and the impulse ratio each mechanism leaves."""
    print()
    print(f"marble / coal peak beam angular velocity, nominal scene (study: {STUDY_MARBLE_RATIO})")
    for label, tier, extra in (
        ("rigid tier", "rigid", {}),
        ("modal tier, 2 modes (shipped)", "modal", {}),
        ("modal tier, 3 modes", "modal", {"modes": {"count": 3}}),
    ):
        merged = deep_merge(params, extra)
        coal = suite_summary(merged, tier, material="coal")
        marble = suite_summary(merged, tier, material="marble")
        key = "peak_beam_angular_velocity_radps"
        ratio = marble[key] / coal[key]
        print(f"  {label:32s} {ratio:.3f}")
    materials = params["materials"]
    coal = Material.from_params("coal", materials["coal"])
    marble = Material.from_params("marble", materials["marble"])
    plate_name = params["support"]["plate_material"]
    plate = Material.from_params(plate_name, materials[plate_name])
    scene = Scene.from_params(params, {"material": "coal"})
    radius_m, speed_mps = scene.impact.radius_m, scene.impact.impact_speed_mps
    masses = {m.name: sphere_mass_kg(m.density_kgpm3, radius_m) for m in (coal, marble)}
    damping = plate_point_damping_nspm(plate, params["support"]["plate_thickness_m"])
    with_waves = {}
    for material in (coal, marble):
        stiffness = hertz_constant(effective_modulus_pa(material, plate), radius_m)
        with_waves[material.name] = sphere_on_plate(
            masses[material.name], stiffness, speed_mps, calibrated_chi(material.restitution),
            damping,
        ).restitution
    crushing = CrushingContact(effective_modulus_pa(coal, plate), radius_m,
                               coal.crushing_strength_pa * confinement)
    crushed = math.sqrt(crushing.rebound_energy_ratio(0.5 * masses["coal"] * speed_mps**2))
    rows = (
        ("impulse ratio, suite's e", coal.restitution, marble.restitution),
        ("impulse ratio, plate waves on both", with_waves["coal"], with_waves["marble"]),
        ("impulse ratio, coal crushing", crushed, marble.restitution),
    )
    for label, e_coal, e_marble in rows:
        ratio = impulse_ratio(masses["marble"], e_marble, masses["coal"], e_coal)
        print(f"  {label:36s} {ratio:.3f}  (e coal {e_coal:.3f}, e marble {e_marble:.3f})")
    need_coal = masses["marble"] * (1 + marble.restitution) / (
        STUDY_MARBLE_RATIO * masses["coal"]) - 1
    need_marble = STUDY_MARBLE_RATIO * masses["coal"] * (1 + coal.restitution) / masses[
        "marble"] - 1
    print(f"  impulse ratio {STUDY_MARBLE_RATIO} needs e coal {need_coal:.3f} (marble "
          f"{marble.restitution}) or e marble {need_marble:.3f} (coal {coal.restitution})")


def main() -> None:
    """Parse the options and print both tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rib-spacing-m", type=float, default=0.5,
                        help="distance between the top plate's ribs (webs), m (default 0.5)")
    parser.add_argument("--crushing-confinement", type=float, default=3.0,
                        help="crushing pressure over the uniaxial crushing strength (default 3)")
    options = parser.parse_args()
    params = load_parameters()
    radius_table(params, options.rib_spacing_m, options.crushing_confinement)
    marble_table(params, options.crushing_confinement)


if __name__ == "__main__":
    main()
