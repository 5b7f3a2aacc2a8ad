"""The flow scene set of `tail-beam evaluate` on a small size, its figures from a known case, and
the gangue share of a simulated pure-coal flow."""

from __future__ import annotations

import copy
import json
import math

import pytest

from tail_beam_id.stream.label import Label
from tail_beam_id.stream.share import GangueShare, ShareConfig
from tail_beam_id.study.flow import record_sim_flow
from tail_beam_id.study.flow_evaluation import (
    CROSSING_WITHIN_S,
    FlowCase,
    confident_wrong_line,
    coverage_line,
    crossing_delay,
    first_reaching,
    identify_flow,
    rank_auc,
    score_coal,
)
from tail_beam_sim.cli import main
from tail_beam_sim.config import load_parameters


def share(end_s: float, value: float | None) -> GangueShare:
    return GangueShare(end_s - 1.0, end_s, value, 0.0, 1.0, None, 1, 0, 0, "labels", ())


def test_crossings_and_false_alarms_are_read_from_the_interval_ends():
    """Crossings are the first interval end reaching the level after a stamp; pure-coal intervals
    reaching 1/5 count as false."""
    ends = [1.0, 1.5, 2.0, 2.5]
    assert first_reaching(ends, [0.0, 0.3, 0.1, 0.5], 0.2, 0.0) == 1.5
    assert first_reaching(ends, [0.0, 0.3, 0.1, 0.5], 0.2, 1.8) == 2.5
    assert math.isnan(first_reaching(ends, [None, 0.1, 0.1, 0.1], 0.2, 0.0))
    case = FlowCase("nominal", "shipped", 5.0)
    # The crossing rule without a reference needs two consecutive intervals over the level.
    config = ShareConfig(alarm_z=1.5, alarm_intervals=2, alarm_reference_s=0.0)
    score_coal(case, [share(1.0, 0.0), share(1.5, 0.25), share(2.0, None)], config)
    assert (case.coal_intervals, case.false_crossings) == (3, 1)
    assert case.false_alarms == 0
    score_coal(case, [share(3.0, 0.25), share(3.5, 0.3), share(4.0, 0.0)], config)
    assert case.false_alarms == 1
    # config/'s reference: a flow's first 3 s are its top coal, where no alarm rises.
    score_coal(case, [share(3.0, 0.25), share(3.5, 0.3), share(4.0, 0.0)])
    assert case.false_alarms == 1


def test_a_crossing_too_late_in_the_flow_to_judge_is_not_counted_as_missed():
    """A read that never reached the level counts as missed (inf) only where the flow ran
    CROSSING_WITHIN_S past the truth's crossing; nearer the end it is not judged (nan), while
    a read that did reach it keeps its delay however late."""
    end = 10.0
    assert crossing_delay(5.0, math.nan, end) == math.inf
    assert crossing_delay(end - CROSSING_WITHIN_S, math.nan, end) == math.inf
    assert math.isnan(crossing_delay(end - 0.5, math.nan, end))
    assert crossing_delay(end - 0.5, end, end) == pytest.approx(0.5)
    assert crossing_delay(5.0, 4.5, end) == pytest.approx(-0.5)
    assert math.isnan(crossing_delay(math.nan, 6.0, end))


def test_the_score_auc_is_the_mann_whitney_statistic():
    """Separated scores give 1, reversed 0, all tied 0.5; 3 positives at 2, 4, 6 against 1, 3,
    5 win 6 of 9 pairs; one class alone gives nan."""
    assert rank_auc([1, 2, 3, 4], [False, False, True, True]) == 1.0
    assert rank_auc([4, 3, 2, 1], [False, False, True, True]) == 0.0
    assert rank_auc([1, 1, 1, 1], [False, True, False, True]) == 0.5
    assert rank_auc([1, 2, 3, 4, 5, 6], [False, True] * 3) == pytest.approx(6 / 9)
    assert math.isnan(rank_auc([1.0, 2.0], [True, True]))


def test_a_sparse_pure_coal_flow_reads_near_zero_with_intervals_holding_it():
    """Pure coal at 3 lumps/s on the nominal support: almost every interval's interval holds
    0, and the labels are mostly coal."""
    params = load_parameters([])
    recording = record_sim_flow(params, 3.0, 5.0, 0.0, 0.0, 0.0, seed=9001)
    assert not any(t["label"] == "gangue" for t in recording.truths)
    labels, shares = identify_flow(recording, "shipped")
    assert len(shares) >= 6 and [s.end_stamp_s for s in shares] == sorted(
        s.end_stamp_s for s in shares
    )
    rested = [s for s in shares if s.share is not None]
    holding_zero = sum(s.low == 0.0 for s in rested)
    assert holding_zero >= len(rested) - 1
    coal = sum(isinstance(lab, Label) and lab.material == "coal" for lab in labels)
    assert coal >= 0.8 * len(labels)


def test_a_dense_pure_coal_flow_raises_no_alarm_and_no_lower_bound_reaches_a_fifth():
    """Pure coal at 50 lumps/s for 4 s on the nominal support: the shares rest on the mixture
    of about 50 labels a second; no interval's lower 95 % bound reaches 1/5, and the crossing
    rule never rises at 1/5 or 1/3."""
    from tail_beam_id.stream.share import ShareConfig
    from tail_beam_id.stream.share_alarm import alarm_states

    params = load_parameters([])
    recording = record_sim_flow(params, 50.0, 4.0, 0.0, 0.0, 0.0, seed=9003)
    assert not any(t["label"] == "gangue" for t in recording.truths)
    _, shares = identify_flow(recording, "shipped")
    rested = [s for s in shares if s.share is not None]
    assert len(rested) >= 5 and all(s.basis_method == "mixture" for s in rested[1:])
    assert all(s.low < 0.2 for s in rested)
    config = ShareConfig.from_params(recording.params["identification"].get("gangue_share"))
    for level in (0.2, 1.0 / 3.0):
        assert not any(alarm_states(shares, level, config))


def test_a_drawn_supports_flow_is_read_with_what_the_profile_knows_of_it():
    """The flow set's profiles: self-calibrated finds a drawn support's sway from its own
    flow (within 3 %, where config/ is 13 % off), nominal is config/ itself, true the drawn
    support; a pure-coal flow's labels follow."""
    from tail_beam_id.study.flow_evaluation import flow_supports, reading_params
    from tail_beam_sim.physics.scene import Scene

    params = load_parameters([])
    _, draw = flow_supports(params, 1, 777)[1]
    recording = record_sim_flow(params, 5.0, 6.0, 0.0, 0.0, 0.0, seed=9011, support=draw)

    def sway_hz(p):
        return Scene.from_params(p).support.rigid_mode_frequency_hz

    true_hz = sway_hz(recording.params)
    assert abs(sway_hz(params) / true_hz - 1.0) > 0.1  # the drawn support is another one
    calibrated = reading_params(params, recording, "self-calibrated", "shipped")
    assert sway_hz(calibrated) == pytest.approx(true_hz, rel=0.03)
    assert reading_params(params, recording, "nominal", "shipped") is params
    assert sway_hz(reading_params(params, recording, "true", "shipped")) == true_hz
    labels, _ = identify_flow(recording, "shipped", None, calibrated)
    assert sum(isinstance(lab, Label) and lab.material == "coal" for lab in labels) >= 0.8 * len(
        labels
    )


@pytest.mark.slow
def test_evaluate_flow_set_on_a_small_size(capsys, tmp_path):
    """`tail-beam evaluate --sets flow` runs every support and layout, prints the targets and
    writes flow.json with finite figures."""
    code = main(
        [
            "evaluate",
            "--sets",
            "flow",
            "--flow-rates",
            "5",
            "--flow-foreign",
            "1",
            "--flow-duration-s",
            "4",
            "--flow-coal-s",
            "2",
            "--flow-seed",
            "7",
            "--out",
            str(tmp_path),
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    assert "targets (flow; shipped layout):" in out and "foreign-1" in out
    assert "seed 7," in out
    assert "crossing rule (share_alarm)" in out
    cases = json.loads((tmp_path / "flow.json").read_text())
    assert {(c["support"], c["layout"]) for c in cases} == {
        (s, layout) for s in ("nominal", "foreign-1") for layout in ("shipped", "imu")
    }
    assert "95 % intervals holding the true share:" in out
    assert "wrong labels at confidence >= 0.9:" in out
    for case in cases:
        assert case["intervals"] >= 3 and 0.0 <= case["mae"] <= 1.0
        assert 0.0 <= case["coverage"] <= 1.0 and case["false_alarms"] >= 0
        assert case["coal_intervals"] >= 1 and case["impacts"] >= 10
        # Confident wrong labels are among the wrong ones.
        wrong = case["impacts"] - round(case["accuracy"] * case["impacts"])
        assert 0 <= case["confident_wrong"] <= wrong
        # Each scored interval is tallied under the method that read it, once.
        tallies = case["coverage_by_method"].values()
        assert sum(n for _, n in tallies) == case["intervals"]
        assert sum(h for h, _ in tallies) == round(case["coverage"] * case["intervals"])


def test_the_coverage_line_sums_the_intervals_holding_the_truth_by_method():
    """Two cases' tallies add up per method and in all; no scored interval says so."""
    first, second = FlowCase("nominal", "shipped", 5.0), FlowCase("foreign-1", "shipped", 50.0)
    first.covered_by_method = {"labels": [18, 19], "mixture": [1, 1]}
    second.covered_by_method = {"mixture": [15, 20]}
    line = coverage_line([first, second])
    assert line.startswith("95 % intervals holding the true share: 34 of 40 (85 %;")
    assert "labels 18 of 19 (95 %)" in line and "mixture 16 of 21 (76 %)" in line
    assert coverage_line([FlowCase("nominal", "shipped", 5.0)]).endswith("none scored")


def test_the_confident_wrong_line_counts_over_every_impact():
    """Two cases' confident wrong labels over their impacts (lumps and extra labels)."""
    first, second = FlowCase("nominal", "shipped", 5.0), FlowCase("foreign-1", "shipped", 50.0)
    first.confident_wrong, first.impacts = 1, 40
    second.confident_wrong, second.impacts = 3, 160
    line = confident_wrong_line([first, second])
    assert line.startswith("wrong labels at confidence >= 0.9: 4 of 200 impacts (2.0 %)")
    assert confident_wrong_line([]).startswith("wrong labels at confidence >= 0.9: 0 of 0")


@pytest.mark.parametrize(
    ("argv", "field"),
    [
        (["evaluate", "--sets", "flow", "--flow-rates", "-5"], "--flow-rates"),
        (["evaluate", "--sets", "flow", "--flow-duration-s", "0.5"], "--flow-duration-s"),
        (["evaluate", "--sets", "flow", "--flow-foreign", "-1"], "--flow-foreign"),
        (["evaluate", "--sets", "flow", "--flow-layouts", "camera"], "--flow-layouts"),
        (["evaluate", "--sets", "flow", "--flow-seed", "-1"], "--flow-seed"),
    ],
)
def test_bad_flow_options_are_refused_in_one_line(capsys, argv, field):
    """Each bad flow option exits 2 with one line naming it."""
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and field in err


def label_record(label: Label) -> dict:
    """A label's JSON without its wall-clock latency."""
    data = json.loads(label.to_json())
    data.pop("latency_ms", None)
    return data


@pytest.mark.parametrize(
    ("rate_per_s", "duration_s", "seed"), [(50.0, 3.0, 9002), (200.0, 2.0, 9101)]
)
def test_a_dense_flows_labels_and_shares_do_not_depend_on_how_the_streams_were_chunked(
    rate_per_s, duration_s, seed
):
    """A dense flow replayed in 10 ms, 3.7 ms and 21.3 ms chunks (as id_node's batches differ
    from replay's) gives the same labels (overlap flags and rebounds among them) and the same
    shares."""
    from tail_beam_id.stream.replay import replay
    from tail_beam_id.stream.share_reader import SharingIdentifier

    params = load_parameters([])
    recording = record_sim_flow(
        params, rate_per_s, duration_s, 0.5 * duration_s, 0.5, 0.7, seed=seed
    )
    runs = []
    for chunk_s in (0.01, 0.0037, 0.0213):
        identifier = SharingIdentifier(
            None, params=recording.params["identification"], model_params=recording.params
        )
        labels = replay(
            identifier,
            recording.pressure,
            recording.imu,
            recording.rebounds,
            chunk_s=chunk_s,
            vibration=recording.vibration,
        )
        runs.append(
            (
                [label_record(lab) for lab in labels],
                [s.to_json() for s in identifier.take_shares()],
            )
        )
    assert len(runs[0][0]) >= 0.5 * rate_per_s * duration_s and len(runs[0][1]) >= 3
    assert any(lab["overlap"] for lab in runs[0][0])
    assert runs[1] == runs[0] and runs[2] == runs[0]


def test_a_flow_whose_camera_reports_the_impact_point_is_read_with_it():
    """The flow set's recordings keep the camera's impact points, and identify_flow hands them
    to the identifier: with sensors.camera_reports_impact_point every label of a sparse flow
    rests on a point (feature impact_x_m, within 0.06 m of where its lump struck); the same flow
    without it gives labels without one."""
    params = copy.deepcopy(dict(load_parameters([])))
    params["sensors"]["camera_reports_impact_point"] = True
    pointed = record_sim_flow(params, 3.0, 4.0, 0.0, 0.0, 0.0, seed=9005)
    assert len(pointed.points) == len(pointed.rebounds) >= 6
    labels, _ = identify_flow(pointed, "shipped")
    struck = {round(t["contact_start_stamp"], 3): t["position_m"] for t in pointed.truths}
    read = [lab for lab in labels if isinstance(lab, Label)]
    assert len(read) >= 6
    for lab in read:
        assert "impact_x_m" in lab.features
        nearest = min(struck, key=lambda stamp: abs(stamp - lab.impact_stamp_s))
        assert abs(lab.features["impact_x_m"] - struck[nearest]) < 0.06
    params["sensors"]["camera_reports_impact_point"] = False
    plain = record_sim_flow(params, 3.0, 4.0, 0.0, 0.0, 0.0, seed=9005)
    assert plain.points == []
    assert not any("impact_x_m" in lab.features for lab in identify_flow(plain, "shipped")[0])
