"""The closed-form impulse model: each contact an instantaneous impulse, the beam exact between.

For scenes that need only the rebound and the impulse (and the slow rigid-beam response that
an impulse sets off). A contact with relative approach speed v exchanges the impulse
J = mu (1 + e) v (mu the reduced mass of the particle and the plate's effective mass, e the
restitution that the contact law's hysteresis factor delivers, from the pulse table); the
impulse is applied at the pulse's centroid, so that a beam mode of frequency omega sees the
pulse's effect to second order in omega times the pulse's width. Duration and peak force come
from the same table (they are what the hybrid solver's pulse gives). During the contact the
particle's own position is not modelled: only its velocity after the contact is.
"""

from __future__ import annotations

import math

from tail_beam_sim.physics.solvers.hybrid import next_contact_time
from tail_beam_sim.physics.solvers.problem import (
    ContactRecord,
    FreeSegment,
    ImpactProblem,
    SolverError,
    Trajectory,
)
from tail_beam_sim.physics.solvers.pulse import contact_pulse, max_chi

REST_SPEED_MPS = 1e-4
MAX_CONTACTS = 500


def solve(problem: ImpactProblem) -> Trajectory:
    """The impulse model of ``problem`` (module docstring); stats hold the pulse's width, s.

    ``error_estimate``: what the impulse leaves out of each contact, relative: gravity over the
    contact (g T / v, in the rebound) and the pulse's spread about its centroid as the fastest
    mode of frequency omega sees it ((omega sigma)^2 / 2, in the response), the worst contact's.
    """
    if problem.crushing is not None or problem.damping_factor > max_chi():
        raise SolverError(
            "impulse", "covers Hertz contacts with hysteresis factor <= 40 only; use hybrid"
        )
    structure = problem.structure
    b = problem.contact_shape
    g = problem.gravity_mps2
    load = problem.contact_load
    reduced_mass = problem.reduced_mass_kg
    q, qd = problem.q0.astype(float), problem.qd0.astype(float)
    z, zd = 0.0, -problem.impact_speed_mps
    segments: list[FreeSegment] = []
    contacts: list[ContactRecord] = []
    t, previous, width, at_rest, estimate = 0.0, -math.inf, 0.0, False, 0.0
    frequencies = structure.natural_frequencies_hz()
    fastest = 2 * math.pi * float(frequencies.max()) if frequencies.size else 0.0
    while True:
        approach = -zd - float(b @ qd)
        if approach < REST_SPEED_MPS or len(contacts) >= MAX_CONTACTS:
            at_rest = True
            break
        pulse = contact_pulse(
            problem.damping_factor, problem.hertz_stiffness, reduced_mass, approach
        )
        centroid = pulse.centroid_s
        width = max(width, pulse.width_s)
        estimate = max(
            estimate, abs(g) * pulse.duration_s / approach, 0.5 * (fastest * pulse.width_s) ** 2
        )
        impulse = reduced_mass * (approach + pulse.separation_mps)
        segments.append(FreeSegment(previous, t + centroid, t, q, qd, z, zd))
        q, qd = structure.propagate(q, qd, centroid)
        z, zd = z + zd * centroid - 0.5 * g * centroid**2, zd - g * centroid
        qd = qd + load * impulse
        zd = zd + impulse / problem.mass_kg
        end = t + pulse.duration_s
        contacts.append(ContactRecord(t, end, approach, zd, pulse.peak_force_n))
        t = t + centroid
        previous = t
        z = -float(b @ q)
        following = next_contact_time(problem, t, q, qd, z, zd)
        if following is None:
            break
        segments.append(FreeSegment(previous, following, t, q, qd, z, zd))
        dt = following - t
        q, qd = structure.propagate(q, qd, dt)
        z, zd = -float(b @ q), zd - g * dt
        previous = t = following
    segments.append(FreeSegment(previous, math.inf, t, q, qd, z, zd))
    return Trajectory(
        problem,
        segments,
        contacts,
        "impulse",
        estimate,
        particle_at_rest=at_rest,
        stats={"pulse_width_s": width},
    )
