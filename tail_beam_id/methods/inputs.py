"""The trained networks' inputs from an impact's features: shared by the statistical method and
the support-hysteresis network (tail_beam_id.methods.hysteresis)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np


def base_vector(
    features: Mapping[str, float], names: Sequence[tuple[str, float | None]]
) -> np.ndarray:
    """The model's inputs before expansion: logs of the clipped magnitudes (each name's floor,
    in the feature's unit), raw values where the floor is None (signs, ratios near 1)."""
    values = []
    for name, floor in names:
        value = float(features[name])
        values.append(value if floor is None else math.log(max(value, floor)))
    return np.array(values)
