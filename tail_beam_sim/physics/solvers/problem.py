"""What a solver is given (:class:`ImpactProblem`) and what it returns (:class:`Trajectory`).

Times are seconds from the first contact (t = 0), when the particle, falling at
``impact_speed_mps``, touches the undeformed plate. The particle's position ``z_m`` is its
lowest point along the plate's outward normal, zero at the undeformed plate; the plate under
it is displaced by ``contact_shape @ q`` away from it, so the penetration is
``delta = -(contact_shape @ q) - z``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from tail_beam_sim.physics.contact import CrushingContact
from tail_beam_sim.physics.solvers.lazy import lazy
from tail_beam_sim.physics.structure import LinearStructure, reduced_mass_kg


class SolverError(RuntimeError):
    """A solve failed: the solver could not deliver a trustworthy result for this problem.

    Raised instead of returning a wrong answer (a diverged step, energy gained in a contact,
    a step beyond the stability limit, a problem outside the method's range). It is not bad
    input (an option out of range is :class:`~tail_beam_sim.errors.InputError`): the command
    line exits with its own status (3) and a node logs it and keeps running. The message is
    one line, ``<solver>: <what went wrong and what to change>``.
    """

    def __init__(self, solver: str, reason: str) -> None:
        self.solver = solver
        self.reason = reason
        super().__init__(f"{solver}: {reason}")


@dataclass(frozen=True)
class ImpactProblem:
    """One particle striking a linear structure through a Hertz contact with hysteresis.

    ``crushing`` (None by default) switches the contact to the brittle law of
    :class:`~tail_beam_sim.physics.contact.CrushingContact`, which replaces the hysteresis.
    """

    structure: LinearStructure
    contact_shape: np.ndarray
    mass_kg: float
    hertz_stiffness: float
    damping_factor: float
    impact_speed_mps: float
    gravity_mps2: float
    window_s: float
    q0: np.ndarray
    qd0: np.ndarray
    crushing: CrushingContact | None = None

    @lazy
    def contact_load(self) -> np.ndarray:
        """M^-1 b: the structure's acceleration per newton at the contact point (kept: the
        problem is frozen)."""
        return np.dot(self.structure.inv_mass, self.contact_shape)

    @lazy
    def reduced_mass_kg(self) -> float:
        """The particle's and the plate's effective mass at the contact point, in series, kg."""
        # Written with the compliance b^T M^-1 b, so that it stays finite over the hinge (a
        # rigid wall: compliance 0, the particle's own mass).
        return float(
            reduced_mass_kg(self.mass_kg, float(np.dot(self.contact_shape, self.contact_load)))
        )


@dataclass(frozen=True)
class ContactRecord:
    """One contact as it happened: start and end (s), speeds (m/s) and peak force (N)."""

    start_s: float
    end_s: float
    approach_speed_mps: float
    separation_speed_mps: float
    peak_force_n: float

    @property
    def duration_s(self) -> float:
        return self.end_s - self.start_s


@dataclass
class ContactSegment:
    """Dense solution of an integrated span (a contact, or a fixed-step solver's whole window):
    states at the solver's steps, sampled by cubic Hermite interpolation."""

    t_s: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    z_m: np.ndarray
    zd_mps: np.ndarray
    force_n: np.ndarray

    @property
    def start_s(self) -> float:
        return float(self.t_s[0])


@dataclass
class FreeSegment:
    """No contact: the structure rings freely and the particle flies under gravity.

    The state is known exactly at ``anchor_s``; the segment covers [start_s, end_s).
    """

    start_s: float
    end_s: float
    anchor_s: float
    q: np.ndarray
    qd: np.ndarray
    z_m: float
    zd_mps: float

    @lazy
    def at_rest(self) -> bool:
        """Whether the structure is at rest in this segment (q and qd all zero): it stays so."""
        return not (self.q.any() or self.qd.any())


@dataclass
class OdeSegment:
    """A free-flight span integrated by an adaptive solver, sampled through its dense output
    (``dense(t)`` returns the states [q, qd, z, zd] as columns) so that long steps of a
    high-order method are interpolated at the method's own order."""

    t_s: np.ndarray
    dense: Callable[[np.ndarray], np.ndarray]

    @property
    def start_s(self) -> float:
        return float(self.t_s[0])


@dataclass
class Samples:
    """The system's state at a set of times (arrays over time; q-like ones are (n, T))."""

    t_s: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    force_n: np.ndarray
    z_m: np.ndarray
    zd_mps: np.ndarray

    def take(self, where: slice) -> Samples:
        """The samples at positions ``where`` (views, not copies)."""
        return Samples(
            self.t_s[where],
            self.q[:, where],
            self.qd[:, where],
            self.qdd[:, where],
            self.force_n[where],
            self.z_m[where],
            self.zd_mps[where],
        )


@dataclass
class Trajectory:
    """The piecewise solution of an impact, evaluable at any time (before, during, after).

    The fields every solver fills are its contract (``tail_beam_sim.physics.solvers``):
    ``segments`` ordered by start time and covering the whole real line; ``contacts``, each
    contact in order; ``solver``, the registered name that produced it; ``error_estimate``, the
    solver's own relative error estimate of the trajectory (nan: it has none);
    ``particle_at_rest``, whether the particle ended lying on the plate. ``stats`` holds the
    solver's own counters, for reports only: nothing downstream reads them.
    """

    problem: ImpactProblem
    segments: list[ContactSegment | FreeSegment | OdeSegment]
    contacts: list[ContactRecord]
    solver: str
    error_estimate: float
    particle_at_rest: bool = False
    stats: dict[str, float] = field(default_factory=dict)

    @property
    def rebound_velocity_mps(self) -> float:
        """The particle's normal velocity as it last left the plate (outward positive), m/s."""
        last = self.contacts[-1] if self.contacts else None
        return last.separation_speed_mps if last else -self.problem.impact_speed_mps

    @property
    def final_separation_s(self) -> float:
        """When the particle last left the plate, s (nan if it never left)."""
        return self.contacts[-1].end_s if self.contacts else math.nan

    def sample(self, t_s: np.ndarray) -> Samples:
        """Evaluate the state at times ``t_s`` (any order, any range)."""
        times = np.atleast_1d(np.asarray(t_s, dtype=float))
        starts = np.array([seg.start_s for seg in self.segments])
        # at most the last segment's index; times before the first segment's start are
        # evaluated on it
        which = np.maximum(np.searchsorted(starts, times, side="right") - 1, 0)
        # Each segment's times as one contiguous run: times out of segment order (several sets
        # of times asked at once) are grouped by segment, evaluated in runs and put back in
        # their order once per array at the end, not once per segment.
        if times.size < 2 or bool((which[1:] >= which[:-1]).all()):
            return self._sample_grouped(times, which)
        order = np.argsort(which, kind="stable")
        grouped = self._sample_grouped(times[order], which[order])
        out = self._empty_samples(times)
        # every field is a block of rows of one buffer: one scatter puts them all back
        out.q.base[:, order] = grouped.q.base
        return out

    def _empty_samples(self, times: np.ndarray) -> Samples:
        """Zeroed samples at ``times`` whose fields are rows of one (3n + 3, T) buffer (q, qd,
        qdd, force, z, zd), so that they are allocated, and reordered, at once."""
        n = self.problem.structure.size
        buffer = np.zeros((3 * n + 3, times.size))
        return Samples(
            t_s=times,
            q=buffer[:n],
            qd=buffer[n : 2 * n],
            qdd=buffer[2 * n : 3 * n],
            force_n=buffer[3 * n],
            z_m=buffer[3 * n + 1],
            zd_mps=buffer[3 * n + 2],
        )

    def _sample_grouped(self, times: np.ndarray, which: np.ndarray) -> Samples:
        """The states at ``times`` whose segment indices ``which`` do not decrease."""
        out = self._empty_samples(times)
        edges = np.searchsorted(which, np.arange(len(self.segments) + 1)).tolist()
        for index in range(len(self.segments)):
            lo, hi = edges[index], edges[index + 1]
            if lo != hi:
                where = slice(lo, hi)
                self._sample_on(index, times[where], out, where)
        return out

    def sample_segment(self, index: int, t_s: np.ndarray) -> Samples:
        """The states at times ``t_s`` evaluated on segment ``index``: what :meth:`sample`
        gives for those of them that fall in it (the others read its formula beyond its
        span)."""
        times = np.asarray(t_s, dtype=float)
        out = self._empty_samples(times)
        self._sample_on(index, times, out, slice(None))
        return out

    def _sample_on(self, index: int, times: np.ndarray, out: Samples, where: slice) -> None:
        """Segment ``index`` evaluated at ``times`` into positions ``where`` of ``out``."""
        segment = self.segments[index]
        if isinstance(segment, FreeSegment):
            self._sample_free(segment, times, out, where)
        elif isinstance(segment, OdeSegment):
            self._sample_ode(segment, times, out, where)
        else:
            self._sample_contact(segment, times, out, where, self._stacks(index))

    def sample_many(self, parts: Sequence[np.ndarray]) -> list[Samples]:
        """Evaluate the state at several sets of times in one pass: the same values as
        ``[self.sample(t) for t in parts]`` (each time's state does not depend on the others
        asked with it), at the cost of one call: the sensors of one impact ask for thousands
        of instants in several sets, and the work per call weighs as much as the work per
        instant."""
        arrays = [np.atleast_1d(np.asarray(t, dtype=float)) for t in parts]
        edges = np.cumsum([0] + [a.size for a in arrays])
        union = self.sample(np.concatenate(arrays) if arrays else np.empty(0))
        return [union.take(slice(int(lo), int(hi))) for lo, hi in zip(edges[:-1], edges[1:])]

    def _stacks(self, index: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """What contact segment ``index`` is interpolated from, stacked so that one Hermite
        evaluation serves every state: the values [q; q'; z; z'] (2n + 2, steps), their slopes
        [q'; q''; z'; z''] (the particle's acceleration z'' from its velocity's gradient, m/s^2),
        the steps' lengths (s) and each step's polynomials (:func:`_step_polynomials`). Built
        once per segment: the sensors sample a trajectory several times, and the stream once
        per chunk."""
        cache = self.__dict__.setdefault("_contact_stacks", {})
        segment = self.segments[index]
        known = cache.get(index)
        if known is not None and known[0] is segment:
            return known[1]
        t = segment.t_s
        steps = t[1:] - t[:-1] if t.size > 1 else np.zeros(1)  # np.diff(t)
        zdd = _gradient(segment.zd_mps, steps) if t.size > 1 else np.zeros(1)
        values = _rows(segment.q, segment.qd, segment.z_m, segment.zd_mps)
        slopes = _rows(segment.qd, segment.qdd, segment.zd_mps, zdd)
        stacks = (values, slopes, steps, _step_polynomials(values, slopes, steps, segment))
        cache[index] = (segment, stacks)
        return stacks

    def _sample_free(self, seg: FreeSegment, times: np.ndarray, out: Samples, mask: slice) -> None:
        structure = self.problem.structure
        dt = times - seg.anchor_s
        g = self.problem.gravity_mps2
        if seg.at_rest:
            # at rest it stays at rest (the zeros of ``out``), also backwards in time
            out.z_m[mask] = seg.z_m + seg.zd_mps * dt - 0.5 * g * dt * dt
            out.zd_mps[mask] = seg.zd_mps - g * dt
            return
        q, qd = structure.propagate(seg.q, seg.qd, dt)
        out.q[:, mask], out.qd[:, mask] = q, qd
        # no contact force: q'' = -M^-1 (C q' + K q), each time's value independent of how many
        # are asked at once (as propagate's)
        internal = _columnwise(structure.damping, qd) + _columnwise(structure.stiffness, q)
        out.qdd[:, mask] = -_columnwise(structure.inv_mass, internal)
        out.z_m[mask] = seg.z_m + seg.zd_mps * dt - 0.5 * g * dt * dt
        out.zd_mps[mask] = seg.zd_mps - g * dt

    def _sample_ode(self, seg: OdeSegment, times: np.ndarray, out: Samples, mask: slice) -> None:
        n = self.problem.structure.size
        states = seg.dense(np.clip(times, seg.t_s[0], seg.t_s[-1]))
        q, qd = states[:n], states[n : 2 * n]
        out.q[:, mask], out.qd[:, mask] = q, qd
        out.qdd[:, mask] = self.problem.structure.acceleration(
            q, qd, np.zeros(times.size), self.problem.contact_shape
        )
        out.z_m[mask], out.zd_mps[mask] = states[2 * n], states[2 * n + 1]

    @staticmethod
    def _sample_contact(
        seg: ContactSegment,
        times: np.ndarray,
        out: Samples,
        mask: slice,
        stacks: tuple[np.ndarray, np.ndarray, np.ndarray],
    ) -> None:
        """Cubic Hermite through the steps of ``seg`` (values and slopes: :meth:`_stacks`),
        linear for q'' and the force."""
        values, slopes, steps, polynomials = stacks
        t = seg.t_s
        k = np.minimum(np.maximum(np.searchsorted(t, times, side="right") - 1, 0), t.size - 2)
        h = steps[k] if t.size > 1 else np.zeros(times.size)
        s = np.where(h > 0, (times - t[k]) / np.where(h > 0, h, 1.0), 0.0)
        n = out.q.shape[0]
        if polynomials is not None:
            # every state's polynomial of the steps asked, at once (Horner in s)
            c = polynomials[k]  # (T, 4, 3n + 3)
            x = s[:, None]
            y = (c[:, 0] + x * (c[:, 1] + x * (c[:, 2] + x * c[:, 3]))).T
            out.q[:, mask], out.qd[:, mask] = y[:n], y[n : 2 * n]
            out.z_m[mask], out.zd_mps[mask] = y[2 * n], y[2 * n + 1]
            out.qdd[:, mask], out.force_n[mask] = y[2 * n + 2 : 3 * n + 2], y[3 * n + 2]
            return
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        y = (
            h00 * values[:, k]
            + h10 * h * slopes[:, k]
            + h01 * values[:, k + 1]
            + h11 * h * slopes[:, k + 1]
        )
        out.q[:, mask], out.qd[:, mask] = y[:n], y[n : 2 * n]
        out.z_m[mask], out.zd_mps[mask] = y[2 * n], y[2 * n + 1]
        out.qdd[:, mask] = seg.qdd[:, k] * (1 - s) + seg.qdd[:, k + 1] * s
        out.force_n[mask] = seg.force_n[k] * (1 - s) + seg.force_n[k + 1] * s


def _step_polynomials(
    values: np.ndarray, slopes: np.ndarray, steps: np.ndarray, segment: ContactSegment
) -> np.ndarray | None:
    """(steps, 4, 3n + 3): per step, the coefficients of s^0 .. s^3 (s the fraction of the
    step) of the cubic Hermite of each of [q; q'; z; z'] (``values`` and ``slopes`` at the
    step's ends) and of the straight line of [q''; force]; None for a segment of one instant
    (nothing to interpolate)."""
    if steps.size < 1 or segment.t_s.size < 2:
        return None
    hermite = values.shape[0]  # the rows of [q; q'; z; z'], then those of [q''; force]
    qdd, force = segment.qdd, segment.force_n
    # (4, 3n + 3, steps), each block written in place
    coefficients = np.empty((4, hermite + qdd.shape[0] + 1, steps.size))
    constant, linear, square, cube = coefficients
    v0, v1 = values[:, :-1], values[:, 1:]
    m0 = np.multiply(slopes[:, :-1], steps, out=linear[:hermite])
    m1 = slopes[:, 1:] * steps
    constant[:hermite] = v0
    constant[hermite:-1] = qdd[:, :-1]
    constant[-1] = force[:-1]
    np.subtract(qdd[:, 1:], qdd[:, :-1], out=linear[hermite:-1])
    np.subtract(force[1:], force[:-1], out=linear[-1])
    square[:hermite] = 3.0 * (v1 - v0) - 2.0 * m0 - m1
    cube[:hermite] = 2.0 * (v0 - v1) + m0 + m1
    coefficients[2:, hermite:] = 0.0
    return np.ascontiguousarray(coefficients.transpose(2, 0, 1))


def _rows(q: np.ndarray, qd: np.ndarray, z: np.ndarray, zd: np.ndarray) -> np.ndarray:
    """``np.vstack([q, qd, z, zd])`` (q and qd (n, T), z and zd (T,)) written in place."""
    n = q.shape[0]
    out = np.empty((2 * n + 2, z.size))
    out[:n], out[n : 2 * n], out[2 * n], out[2 * n + 1] = q, qd, z, zd
    return out


def _columnwise(matrix: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``matrix @ values`` (values (n, T)) summed term by term in a fixed order, so that each
    column's result does not depend on the other columns: a BLAS product (or einsum) takes
    other code paths, rounding differently, for one column than for many."""
    out = matrix[:, :1] * values[0]
    for j in range(1, matrix.shape[1]):
        out = out + matrix[:, j : j + 1] * values[j]
    return out


def _gradient(values: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """``np.gradient(values, t)`` given the steps ``np.diff(t)`` (at least one), the same
    arithmetic without its argument handling, which costs more than the arithmetic on a
    contact's few dozen steps: second-order differences inside (the uniform-step formula when
    every step is equal), first-order at the ends."""
    out = np.empty_like(values, dtype=float)
    if (steps == steps[0]).all():
        step = steps[0]
        out[1:-1] = (values[2:] - values[:-2]) / (2.0 * step)
        first = last = step
    else:
        dx1, dx2 = steps[:-1], steps[1:]
        a = -(dx2) / (dx1 * (dx1 + dx2))
        b = (dx2 - dx1) / (dx1 * dx2)
        c = dx1 / (dx2 * (dx1 + dx2))
        out[1:-1] = a * values[:-2] + b * values[1:-1] + c * values[2:]
        first, last = steps[0], steps[-1]
    out[0] = (values[1] - values[0]) / first
    out[-1] = (values[-1] - values[-2]) / last
    return out
