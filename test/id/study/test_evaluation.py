"""Evaluation figures (intervals, balanced accuracy, confusion), training fits, and the
`tail-beam evaluate` command line."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from tail_beam_id.cli.evaluate_cmd import BEST_TARGETS_HEADING
from tail_beam_id.stream.label import Label
from tail_beam_id.study.evaluation import summarise, wilson
from tail_beam_id.study.runs import Record
from tail_beam_id.study.training import fit_logistic, fit_size_temperature, fit_temperature
from tail_beam_sim.cli import main


def record(is_coal: bool, said: str | None, radius_m: float = 0.03) -> Record:
    label = (
        None
        if said is None
        else Label(1.0, said, 0.9, "physics", latency_ms=1.0, data_latency_ms=12.0)
    )
    return Record(
        "stream",
        "nominal/x1",
        "physics",
        0.012,
        0,
        "coal" if is_coal else "marble",
        is_coal,
        radius_m,
        0.999,
        3e-4,
        label,
        0,
        0.01,
    )


def test_wilson_interval_matches_the_textbook_values():
    # Wilson 95 % interval: 10/10 -> [0.7225, 1]; 0/10 -> [0, 0.2775]; 5/10 -> [0.2366, 0.7634].
    """The Wilson 95 % interval matches the textbook bounds for 10/10, 0/10 and 5/10."""
    assert wilson(10, 10)[0] == pytest.approx(0.7225, abs=1e-4)
    assert wilson(0, 10)[1] == pytest.approx(0.2775, abs=1e-4)
    assert wilson(5, 10) == pytest.approx((0.2366, 0.7634), abs=1e-4)


def test_missed_impacts_count_as_wrong_and_classes_weigh_equally():
    """A missed impact counts as wrong, balanced accuracy weighs coal and gangue equally, and
    the confusion, size bins and data latency add up by hand."""
    records = [
        record(True, "coal"),
        record(True, "coal"),
        record(True, "coal"),
        record(True, None),
        record(False, "gangue", 0.08),
        record(False, "coal", 0.08),
    ]
    s = summarise(records, [0.025, 0.05, 0.1])
    assert s.accuracy == pytest.approx(4 / 6)
    assert s.balanced_accuracy == pytest.approx((3 / 4 + 1 / 2) / 2)
    assert s.confusion == {
        "coal": {"coal": 3, "gangue": 0, "missed": 1},
        "gangue": {"coal": 1, "gangue": 1, "missed": 0},
    }
    assert s.detected == 5
    assert [b["n"] for b in s.by_size] == [4, 2]
    assert s.by_size[1]["accuracy"] == pytest.approx(0.5)
    # Data latency: from the true contact (0.999 s) to the newest stamp used (1.012 s).
    assert s.data_latency_ms["median"] == pytest.approx(13.0)
    # From the contact's end (0.999 s + 0.3 ms) to the same stamp: 12.7 ms.
    assert s.extra["data_latency_after_contact_end_ms"]["median"] == pytest.approx(12.7)


def test_confident_wrong_labels_are_set_against_what_their_confidences_promise():
    """Of labels at >= 0.9, a calibrated identifier gets sum(1 - confidence) wrong on average:
    two labels at 0.9 and one at 0.95 promise 0.25 wrong; a label under 0.9 and a missed impact
    promise nothing; the count of those actually wrong at >= 0.9 is beside it."""

    def said(is_coal, material, confidence):
        r = record(is_coal, material)
        return replace(r, label=replace(r.label, confidence=confidence))

    records = [
        said(True, "coal", 0.9),
        said(False, "coal", 0.9),
        said(True, "coal", 0.95),
        said(False, "coal", 0.8),
        record(True, None),
    ]
    s = summarise(records, [0.025, 0.1])
    assert s.extra["confident_wrong"] == 1
    assert s.extra["confident_wrong_if_calibrated"] == pytest.approx(0.25)


def test_logistic_fit_finds_the_boundary_and_temperature_undoes_overconfidence():
    """The logistic fit recovers a known slope and offset, and temperature scaling finds a
    fivefold overconfidence."""
    rng = np.random.default_rng(0)
    x = rng.normal(0.0, 1.0, (2000, 1))
    p = 1.0 / (1.0 + np.exp(-(2.0 * x[:, 0] - 1.0)))
    y = (rng.uniform(size=p.size) < p).astype(float)
    w = fit_logistic(x, y, l2=0.0)
    assert w[0] == pytest.approx(2.0, rel=0.15)
    assert w[1] == pytest.approx(-1.0, abs=0.2)
    # Logits five times too large: the calibrating temperature is about five.
    assert fit_temperature(5.0 * (2.0 * x[:, 0] - 1.0), y) == pytest.approx(5.0, rel=0.2)


def test_size_temperature_finds_overconfidence_that_grows_as_impacts_get_smaller():
    """Logits whose overconfidence is 2 at the reference size and doubles with each unit the log
    size falls below it (true temperature 2 exp(ln 2 (reference - log size))): the fit recovers
    T = 2 and slope ln 2, so the small impacts' confidence comes down and the large ones' up; with
    no size dependence the slope is about 0 and T the plain temperature."""
    rng = np.random.default_rng(1)
    log_size = rng.uniform(-2.0, 2.0, 8000)
    honest = rng.normal(0.0, 2.0, log_size.size)  # the true logit
    y = (rng.uniform(size=log_size.size) < 1.0 / (1.0 + np.exp(-honest))).astype(float)
    true_t = 2.0 * np.exp(np.log(2.0) * (0.0 - log_size))
    temperature, slope = fit_size_temperature(honest * true_t, y, log_size, reference=0.0)
    assert temperature == pytest.approx(2.0, rel=0.15)
    assert slope == pytest.approx(np.log(2.0), rel=0.15)
    flat_t, flat_slope = fit_size_temperature(3.0 * honest, y, log_size, reference=0.0)
    assert abs(flat_slope) < 0.05 and flat_t == pytest.approx(
        fit_temperature(3.0 * honest, y), rel=0.05
    )


def test_evaluate_command_prints_figures_and_targets(capsys, tmp_path):
    """`tail-beam evaluate` prints the set, the targets and a finite compute time, and writes
    summary.json."""
    code = main(
        [
            "evaluate",
            "--sets",
            "paper",
            "--count",
            "2",
            "--noise",
            "1",
            "--rates",
            "nominal",
            "--methods",
            "threshold,physics",
            "--out",
            str(tmp_path),
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    assert "paper" in out and BEST_TARGETS_HEADING in out and "(issue" not in out
    assert (tmp_path / "summary.json").is_file()
    assert not math.isnan(
        float(out.split("compute per impact, worst group median ")[1].split(" ms")[0])
    )


@pytest.mark.parametrize(
    ("argv", "field"),
    [
        (["evaluate", "--sets", "quarry"], "--sets"),
        (["evaluate", "--methods", "svm"], "--methods"),
        (["evaluate", "--noise", "-1"], "--noise"),
    ],
)
def test_evaluate_rejects_bad_options_in_one_line(capsys, argv, field):
    """Each bad evaluate option exits 2 with one line naming the option."""
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and field in err


def test_evaluate_plot_defaults_to_out_evaluate(tmp_path, monkeypatch, capsys):
    """--plot without --out writes summary.json and the charts under out/evaluate of the
    working directory (ignored by git)."""
    pytest.importorskip("matplotlib")
    monkeypatch.chdir(tmp_path)
    assert (
        main(
            [
                "evaluate",
                "--sets",
                "paper,stream",
                "--count",
                "2",
                "--noise",
                "1,10",
                "--rates",
                "nominal",
                "--methods",
                "threshold",
                "--plot",
            ]
        )
        == 0
    )
    written = sorted(p.name for p in (tmp_path / "out" / "evaluate").iterdir())
    assert written == [
        "accuracy_vs_latency.png",
        "accuracy_vs_noise.png",
        "accuracy_vs_size.png",
        "reliability.png",
        "summary.json",
    ]


def test_charts_are_written(tmp_path):
    """The three evaluation charts are written as real PNG files, under their documented names."""
    pytest.importorskip("matplotlib")
    from tail_beam_id.study.charts import write_all

    items = []
    for noise in ("1", "10"):
        records = [
            record(True, "coal", 0.03),
            record(False, "gangue", 0.08),
            record(False, "coal", 0.04),
        ]
        for r in records:
            r.setting = f"nominal/x{noise}"
        items.append(summarise(records, [0.025, 0.05, 0.1]))
    paths = write_all(items, tmp_path, 0.012)
    assert [p.name for p in paths] == [
        "reliability.png",
        "accuracy_vs_latency.png",
        "accuracy_vs_size.png",
        "accuracy_vs_noise.png",
    ]
    assert all(p.stat().st_size > 1000 and p.read_bytes()[:4] == b"\x89PNG" for p in paths)


def test_evaluate_compares_foreign_supports_with_the_nominal_one_at_the_same_setting(capsys):
    """`--sets stream,foreign --rates nominal`: the foreign supports are scored at the nominal
    setting and with drawn sensors, and the target line sets the former against the nominal
    support's stream scene at that very setting."""
    code = main(
        [
            "evaluate",
            "--sets",
            "stream,foreign",
            "--count",
            "2",
            "--noise",
            "1",
            "--rates",
            "nominal",
            "--methods",
            "threshold",
            "--profiles",
            "nominal",
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    assert "foreign   nominal/x1/nominal" in out and "foreign   drawn/nominal" in out
    targets = out.split(BEST_TARGETS_HEADING)[1].splitlines()
    line = next(x for x in targets if x.strip().startswith("foreign nominal/x1/nominal threshold"))
    assert "vs stream nominal/x1" in line and "within 5:" in line
    assert "vs stream" not in next(
        x for x in targets if x.strip().startswith("foreign drawn/nominal threshold")
    )


def test_evaluate_scores_the_paper_scene_on_every_foreign_support(capsys):
    """`--sets foreign_paper`: the paper scene on the foreign supports, with a target line that
    names the worst support and counts the supports below 99.5 % (the target is every support)."""
    code = main(
        [
            "evaluate",
            "--sets",
            "foreign_paper",
            "--count",
            "2",
            "--noise",
            "1",
            "--rates",
            "nominal",
            "--methods",
            "threshold",
            "--profiles",
            "nominal",
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    assert "foreign_paper nominal/x1/nominal" in out and "foreign_paper drawn/nominal" in out
    line = next(
        x
        for x in out.splitlines()
        if x.strip().startswith("paper scene on foreign supports nominal/x1/nominal threshold")
    )
    assert (
        "worst support #0" in line
        and "of 1 supports below 99.5%" in line
        and "on every support:" in line
    )
