"""The caving study: the oracle as the drawing model closes it, perfect labels as good as the
truth, determinism by seed, the stand-in labels as stated, and `tail-beam caving`."""

from __future__ import annotations

import argparse
import dataclasses
import re

import numpy as np
import pytest

from tail_beam_id.caving.rules import rule_factories
from tail_beam_id.cli import caving_cmd
from tail_beam_id.study.caving import (
    LabelModel,
    frontier_recovery,
    oracle_curve_rules,
    run_one,
    run_study,
    shortfalls,
    summarise,
    wilson,
)
from tail_beam_id.study.caving_latency import latency_study
from tail_beam_sim.physics.face import (
    FaceParams,
    close_at_true_share,
    load_face_parameters,
    run_face,
)


def small_face(**changes) -> tuple[FaceParams, dict]:
    """Three supports of the shipped face, coarse cells (fast), and the shipped caving section."""
    params = load_face_parameters()
    face = FaceParams.from_params(params).with_changes(
        supports=3, group_size=3, cell_size_m=0.25, **changes
    )
    return face, params["caving"]


def test_wilson_interval_of_a_share():
    """0 of 10: [0, z^2 / (n + z^2)] = [0, 0.2775]; 5 of 10 is symmetric about 0.5."""
    low, high = wilson(0, 10)
    assert low == 0.0 and high == pytest.approx(3.8415 / 13.8415, rel=1e-4)
    low, high = wilson(5, 10)
    assert low + high == pytest.approx(1.0) and high == pytest.approx(0.7634, abs=1e-4)
    for total in range(1, 200):  # the share itself always lies inside, rounding and all
        assert wilson(total, total)[1] == 1.0 and wilson(0, total)[0] == 0.0


def test_the_study_oracle_closes_where_the_drawing_model_closes():
    """The oracle fed by the study's truth gives the recovery and gangue content of the
    drawing model closed at the same true share: the study adds nothing to the draw."""
    face, caving = small_face()
    model = LabelModel.from_params(caving["labels"])
    run = run_one(face, rule_factories(caving)["oracle"], "oracle", "truth", model, 4)
    direct = run_face(
        face.with_changes(seed=4),
        close_at_true_share(caving["oracle_level"], face.share_window_kg),
    )
    assert run.recovery == direct.recovery and run.gangue_content == direct.gangue_content


def test_perfect_prompt_labels_decide_as_the_truth_does():
    """Labels always right with no latency give the rules that count labels the truth's result
    (the SPRT weighs confidences, which the truth states as 1)."""
    face, caving = small_face()
    labels = dict(caving["labels"], accuracy=1.0, latency_s=0.0)
    model = LabelModel.from_params(labels)
    makers = rule_factories(caving)
    for rule in ("first_gangue", "share_0.333", "share_0.2"):
        truth = run_one(face, makers[rule], rule, "truth", model, 2)
        stand_in = run_one(face, makers[rule], rule, "stand-in", model, 2)
        assert (truth.recovery, truth.gangue_content) == (
            stand_in.recovery,
            stand_in.gangue_content,
        )


def test_wrong_labels_cost_first_gangue_its_coal():
    """With 5 % wrong labels at tens of lumps a second, first gangue closes each window on a
    wrong label within seconds: far less top coal than on the truth."""
    face, caving = small_face()
    runs = run_study(face, caving, [0], rules=["first_gangue"])
    by_source = {r.source: r for r in runs}
    assert by_source["stand-in"].recovery < 0.5 * by_source["truth"].recovery


def test_the_study_is_deterministic_by_seed():
    """The same seeds give the same runs (wall time aside); another seed another face."""
    face, caving = small_face()

    def strip(runs):
        return [dataclasses.replace(r, wall_s=0.0) for r in runs]

    a = run_study(face, caving, [0, 1], rules=["sprt", "oracle"])
    b = run_study(face, caving, [0, 1], rules=["sprt", "oracle"])
    assert strip(a) == strip(b)
    assert a[0].recovery != a[3].recovery  # seed 0 against seed 1, sprt truth
    summary = summarise(a)
    assert [(s.rule, s.source, s.seeds) for s in summary] == [
        ("sprt", "truth", 2),
        ("sprt", "stand-in", 2),
        ("oracle", "truth", 2),
    ]


def test_stand_in_confidences_have_the_stated_means():
    """The Beta draws' means are confidence_right and confidence_wrong, all in [0.5, 1]."""
    model = LabelModel.from_params(
        dict(
            load_face_parameters()["caving"]["labels"], confidence_right=0.9, confidence_wrong=0.7
        )
    )
    rng = np.random.default_rng(0)
    right = np.array([model.confidence(rng, True) for _ in range(4000)])
    wrong = np.array([model.confidence(rng, False) for _ in range(4000)])
    assert right.mean() == pytest.approx(0.9, abs=0.01)
    assert wrong.mean() == pytest.approx(0.7, abs=0.01)
    assert right.min() >= 0.5 and wrong.max() <= 1.0


def parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="tail-beam")
    caving_cmd.register(parser.add_subparsers(dest="command"))
    return parser.parse_args(["caving", *argv])


def test_the_caving_verb_prints_its_table_and_writes_its_chart(tmp_path, capsys):
    """`tail-beam caving` on 3 supports: a row per rule and source with intervals, the field
    trial, the speed over real time, and the chart's file."""
    pytest.importorskip("matplotlib")
    chart = tmp_path / "sub" / "chart.png"
    args = parse(
        [
            "--supports",
            "3",
            "--seeds",
            "2",
            "--rules",
            "first_gangue,oracle",
            "--chart",
            str(chart),
        ]
    )
    assert caving_cmd.run(args) == 0
    out = capsys.readouterr().out
    assert "first_gangue    stand-in      2" in out and "oracle          truth         2" in out
    assert "Tashan 8222 field trial: recovery 80.53 %, gangue content 4.00 %" in out
    assert "x real time" in out and chart.stat().st_size > 0


def test_the_caving_verb_names_bad_options(tmp_path):
    """An unknown source or rule, seeds out of range, or a chart that cannot be written (a
    folder that is a file, a symbolic link): InputError naming the option, before any run."""
    from tail_beam_sim.errors import InputError

    with pytest.raises(InputError, match="--sources = 'labels'"):
        caving_cmd.run(parse(["--sources", "labels", "--chart", ""]))
    with pytest.raises(InputError, match="rules = 'second_gangue'"):
        caving_cmd.run(parse(["--rules", "second_gangue", "--chart", "", "--supports", "1"]))
    with pytest.raises(InputError, match="--seeds = 0"):
        caving_cmd.run(parse(["--seeds", "0", "--chart", ""]))
    not_a_folder = tmp_path / "file"
    not_a_folder.write_text("")
    with pytest.raises(InputError, match="is not a directory"):
        caving_cmd.run(parse(["--chart", str(not_a_folder / "chart.png")]))
    link = tmp_path / "link.png"
    link.symlink_to(tmp_path / "elsewhere.png")
    with pytest.raises(InputError, match="symbolic link"):
        caving_cmd.run(parse(["--chart", str(link)]))


def test_the_oracle_curve_envelope_is_the_best_recovery_at_no_more_gangue():
    """Hand-made curve (gangue, recovery): between points the envelope is linear, a point
    below a point of less gangue is raised to it, beyond the last it is flat, and below the
    least gangue there is no comparison."""
    points = [(0.02, 0.70), (0.04, 0.80), (0.05, 0.78), (0.08, 0.86)]
    assert frontier_recovery(points, 0.03) == pytest.approx(0.75)
    assert frontier_recovery(points, 0.05) == pytest.approx(0.80)  # 0.78 raised to 0.80
    assert frontier_recovery(points, 0.065) == pytest.approx(0.83)
    assert frontier_recovery(points, 0.20) == pytest.approx(0.86)
    assert np.isnan(frontier_recovery(points, 0.01))


def _run(rule: str, seed: int, gangue: float, recovery: float, source: str = "truth"):
    from tail_beam_id.study.caving import CavingRun

    return CavingRun(rule, source, seed, recovery, gangue, 100.0, 0.1, 0)


def test_shortfall_is_paired_by_seed_against_that_seeds_curve():
    """A rule 2 points below seed 0's curve and 4 below seed 1's falls 3 points short on
    average, with both seeds counted; one with less gangue than a seed's curve reaches
    is left out on that seed; without a curve nothing is compared."""
    runs = [
        _run("oracle@0.1", 0, 0.02, 0.70),
        _run("oracle@0.3", 0, 0.06, 0.80),
        _run("oracle@0.1", 1, 0.03, 0.60),
        _run("oracle@0.3", 1, 0.05, 0.90),
        _run("sprt", 0, 0.04, 0.73, "identified:shipped"),  # curve 0.75 there
        _run("sprt", 1, 0.04, 0.71, "identified:shipped"),  # curve 0.75 there
        _run("first_gangue", 0, 0.01, 0.10, "identified:shipped"),
        _run("first_gangue", 1, 0.04, 0.70, "identified:shipped"),
    ]
    short = shortfalls(runs)
    sprt = short[("sprt", "identified:shipped")]
    assert sprt.seeds == 2 and sprt.mean == pytest.approx(0.03)
    assert sprt.interval[0] < 0.03 < sprt.interval[1]
    first = short[("first_gangue", "identified:shipped")]
    assert first.seeds == 1 and first.mean == pytest.approx(0.05)
    assert ("oracle@0.1", "truth") not in short
    assert shortfalls([r for r in runs if not r.rule.startswith("oracle@")]) == {}


def test_the_oracle_curve_runs_on_the_truth_at_each_level():
    """--oracle-curve adds the oracle at each configured level, on the truth alone, each run
    the drawing model closed at that true share; a level out of (0, 1] is refused by name."""
    from tail_beam_sim.errors import InputError

    face, caving = small_face()
    caving = dict(caving, oracle_curve_levels=[0.2, 0.4])
    runs = run_study(
        face, caving, [3], rules=["first_gangue"], sources=("stand-in",), oracle_curve=True
    )
    curve = {r.rule: r for r in runs if r.rule.startswith("oracle@")}
    assert sorted(curve) == ["oracle@0.2", "oracle@0.4"]
    assert {r.source for r in curve.values()} == {"truth"}
    for level in (0.2, 0.4):
        direct = run_face(
            face.with_changes(seed=3), close_at_true_share(level, face.share_window_kg)
        )
        assert curve[f"oracle@{level:g}"].recovery == direct.recovery
    assert curve["oracle@0.4"].gangue_content >= curve["oracle@0.2"].gangue_content
    with pytest.raises(InputError, match="oracle_curve_levels"):
        oracle_curve_rules(dict(caving, oracle_curve_levels=[0.3, 1.5]))


def test_the_caving_verb_prints_the_shortfall_with_the_oracle_curve(capsys):
    """`tail-beam caving --oracle-curve`: a column of each rule's recovery short of the
    oracle's curve, the curve's rows, and the oracle's own point on it (short by 0)."""
    args = parse(
        ["--supports", "3", "--seeds", "2", "--rules", "sprt,oracle", "--oracle-curve"]
        + ["--chart", ""]
    )
    assert caving_cmd.run(args) == 0
    out = capsys.readouterr().out
    assert "short of oracle curve, pts" in out and "oracle@0.05" in out
    oracle_row = next(line for line in out.splitlines() if line.startswith("oracle   "))
    # oracle@0.3 is the oracle's own run: the curve passes through it (or above, where a lower
    # level recovered more with less gangue), so it is never short of it
    short = float(re.findall(r"(-?\d+\.\d) \[", oracle_row)[-1])
    assert 0.0 <= short < 0.5


def test_a_later_label_closes_first_gangue_no_earlier():
    """One support, the same stand-in labels known 0 or 2 s after their impacts: first gangue
    closes on the same label, 2 s later, so the window draws at least as much coal and
    gangue; the oracle reads the truth and runs once, at no latency."""
    face, caving = small_face()
    face = face.with_changes(supports=1, group_size=1)
    rows = latency_study(face, caving, [1, 2], [0.0, 2.0], ["first_gangue", "oracle"])
    by = {(r.latency_s, r.summary.rule): r.summary for r in rows}
    assert sorted(by) == [(0.0, "first_gangue"), (0.0, "oracle"), (2.0, "first_gangue")]
    early, late = by[(0.0, "first_gangue")], by[(2.0, "first_gangue")]
    assert late.recovery >= early.recovery and late.gangue_content >= early.gangue_content
    assert late.drawing_s > early.drawing_s


def test_the_caving_verb_charts_recovery_against_latency(tmp_path, capsys):
    """`tail-beam caving --latencies`: a row per latency and rule, the chart written; a latency
    that is no number, or beyond caving.labels.latency_s's range, refused by name."""
    from tail_beam_sim.errors import InputError

    pytest.importorskip("matplotlib")
    chart = tmp_path / "latency.png"
    argv = ["--supports", "2", "--seeds", "1", "--rules", "sprt", "--latencies", "0,1.5"]
    assert caving_cmd.run(parse(argv + ["--latency-chart", str(chart)])) == 0
    out = capsys.readouterr().out
    assert re.search(r"^\s+0  sprt ", out, re.M) and re.search(r"^\s+1\.5  sprt ", out, re.M)
    assert chart.stat().st_size > 0
    with pytest.raises(InputError, match="--latencies = 'soon'"):
        caving_cmd.run(parse(["--latencies", "0,soon", "--latency-chart", ""]))
    with pytest.raises(InputError, match="latency_s"):
        caving_cmd.run(parse(["--latencies", "100", "--latency-chart", ""]))
    with pytest.raises(InputError, match="--latencies = '1': runs on the stand-in labels"):
        caving_cmd.run(parse(["--latencies", "1", "--sources", "truth", "--latency-chart", ""]))


def test_the_latency_study_counts_its_runs():
    """Two seeds, the SPRT at two latencies and the oracle once: 6 runs, counted 1 to 6."""
    face, caving = small_face()
    told = []
    latency_study(
        face,
        caving,
        [0, 1],
        [0.0, 1.0],
        ["sprt", "oracle"],
        progress=lambda done, total: told.append((done, total)),
    )
    assert told == [(k, 6) for k in range(1, 7)]
