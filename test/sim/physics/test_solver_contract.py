"""The solvers' written contract (tail_beam_sim.physics.solvers): every registered solver fills
the same Trajectory fields; a failed solve is a SolverError with its own exit status and log
line."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rcl_interfaces.msg import Log
from std_msgs.msg import String

from tail_beam_sim import topics
from tail_beam_sim.cli import EXIT_SOLVER_FAILED, main
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.fidelity import TIERS, shipped_settings, structure_for
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.simulate import build_problem, simulate
from tail_beam_sim.physics.solvers import SOLVERS, SolverError, Trajectory, solve
from tail_beam_sim.physics.solvers.problem import FreeSegment

# Flores et al.'s law asks chi = 8 (1 - e) / (5 e) = 52 for e = 0.03: past the pulse table (chi <=
# 40), which the impulse solver cannot go beyond.
OUT_OF_RANGE = {"contact_model": "flores", "restitution": 0.03}


def _problem(params, **overrides):
    scene = Scene.from_params(params, {"window_s": 0.01, **overrides})
    structure = structure_for(TIERS["rigid"], scene.support, shipped_settings().modes)
    return build_problem(
        scene.support, scene.impact, scene.contact_model, scene.window_s, structure=structure
    )


@pytest.mark.parametrize("name", sorted(SOLVERS))
def test_every_solver_fills_the_contract_fields(params, name):
    """Problem, segments over the whole real line in start order, contacts from t = 0 in order,
    its registered name, a relative error estimate (a number in [0, 0.1), or nan for none) and
    a bool at-rest flag; the trajectory samples finite states before, during and after."""
    problem = _problem(params)
    trajectory = solve(problem, name)
    assert isinstance(trajectory, Trajectory) and trajectory.problem is problem
    assert trajectory.solver == name
    starts = [segment.start_s for segment in trajectory.segments]
    assert starts[0] == -math.inf and starts == sorted(starts)
    assert (
        isinstance(trajectory.segments[-1], FreeSegment)
        and trajectory.segments[-1].end_s == math.inf
    )
    contacts = trajectory.contacts
    assert contacts and contacts[0].start_s == 0.0
    assert all(c.start_s < c.end_s for c in contacts)
    assert all(a.end_s <= b.start_s for a, b in zip(contacts, contacts[1:]))
    assert contacts[0].approach_speed_mps == pytest.approx(problem.impact_speed_mps)
    assert contacts[0].peak_force_n > 0.0
    estimate = trajectory.error_estimate
    assert isinstance(estimate, float) and (math.isnan(estimate) or 0.0 <= estimate < 0.1)
    assert isinstance(trajectory.particle_at_rest, bool)
    state = trajectory.sample(np.array([-1e-3, 0.5 * contacts[0].end_s, problem.window_s, 1.0]))
    assert np.all(np.isfinite(state.q)) and np.all(np.isfinite(state.zd_mps))


def test_simulate_reports_the_solvers_own_estimate(params):
    """simulate's error_estimate is the larger of the tier's model error and the trajectory's own
    estimate, read from the contract field (nan stays nan: no estimate is not zero)."""
    scene = Scene.from_params(params, {"window_s": 0.005})
    for solver in ("hybrid", "RK45", "verlet"):
        result = simulate(scene, solver, tier="rigid")
        own = result.trajectory.error_estimate
        if math.isnan(own):
            assert math.isnan(result.summary["error_estimate"])
        else:
            assert result.summary["error_estimate"] >= own


def test_a_failed_solve_is_a_solver_error_not_bad_input(params):
    """A problem outside the method's range is a SolverError naming the solver; an option out
    of range is still InputError naming the option."""
    problem = _problem(params, **OUT_OF_RANGE)
    with pytest.raises(SolverError, match=r"^impulse: .*hysteresis factor <= 40") as caught:
        solve(problem, "impulse")
    assert not isinstance(caught.value, InputError)
    with pytest.raises(InputError, match="steps_per_contact = 2"):
        solve(problem, "hybrid", steps_per_contact=2)


def test_cli_exits_3_with_one_line_when_the_solve_fails(capsys):
    """`tail-beam simulate` on a solve that fails: exit status 3 (not bad input's 2), one line
    on stderr naming the solver, nothing on stdout, no traceback."""
    code = main(
        ["simulate", "--solver", "impulse", "--contact-model", "flores", "--restitution", "0.03"]
    )
    captured = capsys.readouterr()
    assert code == EXIT_SOLVER_FAILED == 3
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("tail-beam simulate: solver failed: impulse: ")


@pytest.mark.ros
def test_sim_node_logs_a_failed_solve_in_one_line_and_keeps_running():
    """An impact its solver cannot simulate is one error line in sim_node's log; the impacts
    before and after it are published."""
    from rclpy.parameter import Parameter
    from rosprobe import Probe, ros_context, spin_for, spin_until

    from tail_beam_sim.ros.sim_node import SimNode

    overrides = {
        "sim_node.realtime_factor": 0.0,
        "stream.tier": "impulse",
        "scene.contact_model": "flores",
    }
    command = {"material": "coal", "radius_m": 0.03, "drop_height_m": 3.0, "position_m": 1.0}
    with ros_context() as (context, executor):
        sim = SimNode(
            context=context,
            parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()],
        )
        probe = Probe(context, {topics.IMPACT_TRUTH: String, "/rosout": Log})
        executor.add_node(sim)
        executor.add_node(probe)
        assert spin_until(executor, lambda: probe.command_pub.get_subscription_count() >= 1)
        probe.send({**command, "impact_id": "ok-before"})
        probe.send({**command, "impact_id": "fails", "restitution": OUT_OF_RANGE["restitution"]})
        probe.send({**command, "impact_id": "ok-after"})
        assert spin_until(executor, lambda: len(probe.messages[topics.IMPACT_TRUTH]) == 2)
        spin_for(executor, 0.3)
        assert [t["impact_id"] for t in probe.json(topics.IMPACT_TRUTH)] == [
            "ok-before",
            "ok-after",
        ]
        errors = [
            m.msg
            for m in probe.messages["/rosout"]
            if m.name == "tail_beam_sim" and m.level >= Log.ERROR
        ]
        assert len(errors) == 1 and "\n" not in errors[0]
        assert errors[0].startswith("impact_cmd not simulated: solver failed: impulse: ")
