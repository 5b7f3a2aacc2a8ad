"""The gangue-share score model's training (tail_beam_id.study.share_training): densities from
labelled flows and the systematic error measured across flows held out of the fit."""

from __future__ import annotations

import numpy as np

from tail_beam_id.stream.label import Label
from tail_beam_id.stream.share import ScoreModel
from tail_beam_id.study.share_training import (
    fit_densities,
    interval_errors,
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
