"""The trained networks' inputs from an impact's features: shared by the statistical method and
the support-hysteresis network (tail_beam_id.methods.hysteresis); and the optional input every
method may read, where the particle struck (the camera's ``impact_point``)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

# Where the camera saw the particle strike, when it reports it (docs/interface.md
# ``impact_point``): the distance from the hinge along the plate and across it, m. An optional
# input: present only for an impact whose rebound came with a point.
IMPACT_X = "impact_x_m"
IMPACT_Y = "impact_y_m"
# A decision's estimate saying it rested on the impact point (1.0): the label then names
# ``impact_point`` among its signals.
POINT_USED = "impact_point_used"


def impact_point(features: Mapping[str, float]) -> tuple[float, float] | None:
    """The impact's point on the plate (along, across), m, or None when it has none."""
    if IMPACT_X not in features or IMPACT_Y not in features:
        return None
    return float(features[IMPACT_X]), float(features[IMPACT_Y])


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
