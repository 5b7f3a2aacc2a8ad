"""Solvers of an impact problem, one interface, pluggable (in the spirit of scipy's ``OdeSolver``).

``solve(problem, method="hybrid", **options)`` returns a :class:`Trajectory`. The registered
methods (:data:`SOLVERS`):

* ``hybrid`` (default): each contact alone (pre-integrated pulse, or RK4), exact between;
  options ``contact`` (auto, pulse, rk4), ``steps_per_contact``, ``pulse_tolerance``;
* ``impulse``: each contact an instantaneous impulse (closed form);
* ``euler``, ``verlet``, ``rk4``: fixed steps over the whole window; options ``dt_s``, ``guard``;
* ``RK45``, ``DOP853``, ``Radau``, ``BDF``, ``LSODA``: scipy's adaptive methods with contact
  events; option ``rtol``.

The contract every solver keeps (tests: test_solvers.py, parametrised over SOLVERS):

1. It is a callable ``solver(problem: ImpactProblem, **options) -> Trajectory``; its options
   are keywords with defaults, so ``solve`` can check them against its signature.
2. An option out of its range raises :class:`~tail_beam_sim.errors.InputError` naming the
   option (bad input). A solve that cannot be trusted (diverged, gained energy, a step beyond
   the stability limit, a problem outside the method's range, a step or phase limit hit)
   raises :class:`SolverError` naming the solver and what to change: never a wrong answer.
3. The :class:`Trajectory` it returns fills every field: ``problem`` (the one given),
   ``segments`` (ordered by start time, covering the whole real line, so ``sample`` works at
   any time), ``contacts`` (at least the first, t = 0, in order), ``solver`` (its registered
   name), ``error_estimate`` (its own relative error estimate of the contact figures and the
   structure's response: the pulse's estimate for ``hybrid``, bounded below by the RK4 bound
   when a contact was integrated; the neglected gravity and centroid terms for ``impulse``;
   ``rtol`` for scipy's methods; nan for fixed steps, which have no error control: nan says
   "no estimate", never a guess) and ``particle_at_rest``.
4. ``stats`` is the solver's own, free-form counters (steps, evaluations) for reports:
   callers (``simulate``, the fidelity tiers) never read it, nor branch on a solver's name.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from functools import lru_cache
from typing import Any

from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.solvers import fixed_step, hybrid, impulse, scipy_ivp
from tail_beam_sim.physics.solvers.problem import (
    ContactRecord,
    ImpactProblem,
    Samples,
    SolverError,
    Trajectory,
)


def _scipy(method: str) -> Callable[..., Trajectory]:
    def solve_with(problem: ImpactProblem, rtol: float = 1e-8) -> Trajectory:
        return scipy_ivp.solve(problem, method, rtol)

    solve_with.__doc__ = (
        f"scipy.integrate.solve_ivp(method={method!r}) with contact events; option rtol."
    )
    return solve_with


def _fixed(method: str) -> Callable[..., Trajectory]:
    def solve_with(problem: ImpactProblem, dt_s: float = 1e-6, guard: bool = True) -> Trajectory:
        return fixed_step.solve(problem, method, dt_s, guard)

    solve_with.__doc__ = f"fixed-step {method} over the whole window; options dt_s, guard."
    return solve_with


SOLVERS: dict[str, Callable[..., Trajectory]] = {
    "hybrid": hybrid.solve,
    "impulse": impulse.solve,
    **{name: _fixed(name) for name in fixed_step.STEPPERS},
    **{name: _scipy(name) for name in scipy_ivp.METHODS},
}
DEFAULT_SOLVER = "hybrid"


@lru_cache(maxsize=None)
def _signature(method: str) -> inspect.Signature:
    """The registered solver's signature, read once: reading it costs as much as a fast solve."""
    return inspect.signature(SOLVERS[method])


@lru_cache(maxsize=None)
def _optional_names(method: str) -> frozenset[str]:
    """The options the registered solver takes by keyword, each with a default (empty when one
    is required: then every call's options go through the signature's own check)."""
    parameters = list(_signature(method).parameters.values())[1:]
    if any(p.default is inspect.Parameter.empty for p in parameters):
        return frozenset()
    return frozenset(
        p.name
        for p in parameters
        if p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    )


def solve(problem: ImpactProblem, method: str = DEFAULT_SOLVER, **options: Any) -> Trajectory:
    """Solve ``problem`` with the solver registered as ``method``."""
    try:
        solver = SOLVERS[method]
    except KeyError:
        raise InputError("solver", method, f"must be one of {', '.join(SOLVERS)}") from None
    try:
        if not _optional_names(method).issuperset(options):
            _signature(method).bind(problem, **options)
    except TypeError as exc:
        raise InputError(
            "solver options", sorted(options), f"not all accepted by {method}: {exc}"
        ) from None
    return solver(problem, **options)


__all__ = [
    "ContactRecord",
    "ImpactProblem",
    "Samples",
    "SolverError",
    "Trajectory",
    "SOLVERS",
    "DEFAULT_SOLVER",
    "solve",
]
