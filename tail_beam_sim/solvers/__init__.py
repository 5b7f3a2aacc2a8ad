"""Solvers of an impact problem, one interface, pluggable (in the spirit of ``solve_ivp``).

``solve(problem, method="hybrid", **options)`` returns a :class:`Trajectory`. Every method
takes the same :class:`ImpactProblem` and returns the same kind of result.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from tail_beam_sim.errors import InputError
from tail_beam_sim.solvers import hybrid
from tail_beam_sim.solvers.problem import ContactRecord, ImpactProblem, Samples, Trajectory

SOLVERS: dict[str, Callable[..., Trajectory]] = {"hybrid": hybrid.solve}
DEFAULT_SOLVER = "hybrid"


def solve(problem: ImpactProblem, method: str = DEFAULT_SOLVER, **options: Any) -> Trajectory:
    """Solve ``problem`` with the solver registered as ``method``."""
    try:
        solver = SOLVERS[method]
    except KeyError:
        raise InputError("solver", method, f"must be one of {', '.join(SOLVERS)}") from None
    return solver(problem, **options)


__all__ = ["ContactRecord", "ImpactProblem", "Samples", "Trajectory", "SOLVERS", "DEFAULT_SOLVER", "solve"]
