"""A dense flow of contacts on one linear support, by superposition: cost per contact, not per
contact times stream length.

The support (beam, jack, bending modes) is linear, so its motion under many contact forces is
the sum of its responses to each. :class:`FlowSimulator` is a
:class:`~tail_beam_sim.physics.stream.StreamSimulator` whose contacts may overlap:

* Each contact is solved on its own (the tier's solver) from the beam's velocity at its contact
  stamp as every earlier contact leaves it (their solved forces up to that stamp, a contact
  still in progress included), with zero displacement, as the stream does. During its own
  contact the beam is taken to move freely from that state under this contact's force alone: a
  contact still in progress, or one starting later, does not act back on it. That is the
  approximation (docs/flow.md; checked against a coupled reference in
  test/sim/physics/test_flow_superposition.py); contacts that do not overlap in time are
  superposed exactly.
* Its contribution to the beam's motion is the solved trajectory minus the free response of the
  velocity it started from: the response to its own force from rest
  (:class:`Contribution`). Once its particle has left the plate for the last time the
  contribution is a free response, and it is folded into one aggregate state that is
  propagated exactly (the structure's eigen-decomposition).
* Each contact's start and end starts an epoch (:class:`FlowEpoch`): one free state at its
  start propagated exactly, plus the trajectories of the contacts in progress. Sampling a time
  costs the free propagation plus the few contacts in progress then, so a run costs in
  proportion to its contacts plus its samples. A sensor value averaged over the period before
  its instant reads the part of the period before its epoch from the epoch before. The sensor
  stages are the stream simulator's, unchanged; a span's instants of every sensor are asked of
  each epoch in one pass (:class:`FlowEpochBatch`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from tail_beam_sim.physics.result import impact_truth
from tail_beam_sim.physics.scene import Impact, Scene
from tail_beam_sim.physics.simulate import build_problem
from tail_beam_sim.physics.solvers import ImpactProblem, Samples, Trajectory, solve
from tail_beam_sim.physics.solvers.problem import _columnwise
from tail_beam_sim.physics.stream import (
    CarriedTrajectory,
    Chunk,
    EpochBatch,
    ScheduledImpact,
    StreamSimulator,
    _relative,
    rest_trajectory,
)
from tail_beam_sim.physics.structure import LinearStructure


def _free_acceleration(structure: LinearStructure, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """q'' of the unforced structure, each column independent of the others (as the
    trajectories' own free segments compute it)."""
    internal = _columnwise(structure.damping, qd) + _columnwise(structure.stiffness, q)
    return -_columnwise(structure.inv_mass, internal)


_NAN = np.array([np.nan]).tobytes()  # the buffer of _not_computed's arrays


def _not_computed(shape: tuple[int, ...]) -> np.ndarray:
    """A read-only array of NaN of ``shape`` that holds one value (a field left out)."""
    return np.ndarray(shape, dtype=float, buffer=_NAN, strides=(0,) * len(shape))


@dataclass(frozen=True)
class Contribution:
    """One contact: its trajectory, solved from velocity ``qd0`` (zero displacement) at
    ``stamp_s``; its particle has left the plate for the last time at ``until_s``. Its share of
    the beam's motion is the trajectory minus the free response of ``qd0``: the response to its
    own force from rest."""

    stamp_s: float
    trajectory: Trajectory
    qd0: np.ndarray
    until_s: float

    def sample(self, stamp_s: np.ndarray) -> Samples:
        """The trajectory at absolute stamps (s): q, qd, qdd, and the contact force (N)."""
        return self.trajectory.sample(stamp_s - self.stamp_s)


class FlowEpoch:
    """The beam's motion from one contact stamp (or end) to the next: a free state at the
    epoch's start propagated exactly plus the trajectories of the contacts still active. The
    free state is the aggregate of the contacts folded before, less the free responses that the
    active trajectories carry (each started from the beam's velocity, not from rest): one
    propagation per sample instead of one per active contact. Samples like a
    :class:`Trajectory` (times from the epoch's start), which is all the sensor stages ask."""

    def __init__(
        self,
        problem: ImpactProblem,
        start_s: float,
        q: np.ndarray,
        qd: np.ndarray,
        active: Sequence[Contribution],
        previous: FlowEpoch | Trajectory | None = None,
        previous_start_s: float = -math.inf,
    ) -> None:
        self.problem = problem
        self.start_s = start_s
        self.q = q
        self.qd = qd
        self.active = list(active)
        # the free state's decomposition (LinearStructure.free_amplitude), made at first use
        self._amplitude: np.ndarray | None = None
        self._decomposed = False
        # The epoch before (starting at previous_start_s): a sensor's value is a mean over the
        # period before its instant, and a period reaching back before this epoch is read there.
        self.previous = previous
        self.previous_start_s = previous_start_s

    @property
    def shift_s(self) -> float:
        """This epoch's time less the previous epoch's, s (the rest epoch, from -inf, reads
        absolute stamps)."""
        return self.start_s - (
            self.previous_start_s if math.isfinite(self.previous_start_s) else 0
        )

    def sample(self, t_s: np.ndarray, accelerations: bool = True) -> Samples:
        """The beam's state at times ``t_s`` from the epoch's start (the particle fields hold
        zeros; ``force_n`` is the sum of the contact forces, N); times before the start are
        the previous epoch's. ``accelerations=False``: q and qd only, ``qdd`` and ``force_n``
        left NaN (read-only), which is all the sensors of the stream read."""
        times = np.atleast_1d(np.asarray(t_s, dtype=float))
        before = times < 0.0
        if self.previous is None or not before.any():
            return self.sample_parts(times, accelerations)[0]
        shift = self.shift_s
        # Every time on this epoch's formula (each time's state does not depend on the others
        # asked with it), then the few before its start (a period's reach) read there instead.
        # (Those sampled at the start instead: a contact starting here is not asked before it.)
        out = self.sample_parts(np.maximum(times, 0.0), accelerations)[0]
        out.t_s = times
        where = np.flatnonzero(before)
        early_times = times[where] + shift
        if isinstance(self.previous, FlowEpoch):
            early = self.previous.sample(early_times, accelerations)
        else:
            early = self.previous.sample(early_times)
        out.q[:, where], out.qd[:, where] = early.q, early.qd
        if accelerations:
            out.qdd[:, where], out.force_n[where] = early.qdd, early.force_n
        return out

    def sample_parts(
        self, times: np.ndarray, accelerations: bool = True
    ) -> tuple[Samples, list[Samples]]:
        """The beam's state at times ``times`` (from the epoch's start, on its own formula),
        and each active contact's trajectory there (their sum less the free part);
        ``accelerations`` as for :meth:`sample`."""
        structure = self.problem.structure
        if not self._decomposed:
            self._amplitude = structure.free_amplitude(self.q, self.qd)
            self._decomposed = True
        q, qd = structure.propagate_amplitude(self._amplitude, times)
        parts = []
        if accelerations:
            qdd = _free_acceleration(structure, q, qd)
            force = np.zeros(times.size)
        if self.active:
            stamps = times + self.start_s
            for contribution in self.active:
                part = contribution.sample(stamps)
                parts.append(part)
                q, qd = q + part.q, qd + part.qd
                if accelerations:
                    qdd, force = qdd + part.qdd, force + part.force_n
        if not accelerations:
            qdd, force = _not_computed(q.shape), _not_computed(times.shape)
        zeros = np.zeros(times.size)
        return Samples(times, q, qd, qdd, force, zeros, zeros.copy()), parts

    def sample_many(
        self, parts: Sequence[np.ndarray], accelerations: bool = True
    ) -> list[Samples]:
        """:meth:`sample` of several sets of times in one pass (as
        :meth:`Trajectory.sample_many`)."""
        arrays = [np.atleast_1d(np.asarray(t, dtype=float)) for t in parts]
        edges = np.cumsum([0] + [a.size for a in arrays]).tolist()
        union = self.sample(np.concatenate(arrays) if arrays else np.empty(0), accelerations)
        return [union.take(slice(lo, hi)) for lo, hi in zip(edges[:-1], edges[1:])]

    def sample_states(self, parts: Sequence[np.ndarray]) -> list[Samples]:
        """:meth:`sample_many` of q and qd only (what the stream's sensors read)."""
        return self.sample_many(parts, accelerations=False)


class FlowEpochBatch(EpochBatch):
    """The sensors' times of a span asked of the flow's epochs: times before an epoch's start
    asked of the epoch before directly (where :meth:`FlowEpoch.sample` would read them), so
    that each epoch is sampled once per span; q and qd only (what the sensors read)."""

    def __init__(self, epochs: list[FlowEpoch | Trajectory]) -> None:
        super().__init__(epochs)  # type: ignore[arg-type]
        # a ticket's times before its epoch's start: (where, their ticket, the times asked)
        self._early: dict[tuple[int, int], tuple[np.ndarray, tuple[int, int], np.ndarray]] = {}

    def ask(self, epoch: int, t_s: np.ndarray) -> tuple[int, int]:
        trajectory = self._epochs[epoch]
        if (
            isinstance(trajectory, FlowEpoch)
            and epoch > 0
            and trajectory.previous is self._epochs[epoch - 1]
        ):
            before = t_s < 0.0
            if before.any():
                where = np.flatnonzero(before)
                early = self.ask(epoch - 1, t_s[where] + trajectory.shift_s)
                # the others on the epoch's own formula, those before its start at its start
                ticket = super().ask(epoch, np.maximum(t_s, 0.0))
                self._early[ticket] = (where, early, t_s)
                return ticket
        return super().ask(epoch, t_s)

    def _sample(self, trajectory: Trajectory, parts: list[np.ndarray]) -> list[Samples]:
        if isinstance(trajectory, FlowEpoch):
            return trajectory.sample_states(parts)
        return trajectory.sample_many(parts)

    def get(self, ticket: tuple[int, int]) -> Samples:
        out = super().get(ticket)
        early = self._early.pop(ticket, None)
        if early is not None:
            where, before, times = early
            part = self.get(before)
            out.q[:, where], out.qd[:, where] = part.q, part.qd
            out.t_s = times
        return out


class FlowSimulator(StreamSimulator):
    """A stream simulator whose contacts may overlap, superposed (module docstring).

    Contact stamps must not decrease: a stamp before the latest one, or too soon for the
    samples already produced, is moved to the earliest allowed (``earliest_contact_s``); the
    stream's ``min_impact_gap_s`` does not apply.
    """

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._rest_problem = rest_trajectory(self.structure, self.support.gravity_mps2).problem
        self._latest_stamp_s = -math.inf
        self.solver_options: dict[str, object] = {}  # passed to the solver of every contact

    @property
    def earliest_contact_s(self) -> float:
        """The earliest contact stamp a new lump can get now, s: not before the samples already
        produced plus the command lead, nor before the latest contact stamp."""
        return max(self._time_s + self.params.command_lead_s, self._latest_stamp_s)

    def advance(self, until_s: float) -> Chunk:
        """Fold the contacts that end by ``until_s``, then produce the span as the stream
        does."""
        self._fold_until(until_s)
        return super().advance(until_s)

    def _fold_until(self, stamp_s: float) -> None:
        """Start an epoch where each active contact has ended (at or before ``stamp_s``), with
        that contact folded into the free state: epochs then sample each contact's trajectory
        over its contact only."""
        while True:
            epoch = self._epochs[-1]
            active = getattr(epoch, "active", [])
            ended = [c for c in active if c.until_s <= stamp_s]
            if not ended:
                return
            first = min(ended, key=lambda c: c.until_s)
            start = max(first.until_s, self._epoch_starts[-1])
            total, active, parts = self._state_at(start)
            q, qd = self._aggregate(total, active, parts, lambda c: c is not first)
            remaining = [c for c in active if c is not first]
            self._push_epoch(FlowEpoch(self._rest_problem, start, q, qd, remaining))

    def _epoch_batch(self) -> FlowEpochBatch:
        return FlowEpochBatch(self._epochs)

    def _push_epoch(self, epoch: FlowEpoch) -> None:
        """Append ``epoch``, linked to the one before it."""
        epoch.previous, epoch.previous_start_s = self._epochs[-1], self._epoch_starts[-1]
        self._epoch_starts.append(epoch.start_s)
        self._epochs.append(epoch)

    def _prune(self) -> None:
        """Forget the epochs no future sample can fall in, and the first kept epoch's link to
        them (no period reaches back past it any more): memory stays bounded."""
        super()._prune()
        first = self._epochs[0]
        if isinstance(first, FlowEpoch):
            first.previous = None

    def _state_at(self, stamp_s: float) -> tuple[Samples, list[Contribution], list[Samples]]:
        """The latest epoch at ``stamp_s`` (not before its start): the beam's state, the epoch's
        active contacts and each one's trajectory there."""
        epoch = self._epochs[-1]
        times = _relative(np.array([stamp_s]), self._epoch_starts[-1])
        if isinstance(epoch, FlowEpoch) and times[0] >= 0.0:
            total, parts = epoch.sample_parts(times, accelerations=False)
            if times[0] + epoch.start_s == stamp_s:  # the epoch sampled them at stamp_s itself
                return total, epoch.active, parts
            return total, epoch.active, [c.sample(np.array([stamp_s])) for c in epoch.active]
        active = list(getattr(epoch, "active", []))
        return epoch.sample(times), active, [c.sample(np.array([stamp_s])) for c in active]

    @staticmethod
    def _aggregate(
        total: Samples,
        active: Sequence[Contribution],
        parts: Sequence[Samples],
        keep: Callable[[Contribution], bool],
    ) -> tuple[np.ndarray, np.ndarray]:
        """The free state of an epoch whose active contacts are those of ``active`` but
        ``keep`` excludes (``keep(contribution)``): the beam's state ``total`` less their
        trajectories' states ``parts``."""
        q, qd = total.q[:, 0].copy(), total.qd[:, 0].copy()
        for contribution, part in zip(active, parts):
            if keep(contribution):
                q -= part.q[:, 0]
                qd -= part.qd[:, 0]
        return q, qd

    def _solve(self, impact: Impact, stamp_s: float) -> ScheduledImpact:
        """Solve ``impact`` at ``stamp_s`` from the beam's velocity as the earlier contacts
        leave it, and start the epoch it opens."""
        self._fold_until(stamp_s)
        total, active, parts = self._state_at(stamp_s)
        qd0 = total.qd[:, 0].copy()
        q, qd = self._aggregate(total, active, parts, lambda c: True)
        qd = qd - qd0  # the new trajectory starts from (0, qd0): its free part leaves the base
        problem = build_problem(
            self.support, impact, self.contact_model, self.window_s, self.structure, qd0=qd0
        )
        trajectory = solve(problem, self.solver, **self.solver_options)
        separation = trajectory.final_separation_s
        until = stamp_s + (separation if math.isfinite(separation) else self.window_s)
        contribution = Contribution(stamp_s, trajectory, qd0, until)
        self._push_epoch(FlowEpoch(self._rest_problem, stamp_s, q, qd, [*active, contribution]))
        self._latest_stamp_s = stamp_s
        rebound = self._suite.rebound(trajectory, stamp_s)
        point = self._suite.reported_point(impact.position_m, rebound, self.support)
        scene = Scene(
            self.support,
            impact,
            self.sensors,
            self.materials,
            self.contact_model,
            self.window_s,
            0.0,
        )
        return ScheduledImpact(
            impact,
            stamp_s,
            CarriedTrajectory.carry(trajectory, np.zeros(self.structure.size)),
            rebound,
            impact_truth(
                scene, trajectory, stamp_s, rebound.stamp_s, contact_summary(scene, trajectory)
            ),
            point,
        )


def contact_summary(scene: Scene, trajectory: Trajectory) -> dict[str, Any]:
    """The noise-free figures of one lump's contact (the keys of
    :func:`~tail_beam_sim.physics.simulate.summarise` that belong to the lump alone). The
    sensors' peaks are left out: in a flow they are not one lump's."""
    impact = scene.impact
    rebound = max(trajectory.rebound_velocity_mps, 0.0)
    return {
        "mass_kg": impact.mass_kg,
        "drop_height_m": impact.drop_height_m,
        "rebound_speed_mps": rebound,
        "restitution": rebound / impact.impact_speed_mps,
        "contact_duration_s": trajectory.contacts[0].duration_s,
        "peak_contact_force_n": max(c.peak_force_n for c in trajectory.contacts),
        "n_contacts": len(trajectory.contacts),
        "particle_at_rest": trajectory.particle_at_rest,
        "contact_model": scene.contact_model,
        "solver": trajectory.solver,
        "window_s": scene.window_s,
    }
