"""Identification methods: each turns one impact's features into P(coal).

A method is a class with ``name``, ``from_model(model_dict)`` and ``decide(features)``;
trained parameters live as small JSON files in ``tail_beam_id/models/<name>.json``. The
registry (:data:`METHODS`, :func:`available_methods`, :func:`build_method`) names them for the
``identification.method`` parameter; each method's module is imported only when it is built.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from tail_beam_sim.errors import InputError

MODELS_DIR = Path(__file__).resolve().parent.parent / "models"


@dataclass
class Decision:
    """P(coal) for one impact, plus whatever the method estimated on the way (units in names)."""

    p_coal: float
    estimates: dict[str, float] = field(default_factory=dict)
    # Features outside what the method was trained on (its confidence is capped for them).
    outside_training: tuple[str, ...] = ()
    # The signals the decision rested on (jack_pressure, imu for either acceleration channel,
    # rebound_velocity) when the method left some of those it was given aside; None: all of them.
    signals: tuple[str, ...] | None = None

    @property
    def label(self) -> str:
        return "coal" if self.p_coal >= 0.5 else "gangue"

    @property
    def confidence(self) -> float:
        """Probability of the stated label."""
        return max(self.p_coal, 1.0 - self.p_coal)


class Method(Protocol):
    name: str

    def decide(self, features: Mapping[str, float]) -> Decision: ...


def cap_confidence(p_coal: float, cap: float) -> float:
    """P(coal) moved toward 0.5 so that the stated label's probability is at most ``cap``."""
    return min(max(p_coal, 1.0 - cap), cap)


def sigmoid(x: float) -> float:
    """Logistic function, safe for large |x|."""
    if x >= 0:
        return 1.0 / (1.0 + math.exp(-x))
    z = math.exp(x)
    return z / (1.0 + z)


def load_model(name: str, path: str | Path | None = None) -> dict[str, Any]:
    """The trained parameters of method ``name`` (shipped JSON unless ``path`` is given)."""
    file = Path(path) if path else MODELS_DIR / f"{name}.json"
    try:
        return json.loads(file.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"identification.{name}.model", str(file), f"must be a readable JSON file ({exc.strerror})") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"identification.{name}.model", str(file), f"must be valid JSON ({exc.msg})") from None


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
    "Decision", "METHODS", "Method", "MODELS_DIR", "available_methods", "build_method", "cap_confidence", "load_model", "sigmoid",
]
