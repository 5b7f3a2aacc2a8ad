"""Solvers of an impact problem, one interface, pluggable (in the spirit of ``solve_ivp``).

``solve(problem, method="hybrid", **options)`` returns a :class:`Trajectory`. Every method
takes the same :class:`ImpactProblem` and returns the same kind of result:

* ``hybrid`` (default): each contact alone (pre-integrated pulse, or RK4), exact between;
  options ``contact`` (auto, pulse, rk4), ``steps_per_contact``, ``pulse_tolerance``;
* ``impulse``: each contact an instantaneous impulse (closed form);
* ``euler``, ``verlet``, ``rk4``: fixed steps over the whole window; options ``dt_s``, ``guard``;
* ``RK45``, ``DOP853``, ``Radau``, ``BDF``, ``LSODA``: scipy's adaptive methods with contact
  events; option ``rtol``.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

from tail_beam_sim.errors import InputError
from tail_beam_sim.solvers import fixed_step, hybrid, impulse, scipy_ivp
from tail_beam_sim.solvers.problem import ContactRecord, ImpactProblem, Samples, SolverError, Trajectory


def _scipy(method: str) -> Callable[..., Trajectory]:
    def solve_with(problem: ImpactProblem, rtol: float = 1e-8) -> Trajectory:
        return scipy_ivp.solve(problem, method, rtol)

    solve_with.__doc__ = f"scipy.integrate.solve_ivp(method={method!r}) with contact events; option rtol."
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


def solve(problem: ImpactProblem, method: str = DEFAULT_SOLVER, **options: Any) -> Trajectory:
    """Solve ``problem`` with the solver registered as ``method``."""
    try:
        solver = SOLVERS[method]
    except KeyError:
        raise InputError("solver", method, f"must be one of {', '.join(SOLVERS)}") from None
    try:
        inspect.signature(solver).bind(problem, **options)
    except TypeError as exc:
        raise InputError("solver options", sorted(options), f"not all accepted by {method}: {exc}") from None
    return solver(problem, **options)


__all__ = ["ContactRecord", "ImpactProblem", "Samples", "SolverError", "Trajectory", "SOLVERS", "DEFAULT_SOLVER", "solve"]
