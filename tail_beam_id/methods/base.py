"""What every identification method shares: its decision, its protocol, its trained model.

Trained parameters live as small JSON files in ``tail_beam_id/models/<name>.json``; the
registry in :mod:`tail_beam_id.methods` builds a method from them by name.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from tail_beam_sim.errors import InputError

MODELS_DIR = Path(__file__).resolve().parent.parent / "models"

# Arrays of trained models' lists, by the list's identity (the list kept with its array, so
# that the identity is not reused): a decision reads the same weights for every impact.
_ARRAYS: dict[int, tuple[list, np.ndarray]] = {}
MOST_ARRAYS = 4096  # at this many, all are forgotten (training builds many models)


def model_array(model: Mapping[str, Any], name: str) -> np.ndarray:
    """``np.array(model[name])``, read-only, converted once per list: a model's weights and
    standardisation are lists (JSON), never changed in place once trained. Anything but a list
    (an array a fit is still changing) is converted on every call."""
    value = model[name]
    if not isinstance(value, list):
        return np.array(value)
    known = _ARRAYS.get(id(value))
    if known is not None and known[0] is value:
        return known[1]
    array = np.array(value)
    array.flags.writeable = False
    if len(_ARRAYS) >= MOST_ARRAYS:
        _ARRAYS.clear()
    _ARRAYS[id(value)] = (value, array)
    return array


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
        raise InputError(
            f"identification.{name}.model",
            str(file),
            f"must be a readable JSON file ({exc.strerror})",
        ) from None
    except json.JSONDecodeError as exc:
        raise InputError(
            f"identification.{name}.model", str(file), f"must be valid JSON ({exc.msg})"
        ) from None


__all__ = ["Decision", "MODELS_DIR", "Method", "cap_confidence", "load_model", "sigmoid"]
