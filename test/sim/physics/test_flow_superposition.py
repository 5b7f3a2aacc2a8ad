"""The flow's superposition of contacts against the stream simulator (separate contacts: exact)
and against a coupled reference (two contacts at once on the same beam, integrated together)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tail_beam_sim.config import deep_merge, default_config_dir, load_parameters
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.scene import Impact
from tail_beam_sim.physics.simulate import build_problem
from tail_beam_sim.physics.stream import StreamSimulator
from tail_beam_sim.physics.superpose import FlowSimulator


def _params(**sections) -> dict:
    params = load_parameters([default_config_dir() / "sim_node.yaml"])
    params["stream"]["min_impact_gap_s"] = 0.001
    deep_merge(params, sections)
    return params


LUMPS = [
    {"material": "sandstone", "radius_m": 0.05, "drop_height_m": 2.5, "position_m": 0.6},
    {"material": "coal", "radius_m": 0.06, "drop_height_m": 2.0, "position_m": 1.1},
]


def test_separate_contacts_superpose_to_the_stream_simulators_samples():
    """Contacts that do not overlap: the flow's epochs give the stream simulator's samples
    (each contact there solved on the beam as the previous ones leave it) to rounding."""
    stamps = [0.1, 0.13, 0.2, 0.21, 0.35]
    chunks = []
    for cls in (StreamSimulator, FlowSimulator):
        sim = cls.from_params(_params())
        for k, stamp in enumerate(stamps):
            sim.submit({**LUMPS[k % 2], "restitution": 0.4, "impact_id": f"l{k}"}, stamp)
        chunks.append(sim.advance(0.6))
    stream, flow = chunks
    scale = np.ptp(stream.pressure.pressure_pa)
    assert scale > 1e4  # the impacts moved the jack
    assert np.max(np.abs(stream.pressure.pressure_pa - flow.pressure.pressure_pa)) < 1e-9 * scale
    assert np.max(np.abs(stream.vibration.accel_mps2 - flow.vibration.accel_mps2)) < 1e-4
    assert np.allclose(
        stream.imu.linear_acceleration_mps2, flow.imu.linear_acceleration_mps2, atol=1e-9
    )


def _coupled_reference(sim: FlowSimulator, problems, start_s, end_s):
    """Both particles and the beam integrated together (DOP853, tight tolerances): particle j
    meets the plate at start_s[j] at zero penetration with its impact speed, its hysteresis
    scaled by its approach speed then, as the solver's law has it. Returns the beam's state
    (q, qd) at end_s and each particle's final velocity."""
    structure = sim.structure
    n = structure.size
    inv_mass = structure.inv_mass

    def rhs(t, y, active, approach):
        q, qd = y[:n], y[n : 2 * n]
        generalised = np.zeros(n)
        out = np.empty_like(y)
        for j, problem in enumerate(problems):
            z, zd = y[2 * n + 2 * j], y[2 * n + 2 * j + 1]
            force = 0.0
            if active[j]:
                b = problem.contact_shape
                delta, rate = -(b @ q) - z, -(b @ qd) - zd
                if delta > 0.0:
                    force = (
                        problem.hertz_stiffness
                        * delta**1.5
                        * (1.0 + problem.damping_factor * rate / approach[j])
                    )
                    force = max(force, 0.0)
                generalised += b * force
            out[2 * n + 2 * j] = zd
            out[2 * n + 2 * j + 1] = force / problem.mass_kg - problem.gravity_mps2
        out[:n] = qd
        out[n : 2 * n] = inv_mass @ (
            generalised - structure.damping @ qd - structure.stiffness @ q
        )
        return out

    y = np.zeros(2 * n + 2 * len(problems))
    active = [False] * len(problems)
    approach = [1.0] * len(problems)
    t = start_s[0]
    for j, problem in enumerate(problems):
        if start_s[j] > t:
            y = solve_ivp(
                rhs,
                (t, start_s[j]),
                y,
                "DOP853",
                rtol=1e-11,
                atol=1e-14,
                max_step=5e-7,
                args=(active, approach),
            ).y[:, -1]
            t = start_s[j]
        b = problem.contact_shape
        y[2 * n + 2 * j] = -(b @ y[:n])
        y[2 * n + 2 * j + 1] = -problem.impact_speed_mps
        approach[j] = problem.impact_speed_mps + b @ y[n : 2 * n]
        active[j] = True
    y = solve_ivp(
        rhs,
        (t, end_s),
        y,
        "DOP853",
        rtol=1e-11,
        atol=1e-14,
        max_step=5e-7,
        args=(active, approach),
    ).y[:, -1]
    return y[:n], y[n : 2 * n], y[2 * n + 1 :: 2]


@pytest.mark.parametrize(
    "offset_s, contact, tolerance",
    [
        # apart: the stream's own approximation (a contact solved from the beam's velocity,
        # the displacement it meets ringing on freely) and the solver's error
        (1.0e-3, "rk4", 2e-3),
        (0.1e-3, "rk4", 1e-2),  # the second strikes while the first is in contact
        (0.0, "rk4", 1e-2),  # both at once
        (0.1e-3, "pulse", 1e-2),  # the flow's default contact method
    ],
)
def test_two_contacts_against_a_coupled_reference(offset_s, contact, tolerance):
    """The beam's state after two contacts and the particles' rebounds, superposed against the
    coupled integration. Apart, they agree to the solver's error; overlapping, each contact
    sees the beam as the earlier one leaves it at its start but not the force of the other
    during its own contact: the error stays within 1 % of the response (docs/flow.md)."""
    sim = FlowSimulator.from_params(_params())
    sim.solver_options = {"contact": contact}
    start = [0.1, 0.1 + offset_s]
    scheduled = []
    for k, lump in enumerate(LUMPS):
        scheduled.append(sim.submit({**lump, "restitution": 0.4, "impact_id": f"r{k}"}, start[k]))
    # the overlapping case overlaps
    first = scheduled[0].trajectory.contacts[0]
    overlapping = start[1] < start[0] + first.end_s
    assert overlapping == (offset_s < 0.3e-3)
    end = 0.1 + 2e-3
    sim._fold_until(end)
    state = sim._epochs[-1].sample(np.array([end - sim._epoch_starts[-1]]))
    problems = [
        build_problem(
            sim.support,
            Impact.from_mapping({**lump, "restitution": 0.4}, sim.materials, sim.support),
            sim.contact_model,
            sim.window_s,
            sim.structure,
        )
        for lump in LUMPS
    ]
    q, qd, particle_v = _coupled_reference(sim, problems, start, end)
    # the rigid rotation rate and the bending modes' rates, each against its own scale
    scale = np.abs(qd) + 1e-3 * np.max(np.abs(qd))
    assert np.all(np.abs(state.qd[:, 0] - qd) <= tolerance * scale), (state.qd[:, 0], qd)
    for s, v in zip(scheduled, particle_v):
        # the reference's velocity at ``end``: the rebound less gravity's since separation
        flight = end - s.free_after_s
        at_end = s.trajectory.rebound_velocity_mps - sim.support.gravity_mps2 * flight
        assert at_end == pytest.approx(v, rel=tolerance)


@pytest.mark.parametrize("channels", [("pressure", "imu"), ("pressure",), ("imu", "vibration")])
def test_channels_left_out_leave_the_others_bit_for_bit(channels):
    """A simulator told to sample only some sensors gives no sample of the others and the very
    samples (values and stamps) of those it keeps: a caller reading fewer sensors pays for fewer
    without changing what it reads. Two spans, so the chunking is exercised too."""
    chunks = {}
    for name, kept in (("all", None), ("some", channels)):
        options = {} if kept is None else {"channels": kept}
        sim = FlowSimulator.from_params(_params(), **options)
        for k, stamp in enumerate([0.1, 0.1004, 0.25]):  # the first two overlap
            sim.submit({**LUMPS[k % 2], "restitution": 0.4, "impact_id": f"l{k}"}, stamp)
        chunks[name] = [sim.advance(0.2), sim.advance(0.4)]
    for full, part in zip(chunks["all"], chunks["some"]):
        streams = {
            "pressure": (full.pressure.pressure_pa, part.pressure.pressure_pa),
            "imu": (full.imu.linear_acceleration_mps2, part.imu.linear_acceleration_mps2),
            "vibration": (full.vibration.accel_mps2, part.vibration.accel_mps2),
        }
        for channel, (everything, kept) in streams.items():
            if channel in channels:
                assert everything.size and np.array_equal(everything, kept), channel
            else:
                assert kept.size == 0, channel
        assert [r.stamp_s for _, r in full.rebounds] == [r.stamp_s for _, r in part.rebounds]
        if "imu" in channels:
            assert np.array_equal(full.imu.angular_velocity_radps, part.imu.angular_velocity_radps)
            assert np.array_equal(full.imu.stamp_s, part.imu.stamp_s)
        if "vibration" in channels:
            assert np.array_equal(full.vibration.stamp_s, part.vibration.stamp_s)


def test_an_unknown_channel_is_refused_by_name():
    """A channel that is no sampled sensor is refused naming the field and the allowed ones."""
    with pytest.raises(InputError, match="channels.*camera.*must be among pressure, imu"):
        FlowSimulator.from_params(_params(), channels=("pressure", "camera"))
