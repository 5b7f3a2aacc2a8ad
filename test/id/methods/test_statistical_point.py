"""The statistical method and the impact point: an impact with a point is decided by the model
fitted with it, keeping the delay check and signals; one without is decided as before; models
trained before the point existed ignore it."""

from __future__ import annotations

import copy
import math

import pytest
from id_helpers import impact

from tail_beam_id.methods import build_method, load_model
from tail_beam_id.methods.inputs import IMPACT_X, IMPACT_Y, POINT_USED
from tail_beam_id.methods.statistical import FRAME_PERIOD, FULL_KEY, WITH_POINT
from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.replay import point_tuples, replay


@pytest.fixture(scope="module")
def shipped_point_models():
    model = load_model("statistical")
    if FULL_KEY + WITH_POINT not in model["subsets"]:
        pytest.skip("the shipped statistical model has no impact-point models")
    return model


@pytest.fixture(scope="module")
def features(params):
    """A sandstone impact's label features, with its impact point."""
    pointed = copy.deepcopy(params)
    pointed["sensors"]["camera_reports_impact_point"] = True
    result = impact(
        pointed, material="sandstone", radius_m=0.04, drop_height_m=2.5, position_m=0.9
    )
    identifier = StreamIdentifier("statistical", pointed["identification"], pointed)
    (label,) = replay(
        identifier,
        result.pressure,
        result.imu,
        [result.rebound],
        vibration=result.vibration,
        points=point_tuples([result.point]),
    )
    assert "impact_point" in label.signals
    return dict(label.features)


def test_without_the_point_the_decision_is_the_models_without_it(
    params, shipped_point_models, features
):
    """With the point the decision is the point's model's, its logit without the point and its
    delay check kept; without it, the model without the point's."""
    method = build_method("statistical", params)
    bare = {k: v for k, v in features.items() if k not in (IMPACT_X, IMPACT_Y)}
    without = method.decide(bare)
    assert POINT_USED not in without.estimates
    with_point = method.decide(features)
    assert with_point.estimates[POINT_USED] == 1.0
    assert with_point.estimates["logit_without_point"] == pytest.approx(without.estimates["logit"])
    assert with_point.signals == without.signals
    for kept in ("delay_residual", "delay_unusual"):
        if kept in without.estimates:
            assert with_point.estimates[kept] == without.estimates[kept]


def test_a_family_without_point_models_ignores_the_point(params, shipped_point_models, features):
    """Models trained before the point existed (no ~with_point entry) decide as they did."""
    from tail_beam_id.methods.statistical import StatisticalMethod

    stripped = {
        family: {k: v for k, v in shipped_point_models[family].items() if WITH_POINT not in k}
        for family in ("subsets", "calibrated_subsets")
    }
    method = StatisticalMethod.from_model({**shipped_point_models, **stripped}, params)
    bare = {k: v for k, v in features.items() if k not in (IMPACT_X, IMPACT_Y)}
    assert method.decide(features) == method.decide(bare)


def test_the_points_model_reads_the_point(params, shipped_point_models, features):
    """The same impact read as struck near the hinge or near the tip is decided otherwise: the
    moment impulse it carries (m v0 (1 + e) x) means another momentum at another x. (Compared
    as logits: a sandstone this clear is gangue at either point, its P(coal) near 0.)"""
    method = build_method("statistical", params)
    near = method.decide({**features, IMPACT_X: 0.2}).estimates["logit"]
    far = method.decide({**features, IMPACT_X: 1.4}).estimates["logit"]
    assert abs(near - far) > 0.1


def test_a_point_model_missing_an_input_leaves_the_decision_without_the_point(
    params, shipped_point_models, features
):
    """The calibrated family's point models read the camera's frame period as well: an impact
    with a point but no known frame is decided as one without the point, never with an input
    made up."""
    model = shipped_point_models["calibrated_subsets"][FULL_KEY + WITH_POINT]
    if FRAME_PERIOD not in [name for name, _ in model["features"]]:
        pytest.skip("the shipped point models do not read the camera's frame period")
    method = build_method("statistical", params)
    calibrated = {**features, "support_calibrated": 1.0}
    assert method.decide(calibrated).estimates[POINT_USED] == 1.0
    unknown_frame = {k: v for k, v in calibrated.items() if k != FRAME_PERIOD}
    bare = {k: v for k, v in unknown_frame.items() if k not in (IMPACT_X, IMPACT_Y)}
    decided = method.decide(unknown_frame)
    assert POINT_USED not in decided.estimates
    assert decided == method.decide(bare)


def test_the_points_model_reads_the_camera_frame_and_a_faster_one_is_not_outside(
    params, shipped_point_models, features
):
    """The same delay from a camera twice as fast says a contact nearer the delay's length (its
    lag is shorter): the calibrated point model decides it otherwise. A frame shorter than any
    trained is read as the shortest trained (its delay only sharper), not flagged outside
    training."""
    model = shipped_point_models["calibrated_subsets"][FULL_KEY + WITH_POINT]
    names = [name for name, _ in model["features"]]
    if FRAME_PERIOD not in names:
        pytest.skip("the shipped point models do not read the camera's frame period")
    method = build_method("statistical", params)
    calibrated = {**features, "support_calibrated": 1.0}
    slow = method.decide({**calibrated, FRAME_PERIOD: 2e-4})
    fast = method.decide({**calibrated, FRAME_PERIOD: 1e-4})
    assert slow.estimates[POINT_USED] == fast.estimates[POINT_USED] == 1.0
    assert abs(slow.p_coal - fast.p_coal) > 1e-3
    shortest = math.exp(model["envelope"][0][names.index(FRAME_PERIOD)])
    faster = method.decide({**calibrated, FRAME_PERIOD: shortest / 4.0})
    assert FRAME_PERIOD not in faster.outside_training
    at_shortest = method.decide({**calibrated, FRAME_PERIOD: shortest})
    assert faster.p_coal == pytest.approx(at_shortest.p_coal)
    # A camera slower than the training's reference is averaged over its lags by the model
    # without the point (the point's models read one row).
    slower = method.decide({**calibrated, FRAME_PERIOD: 1e-3})
    assert POINT_USED not in slower.estimates


def test_only_the_calibrated_point_models_read_the_camera_frame(shipped_point_models):
    """Identified with config/ alone, the training's single impacts know config/'s frame only
    (one value: nothing to learn from, and any other camera would read as outside training):
    those point models read the point alone; the calibrated ones read the frame as well."""
    for key, model in shipped_point_models["subsets"].items():
        if key.endswith(WITH_POINT):
            assert FRAME_PERIOD not in [name for name, _ in model["features"]], key
    calibrated = [
        model
        for key, model in shipped_point_models["calibrated_subsets"].items()
        if key.endswith(WITH_POINT)
    ]
    assert calibrated
    for model in calibrated:
        assert [name for name, _ in model["features"]][-2:] == [IMPACT_X, FRAME_PERIOD]
