"""The study's idea: one feature compared with one threshold.

The model lists rules in order of preference (feature, threshold, slope); the first rule whose
feature the impact has decides, so the method still labels when a stream is gone. The
confidence is a logistic in log(feature / threshold), fitted on training impacts, so it is
as calibrated as a single feature allows.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from tail_beam_id.methods import Decision, sigmoid

FLOOR = 1e-9  # features are positive physical magnitudes; a noisy reading below this is clipped


@dataclass(frozen=True)
class Rule:
    """P(coal) = sigmoid(slope * (ln(feature) - ln(threshold))); slope < 0: coal below."""

    feature: str
    threshold: float
    slope: float


class ThresholdMethod:
    name = "threshold"

    def __init__(self, rules: list[Rule]) -> None:
        self.rules = rules

    @classmethod
    def from_model(cls, model: Mapping[str, Any]) -> ThresholdMethod:
        return cls([Rule(r["feature"], float(r["threshold"]), float(r["slope"])) for r in model["rules"]])

    def decide(self, features: Mapping[str, float]) -> Decision:
        for rule in self.rules:
            if rule.feature in features:
                value = max(features[rule.feature], FLOOR)
                p = sigmoid(rule.slope * (math.log(value) - math.log(rule.threshold)))
                return Decision(p, {"threshold_feature": rule.feature, "threshold_value": rule.threshold})
        return Decision(0.5, {})
