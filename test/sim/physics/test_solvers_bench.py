"""`tail-beam bench` end to end on a small selection (the figures themselves are the bench's
output, never asserted on time)."""

from __future__ import annotations

import json

from tail_beam_sim.cli import main
from tail_beam_sim.physics.benchmark import Row, mark_pareto


def test_bench_prints_figures_marks_the_front_and_writes_charts(tmp_path, capsys):
    """`tail-beam bench --json` reports every solver against Radau, both ends of the Pareto
    front on it, the hybrid within 1 %, simulate() as a whole against Radau (its rebound within
    1 %, every stage timed) and simulate_many's throughput, and writes PNG charts."""
    code = main(
        [
            "bench",
            "--solvers",
            "hybrid",
            "impulse",
            "DOP853",
            "--repeats",
            "1",
            "--min-time-s",
            "0",
            "--batch-impacts",
            "2000",
            "--simulate-impacts",
            "3",
            "--no-tiers",
            "--out",
            str(tmp_path),
            "--json",
        ]
    )
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    names = {(row["name"], row["setting"]) for row in report["solvers"]}
    assert ("Radau", "rtol=1e-08") in names and ("hybrid", "default") in names
    radau = next(
        r for r in report["solvers"] if (r["name"], r["setting"]) == ("Radau", "rtol=1e-08")
    )
    assert radau["ratio_to_radau_1e-8"] == 1.0
    most_accurate = min(
        report["solvers"], key=lambda r: max(r["err_rebound"], r["err_peak_pressure"])
    )
    fastest = min(report["solvers"], key=lambda r: r["median_s"])
    assert most_accurate["pareto"] and fastest["pareto"]  # both ends of a Pareto front are on it
    hybrid = next(
        r for r in report["solvers"] if (r["name"], r["setting"]) == ("hybrid", "default")
    )
    assert hybrid["err_rebound"] < 0.01 and hybrid["err_peak_pressure"] < 0.01
    assert report["reference_error_bound"] < 1e-6
    assert (
        report["batch"]["rigid_summaries_per_s"] > 0
        and report["real_time"]["modal_real_time_factor"] > 0
    )
    whole = report["simulate"]
    assert whole["rebound_error"] < 0.01
    assert whole["speedup"] > 0 and whole["speedup_no_vibration"] > 0
    assert all(
        whole[f"{stage}_median_s"] > 0
        for stage in ("plan", "solve", "sensors", "sensors_no_vibration", "simulate", "radau")
    )
    many = whole["many"]
    assert many["impacts"] == 3 and many["impacts_per_s"] > 0 and many["impacts_per_cpu_s"] > 0
    for chart in report["charts"]:
        assert open(chart, "rb").read(8) == b"\x89PNG\r\n\x1a\n"


def test_pareto_front_keeps_only_rows_that_no_faster_row_beats():
    """The Pareto front keeps a row only if no faster row is more accurate, ordered by time."""
    rows = [
        Row("a", "", [1.0], {"x": 1e-2}),
        Row("b", "", [2.0], {"x": 1e-1}),
        Row("c", "", [3.0], {"x": 1e-4}),
        Row("d", "", [0.5], {"x": 1.0}),
    ]
    front = mark_pareto(rows, lambda r: r.errors["x"])
    assert [r.name for r in front] == ["d", "a", "c"]


def test_bench_bad_options_exit_2(capsys):
    """`tail-beam bench --repeats 0` exits 2 naming --repeats."""
    assert main(["bench", "--repeats", "0", "--no-plot"]) == 2
    assert "--repeats" in capsys.readouterr().err
