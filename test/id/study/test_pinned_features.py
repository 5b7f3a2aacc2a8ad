"""The features the shipped models read, pinned: a fixed training impact of the stream set at
every sensor setting and two on drawn supports (with and without their accelerometer), as the
suite computed them when the shipped models were trained (pinned_features.json; the drawn
supports follow identification.evaluation.supports.training, so a change of those ranges draws
other supports and rewrites their entries, while the stream set's stay). The models
in tail_beam_id/models/ stay valid only while the features of the same impacts stay these;
changing them on purpose means retraining the models and writing this file anew (the values
printed by the same run_set calls)."""

from __future__ import annotations

import json
import math
from pathlib import Path

from tail_beam_id.study.dataset import evaluation_params, settings
from tail_beam_id.study.runs import run_set

PINNED = Path(__file__).with_name("pinned_features.json")
REL = 1e-9  # float rounding across machines (libm, BLAS), far below any feature's meaning


def test_the_features_of_fixed_impacts_are_those_the_models_were_trained_on(params):
    """Every labelled record of the fixed impacts has the pinned feature names and values to
    1e-9."""
    pinned = json.loads(PINNED.read_text(encoding="utf-8"))
    seed = int(evaluation_params(params)["training_seed"])
    found = {}
    for scene_set, count, set_seed in (("stream", 1, seed), ("varied", 2, seed + 2)):
        for record in run_set(
            params,
            scene_set,
            count,
            set_seed,
            settings(params, every_rate=True),
            ["threshold"],
            without_vibration_too=scene_set == "varied",
        ):
            if record.label is not None:
                key = f"{scene_set}/{record.index}/{record.setting}"
                found[key] = dict(record.label.features)
    assert found.keys() == pinned.keys()
    for key, features in pinned.items():
        assert found[key].keys() == features.keys(), key
        for name, value in features.items():
            got = float(found[key][name])
            assert math.isclose(got, value, rel_tol=REL, abs_tol=1e-300) or (
                math.isnan(got) and math.isnan(value)
            ), f"{key} {name}: {got!r} != pinned {value!r}"
