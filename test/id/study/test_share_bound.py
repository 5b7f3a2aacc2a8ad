"""The share bound bench's own arithmetic (test/bench/bench_share_bound.py): the near-Bayes
labels and the share error it reports, on data whose answer is known."""

from __future__ import annotations

import math

import numpy as np
from bench_share_bound import contact_features, knn_labels, share_mae


def test_nearest_neighbours_label_two_separated_clusters_by_their_class():
    """Coal and gangue lumps far apart in (log) feature space: every test lump takes its
    cluster's class, so the bound cannot call a separable scene ambiguous."""
    rng = np.random.default_rng(3)
    coal = rng.normal(0.0, 0.1, size=(200, 3))
    gangue = rng.normal(2.0, 0.1, size=(200, 3))
    train = np.vstack([coal, gangue])
    classes = np.r_[np.zeros(200), np.ones(200)]
    said = knn_labels(train, classes, np.vstack([coal[:20] + 0.01, gangue[:20] - 0.01]))
    assert said.tolist() == [False] * 20 + [True] * 20


def test_share_error_is_zero_for_true_labels_and_counts_each_interval_with_a_lump():
    """Labels equal to the truth give 0 points; labels all 'coal' give, per interval, the true
    share itself (here 0, 1/2 and 1 over three intervals: a mean of 50 points); an interval
    without a lump is not scored."""
    stamps = np.array([0.1, 1.2, 1.4, 2.5])
    gangue = np.array([False, True, False, True])
    intervals = [(0.0, 1.0), (1.0, 2.0), (2.0, 3.0), (3.0, 4.0)]
    assert share_mae(stamps, gangue, gangue.astype(float), intervals) == 0.0
    assert math.isclose(share_mae(stamps, gangue, np.zeros(4), intervals), 50.0)


def test_contact_features_are_the_logs_of_moment_impulse_rebound_duration_and_position():
    """The moment impulse is m (v_in + v_out) x: 0.1 kg at 8 + 2 m/s, 1.2 m from the hinge
    gives 1.2 N m s; the point's column is added only when asked."""
    truth = {
        "mass_kg": 0.1,
        "impact_speed_mps": 8.0,
        "rebound_speed_mps": 2.0,
        "contact_duration_s": 2e-4,
        "position_m": 1.2,
    }
    plain = contact_features([truth], with_position=False)
    pointed = contact_features([truth], with_position=True)
    assert np.allclose(np.exp(plain[0]), [1.2, 2.0, 2e-4])
    assert np.allclose(np.exp(pointed[0]), [1.2, 2.0, 2e-4, 1.2])
