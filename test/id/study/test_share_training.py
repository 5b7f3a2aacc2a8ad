"""The gangue-share score model's training (tail_beam_id.study.share_training): densities from
labelled flows and the systematic error measured across flows held out of the fit."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tail_beam_id.stream.label import Label
from tail_beam_id.stream.share import ScoreModel
from tail_beam_id.study.share_training import (
    fit_densities,
    held_out_se,
    interval_errors,
    main,
    regime_rows,
    scored_labels,
    systematic_se,
)


def synthetic_flow(flow: int, seed: int, coal_wrong: float, rate_per_s: float = 100.0) -> dict:
    """An identified flow of 6 s at ``rate_per_s``, share 0.4 by count: every lump labelled at
    its stamp, overlapping, its score on the right side except a fifth of the gangue and
    ``coal_wrong`` of the coal."""
    rng = np.random.default_rng(seed)
    stamps = np.sort(rng.uniform(0.0, 6.0, size=int(6 * rate_per_s)))
    gangue = rng.uniform(size=stamps.size) < 0.4
    wrong = rng.uniform(size=stamps.size) < np.where(gangue, 0.2, coal_wrong)
    labels = []
    for t, g, w in zip(stamps, gangue, wrong):
        gangue_like = bool(g != w)
        labels.append(
            Label(
                float(t),
                "gangue" if gangue_like else "coal",
                0.6,
                "statistical",
                signals=("vibration",),
                overlap=True,
                features={"logit": -3.0 if gangue_like else 3.0},
            ).to_json()
        )
    return {
        "flow": flow,
        "rate_per_s": rate_per_s,
        "layout": "shipped",
        "tolerance_s": 1e-4,
        "labels": labels,
        "lump_stamps_s": [float(t) for t in stamps],
        "gangue": [bool(g) for g in gangue],
    }


def test_densities_learnt_from_flows_read_a_like_flow_without_bias():
    """Densities fitted on four flows read a fifth like them within its stated error, and
    flows alike show no systematic error."""
    flows = [synthetic_flow(n, 100 + n, 0.2) for n in range(4)]
    rows = [r for f in flows for r in scored_labels(f)]
    assert len(rows) == sum(len(f["labels"]) for f in flows)
    model = ScoreModel.from_dict(fit_densities(regime_rows(rows)))
    errors = interval_errors(synthetic_flow(9, 200, 0.2), model)
    assert len(errors) >= 8
    mean_error = float(np.mean([e for _, e, _ in errors]))
    stated = float(np.mean([se for _, _, se in errors]))
    assert abs(mean_error) < stated  # within one standard error of the truth on average
    systematic = systematic_se(flows, [0, 1, 0, 1])
    assert max(systematic) < 0.05


def test_flows_unlike_each_other_show_a_systematic_error():
    """Half the flows score coal on the gangue side 40 % of the time (a support unlike the
    other half's): read by densities fitted on the other half, their shares are off by far
    more than the statistical error, which the systematic error states (at 100 labels/s:
    the class 80-150)."""
    flows = [synthetic_flow(n, 300 + n, 0.2 if n % 2 else 0.4) for n in range(4)]
    systematic = systematic_se(flows, [0, 1, 0, 1])
    assert systematic[3] > 0.1 and systematic[0] == 0.0


def test_held_out_flows_unlike_the_training_ones_show_their_systematic_error():
    """Densities fitted on flows of one kind state no systematic error on held-out flows like
    them, and a large one (at 100 labels/s: the class 80-150) on flows whose coal scores on the
    gangue side twice as often: the error of the densities themselves, not of a fold."""
    training = [synthetic_flow(n, 400 + n, 0.2) for n in range(4)]
    model = ScoreModel.from_dict(fit_densities(regime_rows(
        [r for f in training for r in scored_labels(f)]
    )))
    alike = held_out_se(model, [synthetic_flow(10 + n, 500 + n, 0.2) for n in range(2)])
    unlike = held_out_se(model, [synthetic_flow(20 + n, 600 + n, 0.4) for n in range(2)])
    assert alike[3] < 0.05  # the class of the flows' 100 labels a second
    assert unlike[3] > 0.1 and unlike[0] == 0.0


def test_training_refuses_a_cache_holding_fewer_flows_than_asked(tmp_path):
    """A refit from a cache of 3 flows asked for 2 training and 2 held-out flows stops with one
    line naming both options, before anything is written."""
    cache = tmp_path / "flows.json"
    cache.write_text(json.dumps([synthetic_flow(n, 700 + n, 0.2) for n in range(3)]))
    out = tmp_path / "model.json"
    argv = ["--flows", "2", "--held-out-flows", "2", "--cache", str(cache), "--out", str(out)]
    with pytest.raises(SystemExit, match="--flows \\+ --held-out-flows = 4"):
        main(argv)
    assert not out.exists()
    with pytest.raises(SystemExit, match="--held-out-flows must be >= 0"):
        main(["--held-out-flows", "-1", "--cache", str(cache), "--out", str(out)])
    cache.write_text('{"not": "flows"}')
    with pytest.raises(SystemExit, match="is no list of identified flows"):
        main(["--cache", str(cache), "--out", str(out)])
    assert not out.exists()


@pytest.mark.parametrize("duration", ["-1", "0", "nan", "1e9"])
def test_a_flow_length_out_of_range_is_refused_by_name(duration, tmp_path):
    """A training flow's length that is not a positive number of at most 600 s stops with one
    line naming --duration-s, before any flow is simulated or anything written."""
    out = tmp_path / "model.json"
    with pytest.raises(SystemExit, match="--duration-s must be in"):
        main(["--duration-s", duration, "--out", str(out)])
    assert not out.exists()


def test_an_output_that_cannot_be_written_is_one_line(tmp_path):
    """--out into a directory that does not exist ends with one line naming --out, not a
    traceback, after the fit (from a cache)."""
    cache = tmp_path / "flows.json"
    cache.write_text(json.dumps([synthetic_flow(n, 900 + n, 0.2) for n in range(2)]))
    out = tmp_path / "missing" / "model.json"
    with pytest.raises(SystemExit, match="--out .*cannot be written"):
        main(["--flows", "1", "--held-out-flows", "1", "--cache", str(cache), "--out", str(out)])


def test_a_refit_from_a_cache_fits_the_first_flows_and_measures_on_the_rest(tmp_path):
    """From a cache of 4 flows, 2 train the densities and 2 unlike them give the systematic
    error; the model file says how many of each."""
    flows = [synthetic_flow(n, 800 + n, 0.2 if n < 2 else 0.4) for n in range(4)]
    cache = tmp_path / "flows.json"
    cache.write_text(json.dumps(flows))
    out = tmp_path / "model.json"
    main(["--flows", "2", "--held-out-flows", "2", "--cache", str(cache), "--out", str(out)])
    model = json.loads(out.read_text())
    assert model["training"]["flows"] == 2 and model["training"]["held_out_flows"] == 2
    assert model["systematic_se"][3] > 0.1
    fitted = fit_densities(regime_rows([r for f in flows[:2] for r in scored_labels(f)]))
    assert model["densities"] == fitted["densities"]
