"""Training's impacts simulated over several processes (tail_beam_id.study.training.collect_all):
the same records, in the same order, as in one."""

from __future__ import annotations

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
