"""The study's idea: one feature compared with one threshold.

The model lists rules in order of preference (feature, threshold, slope); the first rule whose
feature the impact has decides, so the method still labels when a stream is gone. The
confidence is a logistic in log(feature / threshold), fitted on training impacts, so it is
as calibrated as a single feature allows there; outside the feature values it was tuned on
the confidence is capped (``identification.threshold.extrapolation_confidence_cap``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from tail_beam_id.methods.base import Decision, sigmoid
from tail_beam_sim.errors import require_section
from tail_beam_sim.spec import Section, number

FLOOR = 1e-9  # features are positive physical magnitudes; a noisy reading below this is clipped


THRESHOLD = Section(
    "identification.threshold",
    "The threshold method.",
    (
        number(
            "extrapolation_confidence_cap",
            "Confidence cap outside the tuned range.",
            low=0.5,
            high=1.0,
        ),
    ),
    file="identification.yaml",
)


@dataclass(frozen=True)
class Rule:
    """P(coal) = sigmoid(slope * (ln(feature) - ln(threshold))); slope < 0: coal below.
    ``seen``: the feature's range in the training impacts (its unit)."""

    feature: str
    threshold: float
    slope: float
    seen: tuple[float, float]


class ThresholdMethod:
    name = "threshold"

    def __init__(self, rules: list[Rule], extrapolation_cap: float) -> None:
        self.rules = rules
        self.extrapolation_cap = extrapolation_cap

    @classmethod
    def from_model(cls, model: Mapping[str, Any], params: Mapping[str, Any]) -> ThresholdMethod:
        section = require_section(
            "identification.threshold", params["identification"].get("threshold")
        )
        cap = THRESHOLD.check(section)["extrapolation_confidence_cap"]
        rules = [
            Rule(r["feature"], float(r["threshold"]), float(r["slope"]), tuple(r["seen"]))
            for r in model["rules"]
        ]
        return cls(rules, cap)

    def decide(self, features: Mapping[str, float]) -> Decision:
        for rule in self.rules:
            if rule.feature in features:
                value = features[rule.feature]
                p = sigmoid(rule.slope * (math.log(max(value, FLOOR)) - math.log(rule.threshold)))
                estimates = {"threshold_value": rule.threshold}
                # A threshold tuned on one scene says nothing outside the values it was tuned on.
                if not rule.seen[0] <= value <= rule.seen[1]:
                    p = min(max(p, 1.0 - self.extrapolation_cap), self.extrapolation_cap)
                    estimates["extrapolated"] = 1.0
                return Decision(p, estimates)
        return Decision(0.5, {})
