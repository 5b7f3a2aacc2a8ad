"""Training's impacts simulated over several processes (tail_beam_id.study.training.collect_all):
the same records, in the same order, as in one."""

from __future__ import annotations

import json

import pytest

from tail_beam_id.study.dataset import evaluation_params
from tail_beam_id.study.training import collect_all, main


def test_two_workers_give_the_records_one_gives(params):
    """A stream job (every setting of one nominal impact) and a drawn-support job, collected in
    two processes and in one: equal lists of records (truth, label, features), job by job."""
    seed = int(evaluation_params(params)["training_seed"])
    jobs = [
        (params, "stream", 1, seed, None, False),
        (params, "varied", 2, seed + 2, None, True),
    ]
    alone = collect_all(jobs, 1)
    shared = collect_all(jobs, 2)
    assert [len(part) for part in shared] == [len(part) for part in alone]
    assert all(len(part) > 0 for part in alone)
    for mine, theirs in zip(alone, shared):
        for a, b in zip(mine, theirs):
            assert (a.setting, a.index, a.material, a.radius_m) == (
                b.setting,
                b.index,
                b.material,
                b.radius_m,
            )
            assert a.label is not None and b.label is not None
            assert a.label.material == b.label.material
            assert a.label.confidence == b.label.confidence
            assert a.label.features == b.label.features


@pytest.mark.parametrize("jobs", ["0", "65"])
def test_a_worker_count_out_of_range_is_refused_by_name(jobs, capsys):
    """--jobs outside 1-64 ends with a usage error naming it, before any simulation."""
    with pytest.raises(SystemExit) as ended:
        main(["--jobs", jobs])
    assert ended.value.code == 2
    assert "--jobs" in capsys.readouterr().err


@pytest.mark.parametrize(
    "option, value",
    [("--count", "0"), ("--varied-count", "-5"), ("--varied-paper-count", "-1")],
)
def test_an_impact_count_out_of_range_is_refused_by_name(option, value, capsys):
    """A count of training impacts below 1 ends with a usage error naming the option, before
    any simulation."""
    with pytest.raises(SystemExit) as ended:
        main([option, value])
    assert ended.value.code == 2
    assert option in capsys.readouterr().err


def test_a_plain_run_fits_the_impact_points_models_too(monkeypatch, tmp_path):
    """The README's one training command writes statistical.json afresh and then adds the
    models that read the impact point, from impacts simulated with the camera reporting it:
    without that second step the shipped file would lose them. The simulation and fits are
    stood in for here (their own tests cover them); what is checked is the sequence and that
    each cache keeps its own records."""
    from tail_beam_id.study import training

    simulated: list[bool] = []

    def collect(jobs, workers):
        simulated.append(all(j[0]["sensors"]["camera_reports_impact_point"] for j in jobs))
        return [[] for _ in jobs]

    monkeypatch.setattr(training, "MODELS_DIR", tmp_path)
    monkeypatch.setattr(training, "collect_all", collect)
    monkeypatch.setattr(training, "train_threshold", lambda paper: {"threshold": 1.0})
    monkeypatch.setattr(
        training,
        "train_statistical",
        lambda records, seed, hysteresis: {"subsets": {}, "calibrated_subsets": {}},
    )
    monkeypatch.setattr(training, "duration_ratio_table", lambda params: [])
    monkeypatch.setattr(training, "timing_table", lambda records, vibration=False: {})
    monkeypatch.setattr(
        training,
        "train_point_models",
        lambda records, seed: {"subsets": {"x+point": {}}, "calibrated_subsets": {}},
    )
    cache = tmp_path / "records.json"
    assert main(["--count", "1", "--varied-count", "1", "--jobs", "1", "--cache", str(cache)]) == 0
    assert simulated == [False, True]
    model = json.loads((tmp_path / "statistical.json").read_text(encoding="utf-8"))
    assert "x+point" in model["subsets"] and "point_provenance" in model
    assert cache.is_file() and training.point_cache(cache).is_file()
    assert training.point_cache(cache).name == "records.point.json"
