"""model_array: a trained model's list as an array, converted once per list."""

from __future__ import annotations

import numpy as np
import pytest

from tail_beam_id.methods.base import model_array


def test_a_list_is_converted_once_and_read_only():
    """A trained list reads as np.array of it, the same read-only array on every call."""
    model = {"w1": [[1.0, 2.0], [3.0, 4.0]]}
    first = model_array(model, "w1")
    np.testing.assert_array_equal(first, np.array(model["w1"]))
    assert model_array(model, "w1") is first
    with pytest.raises(ValueError):
        first[0, 0] = 5.0


def test_a_new_list_under_the_same_name_is_read_anew():
    """A list replaced under the same name is converted again, not served from the cache."""
    model = {"mean": [1.0, 2.0]}
    model_array(model, "mean")
    model["mean"] = [5.0, 6.0]
    np.testing.assert_array_equal(model_array(model, "mean"), [5.0, 6.0])


def test_an_array_is_converted_on_every_call():
    """An array (a fit still changing its weights) is copied afresh on every call."""
    weights = np.array([1.0, 2.0])
    model = {"w2": weights}
    seen = model_array(model, "w2")
    weights[0] = 7.0  # a fit still changing its weights
    assert model_array(model, "w2")[0] == 7.0
    assert seen[0] == 1.0
