"""The gangue-share estimator's core (tail_beam_id.stream.share): analytic cases, the Wilson
interval, the mixture estimate of a dense flow's scores, and bad input refused by name."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tail_beam_id.stream.label import Label
from tail_beam_id.stream.share import (
    GangueShare,
    ScoreModel,
    ShareConfig,
    estimate_share,
    interval_ends,
    label_score,
    regime_of,
    wilson_interval,
)
from tail_beam_sim.errors import InputError

CONFIG = ShareConfig()


def label(stamp_s: float, material: str, overlap: bool = False) -> Label:
    return Label(stamp_s, material, 0.9, "statistical", signals=("vibration",), overlap=overlap)


def test_all_coal_gives_zero_with_an_interval_holding_zero():
    """All-coal labels give a share of 0, a Wilson interval from 0 to z^2 / (n + z^2), by count."""
    labels = [label(0.1 * k, "coal") for k in range(12)]
    share = estimate_share(labels, 0.0, 1.0, CONFIG)
    assert share.share == 0.0 and share.low == 0.0
    # Wilson at 0 of 10 (the labels in [0, 1)): z^2 / (n + z^2) = 0.2775
    assert share.lumps == 10 and share.high == pytest.approx(1.96**2 / (10 + 1.96**2), abs=1e-3)
    assert share.basis == "count" and share.basis_method == "labels"
    assert share.signals == ("vibration",)


def test_a_known_mix_gives_the_binomial_share_and_its_wilson_interval():
    """3 gangue labels of 10 give 0.3, the textbook Wilson interval 0.108-0.603 and the binomial
    standard error."""
    materials = ["gangue"] * 3 + ["coal"] * 7
    labels = [label(0.05 + 0.09 * k, m) for k, m in enumerate(materials)]
    share = estimate_share(labels, 0.0, 1.0, CONFIG)
    assert share.share == pytest.approx(0.3) and share.gangue_lumps == 3
    # The published Wilson 95 % interval of 3/10: 0.108 - 0.603.
    assert share.low == pytest.approx(0.1078, abs=5e-4)
    assert share.high == pytest.approx(0.6032, abs=5e-4)
    assert share.standard_error == pytest.approx(math.sqrt(0.3 * 0.7 / 10))


def test_wilson_interval_limits():
    """The Wilson interval of nothing is [0, 1], of 50/100 symmetric; more successes than trials
    are refused."""
    assert wilson_interval(0, 0) == (0.0, 1.0)
    low, high = wilson_interval(50, 100)
    assert low == pytest.approx(1 - high) and low == pytest.approx(0.4038, abs=5e-4)
    with pytest.raises(InputError, match="successes"):
        wilson_interval(5, 3)


def two_bin_model(regime: str = "vibration/overlap", wrong: float = 0.0) -> ScoreModel:
    """Scores below 0 (coal-like) and above (gangue-like); a lump scores on the wrong side with
    probability ``wrong``."""
    edges = np.array([-12.0, 0.0, 12.0])
    coal = np.array([1.0 - wrong, wrong]) / 12.0
    gangue = np.array([wrong, 1.0 - wrong]) / 12.0
    pair = (np.maximum(coal, 1e-12), np.maximum(gangue, 1e-12))
    return ScoreModel(edges, {f"{regime}/{k}": pair for k in range(5)})


def scored(stamp_s: float, gangue_like: bool) -> Label:
    logit_of_coal = -3.0 if gangue_like else 3.0
    return Label(
        stamp_s,
        "gangue" if gangue_like else "coal",
        0.6,
        "statistical",
        signals=("vibration",),
        overlap=True,
        features={"logit": logit_of_coal},
    )


def test_dense_labels_with_a_perfect_score_give_the_count_share():
    """Overlapping labels whose scores separate the materials perfectly: the mixture estimate is
    the count share with the binomial standard error."""
    labels = [scored(0.01 * k, k % 10 < 3) for k in range(100)]
    share = estimate_share(labels, 0.0, 1.0, CONFIG, two_bin_model())
    assert share.basis_method == "mixture" and share.share == pytest.approx(0.3, abs=1e-9)
    assert share.low < 0.3 < share.high and share.lumps == 100 and share.overlapping == 100
    assert share.standard_error == pytest.approx(math.sqrt(0.3 * 0.7 / 100), rel=0.01)


def test_a_classifier_wrong_a_fifth_of_the_time_still_gives_the_true_share():
    """Labels wrong at random (20 %) read as a count give 0.2 + 0.6 x share; the mixture
    estimate undoes it: its interval holds the true share."""
    rng = np.random.default_rng(5)
    truth = rng.uniform(size=4000) < 0.3
    flipped = rng.uniform(size=truth.size) < 0.2
    labels = [scored(k / truth.size, bool(g != f)) for k, (g, f) in enumerate(zip(truth, flipped))]
    share = estimate_share(labels, 0.0, 1.0, CONFIG, two_bin_model(wrong=0.2))
    naive = share.gangue_lumps / share.lumps
    assert naive == pytest.approx(0.2 + 0.6 * truth.mean(), abs=0.03)
    assert share.low <= truth.mean() <= share.high
    assert abs(share.share - truth.mean()) < 3 * share.standard_error


def test_all_coal_in_a_dense_flow_gives_an_interval_holding_zero():
    """Pure coal with a tenth of the scores gangue-like, as the model expects: the mixture estimate
    is about 0 and its interval starts at 0."""
    labels = [scored(0.01 * k, k % 10 == 0) for k in range(100)]  # 10 % wrongly gangue-like
    share = estimate_share(labels, 0.0, 1.0, CONFIG, two_bin_model(wrong=0.1))
    assert share.share == pytest.approx(0.0, abs=0.02) and share.low == 0.0


def test_labels_whose_signals_the_model_does_not_know_are_counted():
    """Labels of signals the score model lacks fall back to the count; a regime it lacks for
    these signals takes the nearest it has (another flow density, then the other overlap)."""
    labels = [scored(0.01 * k, k % 2 == 0) for k in range(10)]
    share = estimate_share(labels, 0.0, 1.0, CONFIG, two_bin_model("imu/overlap"))
    assert share.basis_method == "labels" and share.share == pytest.approx(0.5)
    only_dense = ScoreModel(
        two_bin_model().edges,
        {"vibration/alone/4": two_bin_model().densities["vibration/overlap/4"]},
    )
    share = estimate_share(labels, 0.0, 1.0, CONFIG, only_dense)
    assert share.basis_method == "mixture" and share.share == pytest.approx(0.5, abs=1e-9)


def test_labels_that_read_the_impact_point_are_scored_without_it_where_the_model_lacks_it():
    """A camera reporting the impact point adds ``impact_point`` to a label's signals; a score
    model learnt without the point reads such labels with the logit they would have had without
    it, in the regime of their signals without it: the share is the one the same lumps give
    without the point, not the count. A model that knows the point's regime reads the logit
    that used it."""
    truth = [k % 10 < 3 for k in range(100)]
    plain = [scored(0.01 * k, g) for k, g in enumerate(truth)]
    # With the point, the decision turned (logit +3 <-> -3): only the logit without it agrees
    # with the model's coal-like / gangue-like sides.
    pointed = [
        Label(
            lab.impact_stamp_s,
            lab.material,
            lab.confidence,
            lab.method,
            signals=("impact_point", "vibration"),
            overlap=True,
            features={
                "logit": -lab.features["logit"],
                "logit_without_point": lab.features["logit"],
            },
        )
        for lab in plain
    ]
    without = estimate_share(plain, 0.0, 1.0, CONFIG, two_bin_model())
    read = estimate_share(pointed, 0.0, 1.0, CONFIG, two_bin_model())
    assert read.basis_method == "mixture" and read.share == pytest.approx(without.share)
    assert read.share == pytest.approx(0.3, abs=1e-9)
    knows_point = two_bin_model("impact_point+vibration/overlap")
    assert estimate_share(pointed, 0.0, 1.0, CONFIG, knows_point).share == pytest.approx(0.7)


def test_the_systematic_error_adds_to_the_statistical_one_in_quadrature():
    """A model stating a systematic error of 0.1 at this density: the standard error is the
    binomial one and 0.1 in quadrature, and the interval widens by at least 1.96 x 0.1 below
    and above a share away from the ends."""
    labels = [scored(0.01 * k, k % 10 < 3) for k in range(100)]
    plain = two_bin_model()
    model = ScoreModel(plain.edges, plain.densities, (0.0, 0.0, 0.0, 0.1, 0.1))
    share = estimate_share(labels, 0.0, 1.0, CONFIG, model)
    statistical = math.sqrt(0.3 * 0.7 / 100)
    assert share.share == pytest.approx(0.3, abs=1e-9)
    assert share.standard_error == pytest.approx(math.hypot(statistical, 0.1), rel=0.01)
    assert share.low <= 0.3 - 1.96 * 0.1 and share.high >= 0.3 + 1.96 * 0.1
    assert ScoreModel.from_dict(model.as_dict()).systematic_se == model.systematic_se
    with pytest.raises(InputError, match="systematic_se"):
        ScoreModel.from_dict(dict(model.as_dict(), systematic_se=[0.1, 2.0]))


def test_a_known_synthetic_share_is_recovered_within_its_stated_error():
    """Scores drawn from the model's own densities (a fifth on the wrong side) at a known share
    of 0.35, 200 lumps an interval, 60 intervals: the 95 % interval holds the truth in at least
    90 % of them (binomial: 57 of 60 expected) and the errors' spread matches the standard
    error within a third."""
    rng = np.random.default_rng(11)
    model = two_bin_model(wrong=0.2)
    held, errors, ses = 0, [], []
    for _ in range(60):
        truth = rng.uniform(size=200) < 0.35
        flipped = rng.uniform(size=truth.size) < 0.2
        labels = [
            scored(k / truth.size, bool(g != f)) for k, (g, f) in enumerate(zip(truth, flipped))
        ]
        share = estimate_share(labels, 0.0, 1.0, CONFIG, model)
        held += share.low <= truth.mean() <= share.high
        errors.append(share.share - truth.mean())
        ses.append(share.standard_error)
    assert held >= 54
    assert float(np.std(errors)) == pytest.approx(float(np.mean(ses)), rel=0.34)


def test_the_score_uses_the_uncapped_logit_else_the_confidence():
    """The score is minus the method's logit of coal, else the logit of the stated probability of
    gangue."""
    assert label_score(scored(0.0, True)) == 3.0
    plain = Label(0.0, "gangue", 0.8, "threshold")
    assert label_score(plain) == pytest.approx(math.log(4.0))
    assert regime_of(plain, 10.0) == "/alone/0"
    assert regime_of(scored(0.0, True), 200.0) == "vibration/overlap/4"


def test_no_labels_and_no_model_say_nothing():
    """An interval without labels gives a null share over [0, 1] and reads back from JSON."""
    share = estimate_share([], 0.0, 1.0, CONFIG)
    assert share.share is None and (share.low, share.high) == (0.0, 1.0)
    assert GangueShare.from_json(share.to_json()) == share


def test_the_message_reads_back_and_a_bad_one_is_refused_by_name():
    """A share's JSON reads back equal; a missing field or a share above 1 is refused by name."""
    share = estimate_share([label(0.5, "gangue")], 0.0, 1.0, CONFIG)
    assert GangueShare.from_json(share.to_json()) == share
    with pytest.raises(InputError, match="gangue_share.lumps"):
        GangueShare.from_json(
            '{"share": 0.1}'.replace(
                "}",
                ', "start_stamp_s": 0, '
                '"end_stamp_s": 1, "low": 0, "high": 1, '
                '"standard_error": null}',
            )
        )
    with pytest.raises(InputError, match="gangue_share.share"):
        GangueShare.from_json(share.to_json().replace('"share": 1.0', '"share": 1.5'))


def test_bad_settings_and_intervals_are_refused_by_name():
    """A hop longer than the interval, a negative interval and an empty interval are refused by
    name."""
    with pytest.raises(InputError, match="identification.gangue_share.hop_s"):
        ShareConfig.from_params({"hop_s": 2.0, "interval_s": 1.0})
    with pytest.raises(InputError, match="identification.gangue_share.interval_s"):
        ShareConfig.from_params({"interval_s": -1.0})
    with pytest.raises(InputError, match="end_stamp_s"):
        estimate_share([], 1.0, 1.0, CONFIG)


def test_interval_ends_lie_on_the_grid_within_the_data():
    """Interval ends lie on the hop grid, each interval wholly within the data."""
    assert interval_ends(0.03, 2.6, CONFIG) == [1.5, 2.0, 2.5]
    assert interval_ends(0.0, 0.9, CONFIG) == []
