"""The one rule pairing labels with impacts (tail_beam_id.stream.label.match) and its tolerance
parameter: one to one, closest pair first, inclusive at the tolerance, extras and misses
counted."""

from __future__ import annotations

import pytest

from tail_beam_id.stream.label import Label, Matching, match, match_stamps, match_tolerance_s
from tail_beam_sim.errors import InputError

TOLERANCE_S = 2.0**-8  # 3.90625 ms: binary-exact, so stamps exactly at the edge are exact too


def truths(*stamps_s: float) -> list[dict]:
    return [{"contact_start_stamp": s, "label": "coal"} for s in stamps_s]


def labels(*stamps_s: float) -> list[Label]:
    return [Label(s, "coal", 0.9, "threshold") for s in stamps_s]


def test_a_truth_takes_the_nearest_label_and_the_rest_are_extra():
    """Of three labels the one nearest the contact start is the impact's; the others (one within
    the tolerance) are extra."""
    matching = match(truths(1.0), labels(1.003, 0.999, 1.3), TOLERANCE_S)
    assert matching == Matching(pairs=((0, 1),), missed=(), extra=(0, 2))
    assert matching.label_index(0) == 1


def test_the_closest_pair_wins_whatever_the_truths_order():
    """A label within reach of two truths goes to the nearer one, even when the other comes
    first; the other is missed."""
    matching = match(truths(1.0, 1.003), labels(1.0025), TOLERANCE_S)
    assert matching.pairs == ((1, 0),) and matching.missed == (0,) and matching.extra == ()
    assert matching.label_index(0) is None


def test_one_label_never_counts_for_two_truths():
    """Two truths whose nearest label is the same one: it pairs with the nearer, the other takes
    the next label within reach."""
    # Per truth nearest-label (the old rule) gave label 0 to both impacts and left label 1 extra.
    matching = match(truths(1.0, 1.002), labels(1.0011, 0.997), TOLERANCE_S)
    assert matching.pairs == ((0, 1), (1, 0)) and matching.missed == () and matching.extra == ()
    single = match(truths(1.0, 1.002), labels(1.0011), TOLERANCE_S)
    assert len(single.pairs) == 1 and single.missed == (0,) and single.extra == ()


def test_the_tolerance_is_inclusive_and_nothing_beyond_it_pairs():
    """A label exactly the tolerance early or late pairs; one 1 us further does not, and counts
    as extra with the impact missed."""
    for sign in (1.0, -1.0):
        assert match(truths(1.0), labels(1.0 + sign * TOLERANCE_S), TOLERANCE_S).pairs == ((0, 0),)
        beyond = match(truths(1.0), labels(1.0 + sign * (TOLERANCE_S + 1e-6)), TOLERANCE_S)
        assert beyond == Matching(pairs=(), missed=(0,), extra=(0,))


def test_extras_and_misses_are_counted_in_a_stream():
    """Three impacts, four labels: two pairs, the impact without a label near it missed, the two
    stray labels extra."""
    matching = match_stamps([0.5, 1.0, 1.5], [2.0, 0.501, 1.2, 1.4995], 0.005)
    assert matching.pairs == ((0, 1), (2, 3))
    assert matching.missed == (1,) and matching.extra == (0, 2)
    assert match_stamps([], [1.0], 0.005) == Matching((), (), (0,))
    assert match_stamps([1.0], [], 0.005) == Matching((), (0,), ())


def test_the_tolerance_comes_from_the_identification_section(params):
    """identification.match_tolerance_s is 5 ms as shipped; missing, zero or over 0.1 s it is
    refused naming the field and the range."""
    assert match_tolerance_s(params["identification"]) == pytest.approx(0.005)
    for bad in (None, 0.0, -0.001, 0.2, "soon"):
        with pytest.raises(InputError) as error:
            match_tolerance_s({"match_tolerance_s": bad})
        assert "identification.match_tolerance_s" in str(error.value) and "0.1" in str(error.value)


def test_a_label_never_carries_a_value_that_is_no_number():
    """Whatever a method returns, the label is strict JSON: a non-finite feature or estimate is
    left out and named, a non-finite confidence becomes 0.5 (no idea), never NaN."""
    import json
    import math

    from tail_beam_id.methods import Decision
    from tail_beam_id.stream.label import make_label

    label = make_label(
        impact_stamp_s=1.0,
        decision=Decision(math.nan, {"logit": math.nan, "p": 0.3}),
        confidence=math.nan,
        method="statistical",
        compute_ms=0.5,
        data_latency_ms=12.0,
        signals=["imu"],
        overlap=False,
        calibrated=False,
        features={"moment_impulse_nms": math.inf, "rebound_speed_mps": 2.0},
    )
    json.loads(label.to_json())  # to_json refuses NaN and Infinity (allow_nan=False)
    assert label.confidence == 0.5
    assert label.features == {"rebound_speed_mps": 2.0, "p": 0.3}
    assert label.non_finite_features == ("logit", "moment_impulse_nms")


def test_a_label_reads_back_from_its_json_as_it_was():
    """Label -> JSON -> Label is the identity, and the JSON keeps the contract's field names and
    order."""
    import json

    label = Label(
        12.345678,
        "gangue",
        0.97,
        "physics",
        latency_ms=0.8,
        data_latency_ms=6.0,
        signals=("jack_pressure", "vibration"),
        overlap=True,
        calibrated=True,
        features={"imu_impulse_mps": 0.02},
        saturated=("jack_pressure",),
        imu_mount="inverted",
        outside_training=("pressure_noise_pa",),
    )
    text = label.to_json()
    assert list(json.loads(text))[:4] == ["impact_stamp", "label", "confidence", "method"]
    assert json.loads(text)["label"] == "gangue" and json.loads(text)["imu_mount"] == "inverted"
    assert Label.from_json(text) == label


def test_another_identifiers_label_with_the_contract_fields_only_is_read_and_its_own_keys_kept():
    """docs/interface.md requires impact_stamp, label, confidence and method; the suite's fields
    default, and a key the suite does not know survives a round trip untouched."""
    label = Label.from_json(
        '{"impact_stamp": 1.5, "label": "coal", "confidence": 0.8, "method": "cnn", '
        '"model_version": "v3", '
        '"material": "sandstone", "extra": 1}'
    )
    assert (label.impact_stamp_s, label.material, label.signals, label.latency_ms) == (
        1.5,
        "coal",
        (),
        None,
    )
    # Keys named like the dataclass's own fields (material, extra) are the other identifier's too.
    assert label.as_dict() == {
        "impact_stamp": 1.5,
        "label": "coal",
        "confidence": 0.8,
        "method": "cnn",
        "signals": [],
        "overlap": False,
        "calibrated": False,
        "features": {},
        "model_version": "v3",
        "material": "sandstone",
        "extra": 1,
    }


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ("[1, 2]", "label"),
        ('{"impact_stamp": 1.0, "label": "coal", "confidence": 0.9}', "label.method"),
        (
            '{"impact_stamp": "1.0", "label": "coal", "confidence": 0.9, "method": "m"}',
            "label.impact_stamp",
        ),
        (
            '{"impact_stamp": true, "label": "coal", "confidence": 0.9, "method": "m"}',
            "label.impact_stamp",
        ),
        (
            '{"impact_stamp": 1.0, "label": "sandstone", "confidence": 0.9, "method": "m"}',
            "label.label",
        ),
        (
            '{"impact_stamp": 1.0, "label": "coal", "confidence": 1.5, "method": "m"}',
            "label.confidence",
        ),
        (
            '{"impact_stamp": 1.0, "label": "coal", "confidence": true, "method": "m"}',
            "label.confidence",
        ),
        (
            '{"impact_stamp": 1.0, "label": "coal", "confidence": 0.9, "method": "m", "signals": '
            '"imu"}',
            "label.signals",
        ),
        (
            '{"impact_stamp": 1.0, "label": "coal", "confidence": 0.9, "method": "m", "features": '
            '{"x": "big"}}',
            "label.features.x",
        ),
        (
            '{"impact_stamp": 1.0, "label": "coal", "confidence": 0.9, "method": "m", "overlap": '
            "1}",
            "label.overlap",
        ),
        ('{"impact_stamp": NaN, "label": "coal", "confidence": 0.9, "method": "m"}', "label"),
        (
            '{"impact_stamp": 1.0, "label": "coal", "confidence": 0.9, "method": "m", "score": '
            "Infinity}",
            "label",
        ),
        ('{"impact_stamp": 1.0, ', "label"),
        ("[" * 100000, "label"),
    ],
)
def test_a_label_that_is_not_one_is_refused_naming_the_field(text, field):
    """Whatever a client publishes on label, reading it gives one InputError naming the field
    and what it allows, never another exception."""
    with pytest.raises(InputError) as error:
        Label.from_json(text)
    assert str(error.value).startswith(f"{field} = ")
    if "NaN" in text or "Infinity" in text:
        assert "not strict JSON" in str(error.value)


def test_a_later_decision_for_a_labelled_impact_is_a_revision_never_a_new_impact():
    """Revisions: a decision from all streams after one from partial streams for the same
    impact (within match_tolerance_s) goes out with the first label's stamp and ``revises``;
    a decision beyond the tolerance is a new impact; restart forgets the old time base."""
    from tail_beam_id.stream.label import Revisions, firsts

    rule = Revisions(0.005)
    partial = Label(2.0, "coal", 0.6, "statistical", signals=("vibration",))
    full = Label(
        2.003,
        "gangue",
        0.9,
        "statistical",
        signals=("jack_pressure", "imu", "vibration", "rebound_velocity"),
    )
    other = Label(2.3, "coal", 0.9, "statistical")
    out = [rule.admit(label) for label in (partial, full, other)]
    assert out[0] == partial
    assert out[1].impact_stamp_s == 2.0 and out[1].revises == 2.0
    assert out[1].material == "gangue" and out[1].signals == full.signals
    assert out[2] == other
    assert (rule.revisions, rule.changed) == (1, 1)
    again = Label.from_json(out[1].to_json())
    assert again.revises == 2.0 and "revises" not in again.extra
    assert firsts(out) == ([out[0], out[2]], [out[1]])
    rule.restart()
    assert rule.admit(full).revises is None
