"""The gangue-share estimator's core (tail_beam_id.stream.share): analytic cases, the interval
of a sparse flow's true count given its labels' confidences, the mixture estimate of a dense
flow's scores, and bad input refused by name."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from tail_beam_id.stream.label import Label
from tail_beam_id.stream.share import (
    GangueShare,
    ScoreModel,
    ShareConfig,
    count_interval,
    estimate_share,
    gangue_probability,
    interval_ends,
    label_score,
    regime_of,
)
from tail_beam_sim.errors import InputError

CONFIG = ShareConfig()


def label(stamp_s: float, material: str, overlap: bool = False) -> Label:
    return Label(stamp_s, material, 0.9, "statistical", signals=("vibration",), overlap=overlap)


def enumerated_interval(probabilities: list[float], level: float = 0.95) -> tuple[float, float]:
    """The central interval of the share of gangue among lumps each gangue with its own
    probability, by enumerating every assignment of materials (an independent reference for
    count_interval)."""
    n = len(probabilities)
    pmf = np.zeros(n + 1)
    for materials in itertools.product((0, 1), repeat=n):
        chance = math.prod(q if m else 1 - q for q, m in zip(probabilities, materials))
        pmf[sum(materials)] += chance
    cdf = np.cumsum(pmf)
    tail = (1 - level) / 2
    low = min(k for k in range(n + 1) if cdf[k] > tail - 1e-12)
    high = min(k for k in range(n + 1) if cdf[k] >= 1 - tail - 1e-12)
    return low / n, high / n


def test_all_coal_gives_zero_with_the_interval_the_labels_confidences_give():
    """Ten coal labels each 0.9 sure give a share of 0 by count; its interval is that of the
    true count when each lump is gangue with probability 0.1 (enumerated: 0 to 0.3), and the
    standard error is the labels' own (sqrt(10 x 0.1 x 0.9) / 10): no sampling error at 0."""
    labels = [label(0.1 * k, "coal") for k in range(12)]
    share = estimate_share(labels, 0.0, 1.0, CONFIG)
    assert share.share == 0.0 and share.lumps == 10
    assert (share.low, share.high) == pytest.approx(enumerated_interval([0.1] * 10))
    assert (share.low, share.high) == pytest.approx((0.0, 0.3))
    assert share.standard_error == pytest.approx(math.sqrt(10 * 0.1 * 0.9) / 10)
    assert share.basis == "count" and share.basis_method == "labels"
    assert share.signals == ("vibration",)


def test_a_known_mix_gives_the_count_share_and_the_interval_of_its_true_count():
    """3 gangue labels of 10, each 0.9 sure: the share is 0.3; the interval is the enumerated
    one of lumps gangue with probability 0.9 (three) and 0.1 (seven); the standard error adds
    the flow's binomial sampling and the labels' own in quadrature."""
    materials = ["gangue"] * 3 + ["coal"] * 7
    labels = [label(0.05 + 0.09 * k, m) for k, m in enumerate(materials)]
    share = estimate_share(labels, 0.0, 1.0, CONFIG)
    assert share.share == pytest.approx(0.3) and share.gangue_lumps == 3
    assert (share.low, share.high) == pytest.approx(enumerated_interval([0.9] * 3 + [0.1] * 7))
    labels_variance = (3 * 0.09 + 7 * 0.09) / 100
    assert share.standard_error == pytest.approx(math.sqrt(0.3 * 0.7 / 10 + labels_variance))


def test_certain_labels_give_a_point_and_unsure_ones_a_wide_interval():
    """Labels sure of themselves (confidence 1) leave the count exact: the interval is the
    count share itself. Lumps each gangue with probability 1/2 give the binomial's central 95 %
    interval of 10 trials, 2 to 8, and its standard deviation sqrt(10 / 4) / 10."""
    assert count_interval([1.0] * 3 + [0.0] * 7) == pytest.approx((0.3, 0.3, 0.0))
    assert count_interval([0.5] * 10) == pytest.approx((0.2, 0.8, math.sqrt(2.5) / 10))
    rng = np.random.default_rng(3)
    for _ in range(5):
        probabilities = list(rng.uniform(size=9))
        assert count_interval(probabilities)[:2] == pytest.approx(
            enumerated_interval(probabilities)
        )
    with pytest.raises(InputError, match="gangue_probabilities"):
        count_interval([])


def test_the_interval_holds_the_labels_own_count():
    """Ten gangue labels each only 0.55 sure: the true count's interval alone would end below
    10 of 10, the count the labels give; the interval is widened to hold it. A non-finite
    confidence says nothing: the lump is gangue with probability 1/2."""
    labels = [
        Label(0.05 + 0.09 * k, "gangue", 0.55, "statistical", signals=("vibration",))
        for k in range(10)
    ]
    assert enumerated_interval([0.55] * 10)[1] < 1.0
    share = estimate_share(labels, 0.0, 1.0, CONFIG)
    assert share.share == 1.0 and share.high == 1.0
    assert share.low == pytest.approx(enumerated_interval([0.55] * 10)[0])
    unsure = Label(0.0, "coal", math.nan, "statistical")
    assert gangue_probability(unsure) == 0.5


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
