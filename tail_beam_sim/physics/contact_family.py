"""Many impacts that each make one contact, solved and sampled at once.

The hybrid solver (:mod:`~tail_beam_sim.physics.solvers.hybrid`) takes most impacts as one
contact, the beam starting at rest and the particle never caught again within the window: the
pre-integrated pulse when its error estimate allows, else the contact integrated by RK4. The
impact's motion is then the contact's samples and, after it, a closed form on the structure's
eigenvalues. :class:`ContactFamily` computes them for N impacts on one structure with one array
operation per quantity and the solver's own arithmetic (the pulse's end state and samples in
closed form; the RK4 contacts in lockstep, :mod:`~tail_beam_sim.physics.solvers.contact_batch`),
and marks the impacts that are not of that kind (``ok`` false: a particle coming to rest, a
re-contact possible within the window, a contact the solver would refine), which a caller
solves one by one. :meth:`ContactFamily.read` evaluates linear readings of the states at
(impact, instant) pairs from the states
:meth:`~tail_beam_sim.physics.solvers.problem.Trajectory.sample` gives: rest before the
contact, the cubic Hermite through the contact's samples during it, the exact free response
after it; :meth:`ContactFamily.trajectory` gives one impact's :class:`Trajectory`, the hybrid
solver's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from tail_beam_sim.physics.solvers.contact_batch import integrate_contacts
from tail_beam_sim.physics.solvers.dynamics import FloatDynamics
from tail_beam_sim.physics.solvers.hybrid import (
    DEFAULT_STEPS_PER_CONTACT,
    REST_SPEED_MPS,
    RK4_CONTACT_ERROR,
    PulseSegment,
    contact_phase,
)
from tail_beam_sim.physics.solvers.problem import (
    ContactRecord,
    ContactSegment,
    FreeSegment,
    ImpactProblem,
    SolverError,
    Trajectory,
)
from tail_beam_sim.physics.solvers.pulse import (
    PULSE_NODES,
    SERIES_RADIUS,
    Pulse,
    pulse_integral,
    pulse_table,
)
from tail_beam_sim.physics.structure import LinearStructure, reduced_mass_kg

# RK4 contacts integrated in lockstep from this many on (the lockstep's fixed cost, a few
# thousand array operations, is that of about this many contacts integrated one by one)
LOCKSTEP_MIN = 16


@dataclass
class Grid:
    """S x C instants to read (s from first contact), ``times``; when ``grid`` (G,) and
    ``shift`` (S,) are given, ``times[i, j] = grid[j] - shift[i]`` (a sensor's stamps less each
    scene's contact instant), or ``grid[index[i, j]] - shift[i]`` where ``index`` (S, C) is
    given and not negative."""

    times: np.ndarray
    grid: np.ndarray | None = None
    shift: np.ndarray | None = None
    index: np.ndarray | None = None
    key: tuple[Any, ...] | None = None  # names the grid (a sensor's rate and count): its
    # exponentials are kept per structure and key


_BASES: dict[tuple[int, tuple[Any, ...]], tuple[LinearStructure, np.ndarray]] = {}
BASIS_CACHE_SIZE = 64


def grid_basis(
    structure: LinearStructure, grid: np.ndarray, key: tuple[Any, ...] | None
) -> np.ndarray:
    """(k, G): exp(lambda t) of the structure's half spectrum at the instants ``grid`` (s);
    kept per structure and ``key`` (a sensor's grid depends on its settings only)."""
    eigenvalues = structure._eigen[0][structure._half_spectrum[0]]
    if key is None:
        return np.exp(np.multiply.outer(eigenvalues, grid))
    cached = _BASES.get((id(structure), key))
    if cached is not None and cached[0] is structure:
        return cached[1]
    basis = np.exp(np.multiply.outer(eigenvalues, grid))
    if len(_BASES) >= BASIS_CACHE_SIZE:
        _BASES.clear()
    _BASES[(id(structure), key)] = (structure, basis)  # holding it keeps its id from reuse
    return basis


class ContactFamily:
    """N impacts on one structure, each one contact from rest at t = 0 (module docstring).

    Arrays over impacts (SI): ``pulse`` (whether the contact is the pulse, else RK4),
    ``duration_s``, ``peak_force_n``, ``estimate`` (the solver's relative error estimate),
    the state as the contact ends (``end_q``, ``end_qd`` (N, n), ``end_z_m``, ``end_zd_mps``)
    and ``ok``."""

    def __init__(
        self,
        problems: Sequence[ImpactProblem],
        pulse_tolerance: float,
        steps_per_contact: int = DEFAULT_STEPS_PER_CONTACT,
    ) -> None:
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
        self.end_q, self.end_qd = x_end[:, :n].copy(), x_end[:, n:].copy()
        internal_rows = shape @ structure.modal_internal
        impulse = reduced * (approach + separation)
        neglected = abs(self.gravity_mps2) + np.einsum(
            "ij,ij->i", np.abs(internal_rows), np.abs(beta) * impulse[:, None]
        )
        self.estimate = neglected * np.maximum(
            duration / approach, duration * duration / (2.0 * max_penetration)
        )
        self.end_zd_mps = -np.einsum("ij,ij->i", shape, self.end_qd) + separation
        self.end_z_m = -np.einsum("ij,ij->i", shape, self.end_q)
        finite = np.isfinite(self.estimate) & np.isfinite(x_end).all(axis=1)
        elastic = (chi <= table.chi[-1]) & np.array([p.crushing is None for p in problems])
        self.pulse = elastic & finite & (self.estimate <= pulse_tolerance)
        self.integrated: dict[int, tuple[np.ndarray, ...]] = {}
        ok = self.pulse.copy()
        rk4 = np.flatnonzero(elastic & ~self.pulse)
        if rk4.size:
            ok[rk4] = self._integrate(rk4, steps_per_contact)
        duration = self.duration_s
        plate_speed = np.einsum("ij,ij->i", shape, self.end_qd)
        separating = self.end_zd_mps + plate_speed
        # a bound on the plate's later speed (hybrid.plate_speed_bound_mps): the particle is
        # not caught again within the window when it flies off faster than the plate can follow
        bound = np.abs((shape @ vectors[n:]) * self.end_modal).sum(axis=1)
        window = self.window_s
        never_again = self.end_zd_mps - bound > 0.5 * self.gravity_mps2 * (window - duration)
        self.ok = (
            ok
            & (separating >= REST_SPEED_MPS)
            & (duration < window)
            & never_again
            & np.isfinite(self.end_q).all(axis=1)
            & np.isfinite(self.end_qd).all(axis=1)
        )

    def _integrate(self, which: np.ndarray, steps: int) -> np.ndarray:
        """Integrate the contacts of impacts ``which`` by RK4 (the hybrid solver's, for those
        the pulse does not cover: in lockstep over them when they are LOCKSTEP_MIN or more,
        else one by one, whose fixed cost is smaller) and take their end states; returns which
        are ``ok``."""
        n = self.n
        _, _, inverse = self.structure._eigen
        problems = [self.problems[i] for i in which]
        if which.size >= LOCKSTEP_MIN:
            contacts = integrate_contacts(problems, steps)
            ok = contacts.ok
            found = zip(
                contacts.t_s,
                contacts.states,
                contacts.derivatives,
                contacts.force_n,
                contacts.approach_mps,
                contacts.peak_force_n,
            )
        else:
            ok = np.ones(which.size, dtype=bool)
            found = []
            for k, problem in enumerate(problems):
                dynamics = FloatDynamics(problem)
                start = dynamics.state(problem.q0, problem.qd0, 0.0, -problem.impact_speed_mps)
                try:
                    segment, record = contact_phase(problem, dynamics, 0.0, start, steps)
                except SolverError:
                    ok[k] = False
                    found.append((None,) * 6)
                    continue
                states = np.vstack([segment.q, segment.qd, segment.z_m, segment.zd_mps]).T
                derivatives = np.vstack(
                    [segment.qd, segment.qdd, segment.zd_mps, np.zeros(segment.t_s.size)]
                ).T
                found.append(
                    (
                        segment.t_s,
                        states,
                        derivatives,
                        segment.force_n,
                        record.approach_speed_mps,
                        record.peak_force_n,
                    )
                )
        for k, (i, (t, states, derivatives, force, approach, peak)) in enumerate(
            zip(which, found)
        ):
            if not ok[k]:
                continue
            end = states[-1]
            self.end_q[i], self.end_qd[i] = end[:n], end[n : 2 * n]
            self.end_z_m[i], self.end_zd_mps[i] = end[2 * n], end[2 * n + 1]
            self.duration_s[i] = t[-1]
            self.peak_force_n[i] = peak
            self.approach_mps[i] = approach
            self.estimate[i] = RK4_CONTACT_ERROR
            self.end_modal[i] = inverse @ end[: 2 * n]
            self.integrated[int(i)] = (t, states, derivatives, force)
        return ok

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
            times = pulse_table().fractions * self.duration_s[i]
            out[i] = pulse_integral(eigenvalues, times, self._rows(2)[i] * self.force_scale_n[i])
        return out

    @property
    def size(self) -> int:
        return len(self.problems)

    @cached_property
    def _contact_nodes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every impact's contact samples, padded to the longest: their instants (N, P) (s from
        contact start, +inf past the last), [q; q'] and [q'; q''] at them (N, P, 2n) each (zero
        past the last), the count of samples (N,) and a nominal step (N,) s. The cubic Hermite
        of a step (:meth:`_contact_states`) is formed from them where it is read."""
        size, n = self.size, self.n
        pulses = np.flatnonzero(self.pulse)
        integrated = sorted(self.integrated)
        width = max([PULSE_NODES + 1] + [self.integrated[i][0].size for i in integrated])
        nodes = np.full((size, width), np.inf)
        values = np.zeros((size, width, 2 * n))  # [q; q'] at the samples
        slopes = np.zeros((size, width, 2 * n))  # [q'; q'']
        counts = np.full(size, 2, dtype=np.int64)
        step = np.ones(size)
        if pulses.size:
            times = pulse_table().fractions * self.duration_s[pulses, None]
            nodes[pulses, : PULSE_NODES + 1] = times
            q, qd, qdd = self._pulse_states(pulses, times)
            values[pulses, : PULSE_NODES + 1] = np.concatenate([q, qd], axis=1).transpose(0, 2, 1)
            slopes[pulses, : PULSE_NODES + 1] = np.concatenate([qd, qdd], axis=1).transpose(
                0, 2, 1
            )
            counts[pulses] = PULSE_NODES + 1
            step[pulses] = self.duration_s[pulses] / PULSE_NODES
        for i in integrated:
            t, states, derivatives, _ = self.integrated[i]
            nodes[i, : t.size] = t
            values[i, : t.size] = states[:, : 2 * n]
            slopes[i, : t.size] = derivatives[:, : 2 * n]
            counts[i] = t.size
            step[i] = t[1] - t[0]
        return nodes, values, slopes, counts, step

    @property
    def contact_times(self) -> np.ndarray:
        """(N, P): every impact's contact samples, s from contact start (+inf past the last)."""
        return self._contact_nodes[0]

    def _rows(self, k: int) -> np.ndarray:
        rows = pulse_table().rows
        w = self.weight[:, None]
        return (1 - w) * rows[self.row, k] + w * rows[self.row + 1, k]

    def _pulse_states(
        self, which: np.ndarray, t: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q, q', q'' (W, n, samples) of impacts ``which`` (pulse contacts) at their pulse's
        samples ``t`` (``hybrid.PulseSegment``: the structure driven by the piecewise-linear
        pulse, exact in its eigen-basis)."""
        structure = self.structure
        n = self.n
        eigenvalues, vectors, inverse = structure._eigen
        h = t[:, 1] - t[:, 0]
        force = self._rows(2)[which] * self.force_scale_n[which, None]
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
        beta = self.load[which] @ inverse[:, n:].T  # (N, 2n)
        increments = (beta * phi_a)[:, :, None] * force[:, None, :-1] + (beta * phi_b)[
            :, :, None
        ] * force[:, None, 1:]
        growth = np.exp(eigenvalues[None, :, None] * (t - t[:, :1])[:, None, :])
        modal = np.zeros(growth.shape, dtype=complex)
        modal[:, :, 1:] = growth[:, :, 1:] * np.cumsum(increments / growth[:, :, 1:], axis=2)
        x = np.matmul(vectors, modal).real  # (N, 2n, nodes)
        q, qd = x[:, :n], x[:, n:]
        m_inv = structure.inv_mass
        qdd = self.load[which, :, None] * force[:, None, :] - np.matmul(
            m_inv, np.matmul(structure.damping, qd) + np.matmul(structure.stiffness, q)
        )
        return q, qd, qdd

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

    def read(self, rows: np.ndarray, grid: Grid, readings: np.ndarray) -> np.ndarray:
        """(o, S, C): the readings ``readings`` (o, 3n: weights of [q; q'; q'']) of impact
        ``rows[i]`` (S,) at the instants ``grid.times[i]`` (S, C), from the states
        ``Trajectory.sample`` gives: at rest before the contact, the cubic Hermite through the
        contact's samples during it, the free response after it.

        The free response is read through each reading's own projection of the modal
        amplitudes (q'' = -M^-1 (K q + C q') there); where the grid says its instants are a
        common grid less each scene's shift, it is a product of the grid's and the scenes'
        exponentials (:meth:`_read_on_grid`), elsewhere evaluated instant by instant."""
        n = self.n
        readings = np.atleast_2d(readings)
        weights = self.free_weights(rows, readings)
        times = grid.times
        dt = times - self.duration_s[rows][:, None]
        out = None
        if grid.grid is not None:
            out = self._read_on_grid(rows, grid, weights)
        if out is None:
            out = self._read_direct(weights, dt)
        elif grid.index is not None:
            off = (grid.index < 0) & (dt >= 0.0)
            if off.any():
                i, k = np.nonzero(off)
                out[:, i, k] = self._read_direct(weights[:, i], dt[i, k])
        before = times < 0.0
        if before.any():  # at rest before the contact
            np.copyto(out, 0.0, where=before)
        during = ~before & (dt < 0.0)
        if during.any():
            i, k = np.nonzero(during)
            accel = bool(np.any(readings[:, 2 * n :]))
            values = readings[:, : 3 * n if accel else 2 * n] @ self._contact_states(
                rows[i], times[i, k], accel
            )
            if out.flags.c_contiguous:  # one flat index per pair: a one-axis scatter
                out.reshape(out.shape[0], -1)[:, i * out.shape[2] + k] = values
            else:
                out[:, i, k] = values
        return out

    def read_at_samples(self, rows: np.ndarray, readings: np.ndarray) -> np.ndarray:
        """(o, S, P): :meth:`read` at each impact's contact samples (``contact_times[rows]``;
        nan past an impact's last). There the cubic Hermite is the sample's own state, taken
        as it is; the last sample, the contact's end, is read from the free response."""
        nodes, values, slopes, counts, _ = self._contact_nodes
        readings = np.atleast_2d(readings)
        n = self.n
        accel = bool(np.any(readings[:, 2 * n :]))
        width = 3 * n if accel else 2 * n
        count = rows.size
        steps = nodes.shape[1] - 1
        # each step's value at its start: the state at its first sample ([q; q'] and q'')
        states = values[rows, :steps]  # (S, P - 1, width)
        if accel:
            states = np.concatenate([states, slopes[rows, :steps, n:]], axis=2)
        out = np.full((readings.shape[0], count, steps + 1), np.nan)
        out[:, :, :steps] = (readings[:, :width] @ states.reshape(-1, width).T).reshape(
            -1, count, steps
        )
        last = counts[rows] - 1
        out[:, np.arange(count), last] = self.read(
            rows, Grid(self.duration_s[rows][:, None]), readings
        )[:, :, 0]
        past = np.arange(steps + 1)[None, :] > last[:, None]
        out[:, past] = np.nan
        return out

    def free_weights(self, rows: np.ndarray, readings: np.ndarray) -> np.ndarray:
        """(o, S, k): the readings ``readings`` (o, 3n) of impact ``rows[i]``'s free response
        after its contact as weights w of the half spectrum's exponentials: the reading at
        time t (s from first contact) is sum_k Re(w_k exp(lambda_k (t - duration)))."""
        n = self.n
        structure = self.structure
        readings = np.atleast_2d(readings)
        # the free response's q'' in terms of [q; q']
        free = readings[:, : 2 * n] - readings[:, 2 * n :] @ (
            structure.inv_mass @ np.hstack([structure.stiffness, structure.damping])
        )
        real, imag = self._free_amplitude  # (N, 2n, k)
        return np.einsum("oc,sck->osk", free, real[rows]) + 1j * np.einsum(
            "oc,sck->osk", free, imag[rows]
        )

    def _read_direct(self, weights: np.ndarray, dt: np.ndarray) -> np.ndarray:
        """(o, *dt.shape): sum_k Re(w_k exp(lambda_k dt)) of ``weights`` (o, S, k) after each
        contact's end, instant by instant (``LinearStructure.propagate``'s arithmetic)."""
        _, sigma, omega, _ = self.structure._half_spectrum
        out = None
        for j in range(sigma.size):
            growth = np.exp(sigma[j] * dt)
            a, b = weights.real[:, :, j], weights.imag[:, :, j]
            if dt.ndim == 2:
                a, b = a[:, :, None], b[:, :, None]
            term = a * (growth * np.cos(omega[j] * dt)) - b * (growth * np.sin(omega[j] * dt))
            out = term if out is None else out + term
        return out

    def _read_on_grid(
        self, rows: np.ndarray, grid: Grid, weights: np.ndarray
    ) -> np.ndarray | None:
        """(o, S, C): the free response's readings at instants ``grid[j] - shift[i]`` (or
        ``grid[index[i, j]] - shift[i]``), each term w exp(lambda (t - T)) written as
        (w exp(-lambda (shift + T))) exp(lambda grid): one exponential per scene and one per
        grid instant instead of one per pair, equal to the instant-by-instant form to rounding
        (about 1e-13 of the signal). None where a factor could overflow (a strongly damped mode
        and long shifts)."""
        structure = self.structure
        eigenvalues = structure._eigen[0][structure._half_spectrum[0]]
        offset = grid.shift + self.duration_s[rows]
        fastest = float(np.max(np.abs(eigenvalues.real), initial=0.0))
        reach = max(float(np.max(np.abs(offset), initial=0.0)), abs(float(grid.grid[0])))
        if fastest * max(reach, abs(float(grid.grid[-1]))) > 300.0:
            return None
        shifted = weights * np.exp(-np.multiply.outer(offset, eigenvalues))[None]  # (o, S, k)
        basis = grid_basis(structure, grid.grid, grid.key)  # (k, G)
        if grid.index is None:  # one product over the spectrum for every reading and scene
            flat = shifted.reshape(-1, eigenvalues.size)
            out = _product(flat.real, basis.real) - _product(flat.imag, basis.imag)
            return out.reshape(shifted.shape[:2] + (basis.shape[1],))
        at = np.maximum(grid.index, 0)
        out = None
        for j in range(eigenvalues.size):
            re, im = basis.real[j][at], basis.imag[j][at]  # (S, C)
            term = shifted.real[:, :, j, None] * re - shifted.imag[:, :, j, None] * im
            out = term if out is None else out + term
        return out

    def _contact_states(self, rows: np.ndarray, t_s: np.ndarray, accel: bool) -> np.ndarray:
        """(2n or 3n, M): [q; q'] (and q'' when ``accel``) of impacts ``rows`` at instants
        ``t_s`` within their contacts: the cubic Hermite through the contact's samples (q''
        the straight line; ``Trajectory._sample_contact``)."""
        nodes, values, slopes, counts, step = self._contact_nodes
        width = nodes.shape[1]
        # (impact, sample) pairs as flat indices into the (N * P) samples: one-axis gathers
        flat_nodes = nodes.reshape(-1)
        base = rows * width
        last = counts[rows] - 2
        guess = np.minimum(np.maximum((t_s / step[rows]).astype(np.int64), 0), last)
        # the step k with nodes[k] <= t < nodes[k + 1] (searchsorted's, on the same floats)
        guess -= (flat_nodes.take(base + guess) > t_s) & (guess > 0)
        guess += (flat_nodes.take(base + guess + 1) <= t_s) & (guess < last)
        at = base + guess
        start = flat_nodes.take(at)
        h = flat_nodes.take(at + 1) - start
        s = np.where(h > 0, (t_s - start) / np.where(h > 0, h, 1.0), 0.0)
        n = self.n
        # the step's cubic Hermite of [q; q'] (values v, slopes times the step m) and straight
        # line of q'' (a), as Trajectory._stacks forms them
        flat_values = values.reshape(-1, 2 * n)
        flat_slopes = slopes.reshape(-1, 2 * n)
        v0, v1 = flat_values.take(at, axis=0), flat_values.take(at + 1, axis=0)  # (M, 2n)
        d0, d1 = flat_slopes.take(at, axis=0), flat_slopes.take(at + 1, axis=0)
        # h and s repeated along the 2n columns: operands of one shape run as one loop over
        # all their values (a broadcast column would loop over 2n at a time)
        h = np.repeat(h[:, None], 2 * n, axis=1)
        m0, m1 = d0 * h, d1 * h
        c0, c1 = v0, m0
        c2 = 3.0 * (v1 - v0) - 2.0 * m0 - m1
        c3 = 2.0 * (v0 - v1) + m0 + m1
        if accel:
            a0, a1 = d0[:, n:], d1[:, n:]
            zero = np.zeros_like(a0)
            c0 = np.concatenate([c0, a0], axis=1)
            c1 = np.concatenate([c1, a1 - a0], axis=1)
            c2 = np.concatenate([c2, zero], axis=1)
            c3 = np.concatenate([c3, zero], axis=1)
        x = np.repeat(s[:, None], c0.shape[1], axis=1)
        return (c0 + x * (c1 + x * (c2 + x * c3))).T

    def trajectory(self, i: int) -> Trajectory:
        """Impact ``i``'s trajectory, as the hybrid solver gives it (``ok[i]`` must hold); one
        object per impact, however often asked."""
        known = self._trajectories.get(i)
        if known is None:
            known = self.trajectories([i])[0]
        return known

    def trajectories(self, rows: Sequence[int]) -> list[Trajectory]:
        """:meth:`trajectory` of each of ``rows``; those not yet made are made together, each
        array of the family read once for all of them (as Python numbers: the same values)."""
        known = self._trajectories
        missing = [i for i in dict.fromkeys(rows) if i not in known]
        if missing:
            at = np.array(missing, dtype=np.int64)
            ends = zip(
                self.end_q[at],
                self.end_qd[at],
                self.end_z_m[at].tolist(),
                self.end_zd_mps[at].tolist(),
                self.end_modal[at],
            )
            numbers = zip(
                self.duration_s[at].tolist(),
                self.peak_force_n[at].tolist(),
                self.estimate[at].tolist(),
                self.approach_mps[at].tolist(),
                self.row[at].tolist(),
                self.weight[at].tolist(),
                self.length_m[at].tolist(),
                self.force_scale_n[at].tolist(),
                self.separation_mps[at].tolist(),
                self.max_penetration_m[at].tolist(),
            )
            for i, end, figures in zip(missing, ends, numbers):
                known[i] = self._build_trajectory(i, end, figures)
        return [known[i] for i in rows]

    def _build_trajectory(
        self, i: int, end: tuple[Any, ...], figures: tuple[Any, ...]
    ) -> Trajectory:
        """Impact ``i``'s trajectory from its end state ``end`` (q, q' (n,) each, z, z',
        modal state) and its contact's ``figures`` (duration, peak force, estimate, approach
        speed, and the pulse's table row, weight, length, force scale, separation speed and
        largest penetration)."""
        problem = self.problems[i]
        n = self.n
        x0 = np.zeros(2 * n)
        q, qd, z, zd, modal = end
        (
            duration,
            peak,
            estimate,
            approach,
            row,
            weight,
            length,
            force_scale,
            separation,
            penetration,
        ) = figures
        if i in self.integrated:
            t, states, derivatives, force = self.integrated[i]
            segment: ContactSegment | PulseSegment = ContactSegment(
                t_s=t,
                q=states[:, :n].T,
                qd=states[:, n : 2 * n].T,
                qdd=derivatives[:, n : 2 * n].T,
                z_m=states[:, 2 * n],
                zd_mps=states[:, 2 * n + 1],
                force_n=force,
            )
            stats = {
                "pulse_contacts": 0,
                "rk4_contacts": 1,
                "rk4_steps": t.size - 1,
                "pulse_error_estimate": 0.0,
            }
        else:
            pulse = Pulse.__new__(Pulse)
            pulse.row, pulse.weight = row, weight
            pulse.length_m = length
            pulse.approach_mps = approach
            pulse.force_scale_n = force_scale
            pulse.duration_s, pulse.separation_mps = duration, separation
            pulse.peak_force_n = peak
            pulse.max_penetration_m = penetration
            segment = PulseSegment(problem, 0.0, x0, pulse)
            segment.end_state = (q, qd, z, zd)
            segment.end_modal = modal
            stats = {
                "pulse_contacts": 1,
                "rk4_contacts": 0,
                "rk4_steps": 0,
                "pulse_error_estimate": max(0.0, estimate),
            }
        return Trajectory(
            problem,
            [
                FreeSegment(-math.inf, 0.0, 0.0, x0[:n], x0[n:], 0.0, -problem.impact_speed_mps),
                segment,
                FreeSegment(duration, math.inf, duration, q, qd, z, zd),
            ],
            [ContactRecord(0.0, duration, approach, zd, peak)],
            "hybrid",
            max(0.0, estimate),
            particle_at_rest=False,
            stats=stats,
        )


def _product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` over a short inner dimension (the spectrum's), in numpy's own loop rather
    than BLAS: on a shared machine a threaded BLAS waits for its threads at every call, which
    costs more than these products."""
    return np.einsum("ik,kc->ic", a, b)
