"""Identification methods: each turns one impact's features into P(coal).

A method is a class with ``name``, ``from_model(model_dict)`` and ``decide(features)``
(:class:`~tail_beam_id.methods.base.Method`); trained parameters live as small JSON files in
``tail_beam_id/models/<name>.json``. This registry (:data:`METHODS`, :func:`available_methods`,
:func:`build_method`) names them for the ``identification.method`` parameter; each method's
module is imported only when it is built.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from tail_beam_id.methods.base import (
    MODELS_DIR,
    Decision,
    Method,
    cap_confidence,
    load_model,
    sigmoid,
)
from tail_beam_sim.errors import InputError


def _threshold(model: Mapping[str, Any], params: Mapping[str, Any]) -> Method:
    from tail_beam_id.methods.threshold import ThresholdMethod

    return ThresholdMethod.from_model(model, params)


def _statistical(model: Mapping[str, Any], params: Mapping[str, Any]) -> Method:
    from tail_beam_id.methods.statistical import StatisticalMethod

    return StatisticalMethod.from_model(model, params)


def _physics(model: Mapping[str, Any], params: Mapping[str, Any]) -> Method:
    from tail_beam_id.methods.physics import PhysicsMethod

    return PhysicsMethod.from_model(model, params)


# name -> factory building the method from its trained model dict and the merged parameters.
METHODS: dict[str, Callable[[Mapping[str, Any], Mapping[str, Any]], Method]] = {
    "threshold": _threshold,
    "statistical": _statistical,
    "physics": _physics,
}


def available_methods() -> list[str]:
    """Names the ``method`` parameter accepts."""
    return list(METHODS)


def build_method(name: str, params: Mapping[str, Any], model_path: str | None = None) -> Method:
    """The method ``name`` with its shipped (or given) trained parameters; ``params``: the
    merged parameters (support, materials, identification)."""
    if name not in METHODS:
        raise InputError("identification.method", name, f"must be one of {', '.join(METHODS)}")
    return METHODS[name](load_model(name, model_path), params)


__all__ = [
    "Decision",
    "METHODS",
    "Method",
    "MODELS_DIR",
    "available_methods",
    "build_method",
    "cap_confidence",
    "load_model",
    "sigmoid",
]
