"""Many impacts that each make one pulse contact, solved and sampled at once.

The hybrid solver (:mod:`~tail_beam_sim.physics.solvers.hybrid`) takes most impacts as one
contact: the pre-integrated pulse, the beam starting at rest, the particle never caught again
within the window. Everything about such an impact is then a closed form on the structure's
eigenvalues: the state after the contact, the states at the pulse's samples, the free ring-down
after it. :func:`solve_family` computes them for N impacts on one structure, one array
operation per quantity and the solver's own arithmetic, and marks the impacts that are not of
that kind (``ok`` false: the pulse's error estimate over the tolerance, a particle coming to
rest, a re-contact possible within the window), which a caller solves one by one.
:meth:`PulseFamily.sample` evaluates the states at (impact, instant) pairs as
:meth:`~tail_beam_sim.physics.solvers.problem.Trajectory.sample` does: rest before the contact,
the cubic Hermite through the pulse's samples during it, the exact free response after it;
:meth:`PulseFamily.trajectory` gives one impact's :class:`Trajectory`, the hybrid solver's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from tail_beam_sim.physics.solvers.hybrid import REST_SPEED_MPS, PulseSegment
from tail_beam_sim.physics.solvers.problem import (
    ContactRecord,
    FreeSegment,
    ImpactProblem,
    Trajectory,
)
from tail_beam_sim.physics.solvers.pulse import (
    PULSE_NODES,
    SERIES_RADIUS,
    Pulse,
    pulse_integral,
    pulse_table,
)
from tail_beam_sim.physics.structure import reduced_mass_kg


@dataclass
class FamilyStates:
    """States of S impacts at T instants each: q-like fields (n, S, T), the others (S, T)."""

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    force_n: np.ndarray
    z_m: np.ndarray
    zd_mps: np.ndarray


class PulseFamily:
    """N impacts on one structure, each one pulse contact from rest at t = 0 (module docstring).

    Arrays over impacts (SI): ``duration_s``, ``separation_mps`` (relative), ``peak_force_n``,
    ``estimate`` (the pulse's relative error estimate), the state as the contact ends (``end_q``,
    ``end_qd`` (N, n), ``end_z_m``, ``end_zd_mps``) and ``ok``."""

    def __init__(self, problems: Sequence[ImpactProblem], pulse_tolerance: float) -> None:
        structure = problems[0].structure
        table = pulse_table()
        self.problems = list(problems)
        self._trajectories: dict[int, Trajectory] = {}
        self.structure = structure
        n = self.n = structure.size
        self.gravity_mps2 = problems[0].gravity_mps2
        self.window_s = np.array([p.window_s for p in problems])
        shape = self.shape = np.array([p.contact_shape for p in problems]).reshape(-1, n)
        mass = np.array([p.mass_kg for p in problems])
        hertz = np.array([p.hertz_stiffness for p in problems])
        chi = np.array([p.damping_factor for p in problems])
        speed = self.speed_mps = np.array([p.impact_speed_mps for p in problems])
        eigenvalues, vectors, _ = structure._eigen
        load = shape @ structure.inv_mass.T
        self.load = load
        reduced = reduced_mass_kg(mass, np.einsum("ij,ij->i", shape, load))
        approach = np.maximum(speed, 1e-12)
        row = np.clip(np.searchsorted(table.chi, chi, side="right") - 1, 0, table.chi.size - 2)
        weight = (chi - table.chi[row]) / (table.chi[row + 1] - table.chi[row])

        def blend(values: np.ndarray) -> np.ndarray:
            return (1 - weight) * values[row] + weight * values[row + 1]

        length = (reduced * approach**2 / hertz) ** 0.4
        force_scale = hertz * length**1.5
        duration = blend(table.duration) * length / approach
        separation = approach * blend(table.restitution)
        self.row, self.weight, self.length_m, self.approach_mps = row, weight, length, approach
        self.force_scale_n, self.duration_s, self.separation_mps = (
            force_scale,
            duration,
            separation,
        )
        self.peak_force_n = force_scale * blend(table.peak_force)
        max_penetration = length * blend(table.peak_penetration)
        self.max_penetration_m = max_penetration
        self.hertz = hertz
        # the state as the contact ends, in modal coordinates (the solver's pulse_contact)
        beta = shape @ structure.modal_input.T  # (N, 2n)
        spectrum = self._spectrum(eigenvalues)
        modal_end = np.exp(eigenvalues * duration[:, None]) * (beta * spectrum)
        x_end = (modal_end @ vectors.T).real
        self.end_modal = modal_end
        self.end_q, self.end_qd = x_end[:, :n], x_end[:, n:]
        internal_rows = shape @ structure.modal_internal
        impulse = reduced * (approach + separation)
        neglected = abs(self.gravity_mps2) + np.einsum(
            "ij,ij->i", np.abs(internal_rows), np.abs(beta) * impulse[:, None]
        )
        self.estimate = neglected * np.maximum(
            duration / approach, duration * duration / (2.0 * max_penetration)
        )
        plate_speed = np.einsum("ij,ij->i", shape, self.end_qd)
        self.end_zd_mps = -plate_speed + separation
        self.end_z_m = -np.einsum("ij,ij->i", shape, self.end_q)
        separating = self.end_zd_mps + plate_speed
        # a bound on the plate's later speed (hybrid.plate_speed_bound_mps): the particle is
        # not caught again within the window when it flies off faster than the plate can follow
        bound = np.abs((shape @ vectors[n:]) * modal_end).sum(axis=1)
        window = self.window_s
        never_again = self.end_zd_mps - bound > 0.5 * self.gravity_mps2 * (window - duration)
        self.ok = (
            (chi <= table.chi[-1])
            & np.array([p.crushing is None for p in problems])
            & (self.estimate <= pulse_tolerance)
            & (separating >= REST_SPEED_MPS)
            & (duration < window)
            & never_again
            & np.isfinite(self.estimate)
            & np.isfinite(x_end).all(axis=1)
        )

    def _spectrum(self, eigenvalues: np.ndarray) -> np.ndarray:
        """(N, 2n): int_0^T F(s) e^{-lambda_k s} ds of each impact's pulse, N s
        (:meth:`Pulse.spectrum`: the moments' power series, the quadrature beyond its radius)."""
        table = pulse_table()
        mu = eigenvalues * self.duration_s[:, None]
        row, w = self.row, self.weight[:, None]
        moments = (1 - w) * table.moments[row] + w * table.moments[row + 1]
        powers = np.power.outer(-mu, np.arange(moments.shape[1]))
        scale = (self.force_scale_n * self.duration_s)[:, None]
        out = np.einsum("ikm,im->ik", powers, moments) * scale
        for i in np.flatnonzero(np.abs(mu).max(axis=1) > SERIES_RADIUS):
            out[i] = pulse_integral(eigenvalues, self.node_times[i], self.node_force[i])
        return out

    @property
    def size(self) -> int:
        return len(self.problems)

    @cached_property
    def node_times(self) -> np.ndarray:
        """(N, PULSE_NODES + 1): the pulse's sample instants, s from contact start."""
        return pulse_table().fractions * self.duration_s[:, None]

    def _rows(self, k: int) -> np.ndarray:
        rows = pulse_table().rows
        w = self.weight[:, None]
        return (1 - w) * rows[self.row, k] + w * rows[self.row + 1, k]

    @cached_property
    def node_force(self) -> np.ndarray:
        return self._rows(2) * self.force_scale_n[:, None]

    @cached_property
    def _polynomials(self) -> np.ndarray:
        """(N, steps, 4, 3n + 3): per impact and pulse step, the cubic Hermite coefficients of
        [q; q'; z; z'] and the straight line of [q''; force] (``Trajectory._stacks``)."""
        structure = self.structure
        n = self.n
        eigenvalues, vectors, inverse = structure._eigen
        t = self.node_times
        h = t[:, 1] - t[:, 0]
        force = self.node_force
        # structure_response from rest: piecewise-linear force, exact in the eigen-basis
        lam_h = eigenvalues * h[:, None]  # (N, 2n)
        small = np.abs(lam_h) < 1e-2
        safe = np.where(small, 1.0, lam_h)
        grown = np.exp(lam_h) - 1.0
        hh = h[:, None]
        total = np.where(
            small,
            hh * (1 + lam_h / 2 + lam_h**2 / 6 + lam_h**3 / 24),
            hh * grown / safe,
        )
        phi_b = np.where(
            small,
            hh * (0.5 + lam_h / 6 + lam_h**2 / 24 + lam_h**3 / 120),
            hh * (grown - lam_h) / safe**2,
        )
        phi_a = total - phi_b
        beta = self.load @ inverse[:, n:].T  # (N, 2n)
        increments = (beta * phi_a)[:, :, None] * force[:, None, :-1] + (beta * phi_b)[
            :, :, None
        ] * force[:, None, 1:]
        growth = np.exp(eigenvalues[None, :, None] * (t - t[:, :1])[:, None, :])
        modal = np.zeros(growth.shape, dtype=complex)
        modal[:, :, 1:] = growth[:, :, 1:] * np.cumsum(increments / growth[:, :, 1:], axis=2)
        x = np.matmul(vectors, modal).real  # (N, 2n, nodes)
        q, qd = x[:, :n], x[:, n:]
        m_inv = structure.inv_mass
        qdd = self.load[:, :, None] * force[:, None, :] - np.matmul(
            m_inv, np.matmul(structure.damping, qd) + np.matmul(structure.stiffness, q)
        )
        shape = self.shape[:, :, None]
        z = -(shape * q).sum(axis=1) - self._rows(0) * self.length_m[:, None]
        zd = -(shape * qd).sum(axis=1) - self._rows(1) * self.approach_mps[:, None]
        steps = np.diff(t, axis=1)
        zdd = _gradient_rows(zd, steps)
        values = np.concatenate([q, qd, z[:, None], zd[:, None]], axis=1)
        slopes = np.concatenate([qd, qdd, zd[:, None], zdd[:, None]], axis=1)
        linear = np.concatenate([qdd, force[:, None]], axis=1)
        v0, v1 = values[:, :, :-1], values[:, :, 1:]
        m0, m1 = slopes[:, :, :-1] * steps[:, None], slopes[:, :, 1:] * steps[:, None]
        a0, a1 = linear[:, :, :-1], linear[:, :, 1:]
        zero = np.zeros_like(a0)
        coefficients = np.stack(
            [
                np.concatenate([v0, a0], axis=1),
                np.concatenate([m0, a1 - a0], axis=1),
                np.concatenate([3.0 * (v1 - v0) - 2.0 * m0 - m1, zero], axis=1),
                np.concatenate([2.0 * (v0 - v1) + m0 + m1, zero], axis=1),
            ],
            axis=1,
        )  # (N, 4, 3n + 3, steps)
        return np.ascontiguousarray(coefficients.transpose(0, 3, 1, 2))

    @cached_property
    def _free_amplitude(self) -> tuple[np.ndarray, np.ndarray]:
        """(N, 2n, k) twice: each impact's free response after its contact as the weights of
        the half spectrum's exponentials (``LinearStructure.propagate``), real and imaginary
        parts."""
        _, vectors, inverse = self.structure._eigen
        keep, _, _, weight = self.structure._half_spectrum
        modal = np.concatenate([self.end_q, self.end_qd], axis=1) @ inverse.T
        amplitude = vectors[:, keep][None] * (weight * modal[:, keep])[:, None, :]
        return np.ascontiguousarray(amplitude.real), np.ascontiguousarray(amplitude.imag)

    def sample(
        self,
        rows: np.ndarray,
        t_s: np.ndarray,
        blocks: Sequence[tuple[slice, np.ndarray | None, np.ndarray | None]] = (),
    ) -> FamilyStates:
        """The states of impact ``rows[i]`` (S,) at its trajectory times ``t_s[i]`` (S, T):
        q-like fields (n, S, T), the others (S, T).

        ``blocks``: (columns, grid (C,), shift (S,)) for spans of columns whose instants are
        ``grid[j] - shift[i]`` (a sensor's stamps less each scene's contact instant): there the
        free response is evaluated as a product of the exponentials of the grid and of the
        shifts (:meth:`_free_on_grid`); elsewhere, or with grid None, instant by instant."""
        n = self.n
        structure = self.structure
        g = self.gravity_mps2
        duration = self.duration_s[rows][:, None]
        dt = t_s - duration
        state = np.empty((2 * n,) + t_s.shape)
        covered = np.zeros(t_s.shape[1], dtype=bool)
        for columns, grid, shift in blocks:
            if grid is None:
                continue
            free = self._free_on_grid(rows, grid, shift)
            if free is not None:
                state[:, :, columns] = free
                covered[columns] = True
        if not covered.all():
            rest = ~covered
            state[:, :, rest] = self._free_direct(rows, dt[:, rest])
        q, qd = state[:n], state[n:]
        flat = (n, t_s.size)
        internal = _columnwise(structure.damping, qd.reshape(flat)) + _columnwise(
            structure.stiffness, q.reshape(flat)
        )
        qdd = -_columnwise(structure.inv_mass, internal).reshape(q.shape)
        end_z, end_zd = self.end_z_m[rows][:, None], self.end_zd_mps[rows][:, None]
        out = FamilyStates(
            q,
            qd,
            qdd,
            np.zeros(t_s.shape),
            end_z + end_zd * dt - 0.5 * g * dt * dt,
            end_zd - g * dt,
        )
        before = t_s < 0.0
        if before.any():
            # at rest before the contact, the particle falling at its approach speed
            i, k = np.nonzero(before)
            t = t_s[i, k]
            out.q[:, i, k] = 0.0
            out.qd[:, i, k] = 0.0
            out.qdd[:, i, k] = 0.0
            speed = self.speed_mps[rows[i]]
            out.z_m[i, k] = 0.0 + (-speed) * t - 0.5 * g * t * t
            out.zd_mps[i, k] = -speed - g * t
        during = ~before & (dt < 0.0)
        if during.any():
            i, k = np.nonzero(during)
            self._sample_contact(rows[i], t_s[i, k], out, (i, k))
        return out

    def _free_direct(self, rows: np.ndarray, dt: np.ndarray) -> np.ndarray:
        """(2n, S, T): the free response ``dt`` (S, T) after each contact's end, instant by
        instant (``LinearStructure.propagate``'s arithmetic)."""
        _, sigma, omega, _ = self.structure._half_spectrum
        real, imag = self._free_amplitude
        state = None
        for j in range(sigma.size):
            growth = np.exp(sigma[j] * dt)
            term = real[rows, :, j].T[:, :, None] * (growth * np.cos(omega[j] * dt)) - imag[
                rows, :, j
            ].T[:, :, None] * (growth * np.sin(omega[j] * dt))
            state = term if state is None else state + term
        return state

    def _free_on_grid(
        self, rows: np.ndarray, grid: np.ndarray, shift: np.ndarray
    ) -> np.ndarray | None:
        """(2n, S, C): the free response at instants ``grid[j] - shift[i]``, each term
        w exp(lambda (t - T)) written as (w exp(-lambda (shift + T))) exp(lambda grid): one
        exponential per scene and one per grid instant instead of one per pair, equal to the
        instant-by-instant form to rounding (about 1e-13 of the signal). None where a factor
        could overflow (a strongly damped mode and long shifts)."""
        eigenvalues = self.structure._eigen[0][self.structure._half_spectrum[0]]
        offset = shift + self.duration_s[rows]
        sigma = eigenvalues.real
        if (
            np.max(np.abs(np.multiply.outer(offset, sigma)), initial=0.0) > 300.0
            or np.max(np.abs(np.multiply.outer(grid, sigma)), initial=0.0) > 300.0
        ):
            return None
        real, imag = self._free_amplitude
        weights = (real[rows] + 1j * imag[rows]) * np.exp(-np.multiply.outer(offset, eigenvalues))[
            :, None, :
        ]  # (S, 2n, k)
        basis = np.exp(np.multiply.outer(eigenvalues, grid))  # (k, C)
        state = np.matmul(weights.real, basis.real) - np.matmul(weights.imag, basis.imag)
        return state.transpose(1, 0, 2)

    def _sample_contact(
        self,
        rows: np.ndarray,
        t_s: np.ndarray,
        out: FamilyStates,
        where: tuple[np.ndarray, np.ndarray],
    ) -> None:
        """The cubic Hermite through the pulse's samples (``Trajectory._sample_contact``) at
        (impact, instant) pairs within their contacts."""
        nodes = self.node_times
        last = PULSE_NODES - 1
        guess = np.clip((t_s / self.duration_s[rows] * PULSE_NODES).astype(np.int64), 0, last)
        # the step k with nodes[k] <= t < nodes[k + 1] (searchsorted's, on the same floats)
        guess -= (nodes[rows, guess] > t_s) & (guess > 0)
        guess += (nodes[rows, np.minimum(guess + 1, PULSE_NODES)] <= t_s) & (guess < last)
        k = guess
        start = nodes[rows, k]
        h = nodes[rows, k + 1] - start
        s = np.where(h > 0, (t_s - start) / np.where(h > 0, h, 1.0), 0.0)
        c = self._polynomials[rows, k]  # (M, 4, 3n + 3)
        x = s[:, None]
        y = (c[:, 0] + x * (c[:, 1] + x * (c[:, 2] + x * c[:, 3]))).T
        n = self.n
        i, j = where
        out.q[:, i, j], out.qd[:, i, j] = y[:n], y[n : 2 * n]
        out.z_m[i, j], out.zd_mps[i, j] = y[2 * n], y[2 * n + 1]
        out.qdd[:, i, j], out.force_n[i, j] = y[2 * n + 2 : 3 * n + 2], y[3 * n + 2]

    def trajectory(self, i: int) -> Trajectory:
        """Impact ``i``'s trajectory, as the hybrid solver gives it (``ok[i]`` must hold); one
        object per impact, however often asked."""
        known = self._trajectories.get(i)
        if known is None:
            known = self._trajectories[i] = self._build_trajectory(i)
        return known

    def _build_trajectory(self, i: int) -> Trajectory:
        problem = self.problems[i]
        n = self.n
        duration = float(self.duration_s[i])
        pulse = Pulse.__new__(Pulse)
        pulse.row, pulse.weight = int(self.row[i]), float(self.weight[i])
        pulse.length_m, pulse.approach_mps = float(self.length_m[i]), float(self.approach_mps[i])
        pulse.force_scale_n = float(self.force_scale_n[i])
        pulse.duration_s, pulse.separation_mps = duration, float(self.separation_mps[i])
        pulse.peak_force_n = float(self.peak_force_n[i])
        pulse.max_penetration_m = float(self.max_penetration_m[i])
        x0 = np.zeros(2 * n)
        segment = PulseSegment(problem, 0.0, x0, pulse)
        q, qd = self.end_q[i].copy(), self.end_qd[i].copy()
        z, zd = float(self.end_z_m[i]), float(self.end_zd_mps[i])
        segment.end_state = (q, qd, z, zd)
        segment.end_modal = self.end_modal[i]
        speed = problem.impact_speed_mps
        estimate = float(self.estimate[i])
        return Trajectory(
            problem,
            [
                FreeSegment(-math.inf, 0.0, 0.0, x0[:n], x0[n:], 0.0, -speed),
                segment,
                FreeSegment(duration, math.inf, duration, q, qd, z, zd),
            ],
            [ContactRecord(0.0, duration, float(self.approach_mps[i]), zd, pulse.peak_force_n)],
            "hybrid",
            max(0.0, estimate),
            particle_at_rest=False,
            stats={
                "pulse_contacts": 1,
                "rk4_contacts": 0,
                "rk4_steps": 0,
                "pulse_error_estimate": max(0.0, estimate),
            },
        )


def _columnwise(matrix: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``matrix @ values`` summed term by term (``problem._columnwise``)."""
    out = matrix[:, :1] * values[0]
    for j in range(1, matrix.shape[1]):
        out = out + matrix[:, j : j + 1] * values[j]
    return out


def _gradient_rows(values: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """``problem._gradient`` of each row of ``values`` (N, T) on its own ``steps`` (N, T - 1):
    the uniform-step formula on rows whose steps are all equal, the general one elsewhere."""
    out = np.empty_like(values)
    uniform = (steps == steps[:, :1]).all(axis=1)
    step = steps[:, :1]
    even = (values[:, 2:] - values[:, :-2]) / (2.0 * step)
    dx1, dx2 = steps[:, :-1], steps[:, 1:]
    a = -(dx2) / (dx1 * (dx1 + dx2))
    b = (dx2 - dx1) / (dx1 * dx2)
    c = dx1 / (dx2 * (dx1 + dx2))
    uneven = a * values[:, :-2] + b * values[:, 1:-1] + c * values[:, 2:]
    out[:, 1:-1] = np.where(uniform[:, None], even, uneven)
    out[:, 0] = (values[:, 1] - values[:, 0]) / steps[:, 0]
    out[:, -1] = (values[:, -1] - values[:, -2]) / steps[:, -1]
    return out
