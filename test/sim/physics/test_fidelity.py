"""Fidelity tiers: the automatic choice, its error estimates, the brittle tier, the CLI report."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from tail_beam_sim.cli import main
from tail_beam_sim.config import deep_merge, load_parameters
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.fidelity import BRITTLE_STEPS_PER_CONTACT, Needs, plan, shipped_settings
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.simulate import build_problem, crushing_contact, simulate
from tail_beam_sim.physics.solvers import solve
from tail_beam_sim.physics.solvers.hybrid import RK4_CONTACT_ERROR


def _choice(scene, outputs, tolerance):
    return plan(scene, "auto", Needs.of(outputs, tolerance), shipped_settings())


def test_cheapest_tier_that_meets_what_the_scene_needs(default_scene):
    """Rebound alone: an impulse suffices. Pressure at 5 %: still the impulse (the bending modes
    move the jack pressure by about 4 %). Pressure at 1 %, or the IMU at 2 kHz, whose band holds
    the 695 Hz bending mode: the modal tier."""
    assert _choice(default_scene, ["rebound"], 0.01).tier.name == "impulse"
    assert _choice(default_scene, ["pressure"], 0.05).tier.name == "impulse"
    assert _choice(default_scene, ["pressure"], 0.01).tier.name == "modal"
    assert _choice(default_scene, ["imu"], 0.05).tier.name == "modal"
    assert _choice(default_scene, ["rebound"], 0.01).estimates["impulse"] < 0.01


def test_the_rigid_tiers_estimate_follows_the_imu_bandwidth():
    """The bending modes reach a period-averaging IMU less the slower it samples: at 2 and 5 kHz
    (both resolve the 695 Hz mode) they dominate alike; at 200 Hz they weigh less than half."""
    estimate = {}
    for rate in (5000.0, 2000.0, 200.0):
        scene = Scene.from_params(
            deep_merge(load_parameters(), {"sensors": {"imu_rate_hz": rate}})
        )
        estimate[rate] = _choice(scene, ["imu"], 0.05).estimates["rigid"]
    assert estimate[5000.0] == pytest.approx(estimate[2000.0], rel=0.1)
    assert estimate[200.0] < 0.5 * estimate[2000.0]


@pytest.mark.parametrize(
    "overrides", [{}, {"material": "marble"}, {"drop_height_m": 0.003}, {"position_m": 0.3}]
)
def test_rigid_tiers_estimate_is_not_optimistic(params, overrides):
    """The estimated error of the rigid tier bounds the measured difference to the modal tier
    on the sampled pressure stream and the sampled IMU stream."""
    scene = Scene.from_params(params, overrides)
    for output in ("pressure", "imu"):
        needs = Needs.of([output], 0.01)
        summary = simulate(scene, tier="rigid", needs=needs, check=True).summary
        measured = summary["check"][f"{output}_stream"]
        assert 0.25 * summary["error_estimate"] < measured <= summary["error_estimate"]


def _rigid_wall_scene(material: str, speed: float) -> Scene:
    """A scene whose beam is a rigid wall (inertia 1e12 kg m^2, a stiff jack) without gravity:
    past the bounds a support's parameters are validated against, so set on the built
    support."""
    scene = Scene.from_params(
        load_parameters(), {"material": material, "impact_speed_mps": speed, "window_s": 0.003}
    )
    wall = replace(
        scene.support,
        beam_inertia_about_hinge_kgm2=1e12,
        gravity_mps2=0.0,
        oil_bulk_modulus_pa=1e14,
    )
    return replace(scene, support=wall)


@pytest.mark.parametrize("speed", [0.5, 3.0, 8.0])
def test_crushing_contact_rebound_matches_its_energy_balance(speed):
    """On a rigid wall without gravity, e^2 = (energy given back on unloading) / (impact energy),
    in closed form from the loading and unloading curves; RK4 in the hybrid at the brittle tier's
    steps reproduces it within the 1e-4 that simulate reports, velocity Verlet within 5e-3."""
    scene = _rigid_wall_scene("coal", speed)
    crushing = crushing_contact(
        scene.support, scene.impact, shipped_settings().crushing_confinement_factor
    )
    expected = math.sqrt(crushing.rebound_energy_ratio(0.5 * scene.impact.mass_kg * speed**2))
    problem = build_problem(
        scene.support, scene.impact, scene.contact_model, scene.window_s, crushing=crushing
    )
    rk4 = solve(problem, steps_per_contact=BRITTLE_STEPS_PER_CONTACT).rebound_velocity_mps / speed
    assert rk4 == pytest.approx(expected, rel=RK4_CONTACT_ERROR)
    verlet = solve(problem, "verlet", dt_s=2e-7).rebound_velocity_mps / speed
    assert verlet == pytest.approx(expected, rel=5e-3)
    if speed >= 3.0:
        assert expected < 0.6  # crushing absorbs most of the energy at drop speeds


def test_brittle_tier_caps_coal_force_and_lowers_its_rebound_and_leaves_gangue(params):
    """Coal crushing (past the study): lower peak force, longer contact, lower rebound; marble is
    not brittle in this tier, so its results do not change."""
    coal = Scene.from_params(params)
    elastic, brittle = simulate(coal, tier="modal").summary, simulate(coal, tier="brittle").summary
    assert brittle["peak_contact_force_n"] < 0.7 * elastic["peak_contact_force_n"]
    assert brittle["rebound_speed_mps"] < 0.7 * elastic["rebound_speed_mps"]
    assert brittle["contact_duration_s"] > elastic["contact_duration_s"]
    marble = Scene.from_params(params, {"material": "marble"})
    assert simulate(marble, tier="brittle").summary["rebound_speed_mps"] == pytest.approx(
        simulate(marble, tier="modal").summary["rebound_speed_mps"], rel=1e-3
    )


def _run_json(capsys, *argv):
    code = main(["simulate", "--json", *argv])
    out = capsys.readouterr().out
    assert code == 0
    return json.loads(out)


def test_simulate_json_reports_tier_solver_and_error_estimate(capsys):
    """--json reports the auto-chosen tier and solver with an estimate within tolerance,
    --check's measured differences, and null (not a guess) for a fixed-step solver."""
    summary = _run_json(capsys, "--outputs", "rebound")
    assert (summary["tier"], summary["solver"]) == ("impulse", "impulse")
    assert 0 < summary["error_estimate"] <= 0.01
    summary = _run_json(capsys)
    assert (summary["tier"], summary["solver"]) == ("modal", "hybrid")
    summary = _run_json(capsys, "--tier", "rigid", "--check", "--outputs", "rebound", "pressure")
    assert summary["check"]["against"] == "modal"
    assert summary["check"]["rebound"] < 0.01
    summary = _run_json(capsys, "--tier", "rigid", "--solver", "verlet", "--window-s", "0.005")
    assert (
        summary["solver"] == "verlet" and summary["error_estimate"] is None
    )  # no estimate for fixed steps: null, not a guess


def test_bad_needs_are_reported_with_field_and_range(capsys):
    """Unknown outputs and a zero tolerance are refused naming fidelity.outputs or
    fidelity.tolerance and the range, in one line from the CLI."""
    with pytest.raises(InputError, match="fidelity.outputs"):
        Needs.of(["sound"], 0.01)
    code = main(["simulate", "--tolerance", "0"])
    err = capsys.readouterr().err
    assert (
        code == 2
        and "fidelity.tolerance" in err
        and "(0, 1]" in err
        and len(err.strip().splitlines()) == 1
    )
    assert np.isfinite(shipped_settings().crushing_confinement_factor)
