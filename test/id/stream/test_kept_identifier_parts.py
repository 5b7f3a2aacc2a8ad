"""What an identifier builds from its parameter sections is kept per content: equal sections
give the kept object, a changed value a new one, data that is not plain is never keyed."""

from __future__ import annotations

import copy

import numpy as np

from tail_beam_id.signals.features import BeamModel
from tail_beam_id.stream.config import IdentifierConfig
from tail_beam_sim.config import fingerprint


def test_equal_sections_share_the_kept_config_and_a_changed_one_does_not(params):
    """An equal identification section (a copy) gives the kept config; a changed window a new
    one that reads the change."""
    section = dict(params["identification"])
    first = IdentifierConfig.from_params(section)
    assert IdentifierConfig.from_params(copy.deepcopy(section)) is first
    changed = {**section, "window_s": float(section["window_s"]) * 2.0}
    other = IdentifierConfig.from_params(changed)
    assert other is not first and other.window_s == first.window_s * 2.0


def test_the_beam_model_follows_the_support_it_is_built_from(params):
    """Equal support and materials give the kept beam model; a heavier beam a new one, the kept
    one unchanged."""
    first = BeamModel.from_params(params)
    assert BeamModel.from_params(copy.deepcopy(params)) is first
    heavier = copy.deepcopy(params)
    inertia = float(params["support"]["beam_inertia_about_hinge_kgm2"])
    heavier["support"]["beam_inertia_about_hinge_kgm2"] = 2.0 * inertia
    other = BeamModel.from_params(heavier)
    assert other.support.beam_inertia_about_hinge_kgm2 == 2.0 * inertia
    assert first.support.beam_inertia_about_hinge_kgm2 == inertia


def test_only_plain_data_is_fingerprinted():
    """Key order and numpy scalars do not change a fingerprint; an array gives none."""
    assert fingerprint({"a": np.float64(1.5), "b": [1, 2]}) == fingerprint({"b": [1, 2], "a": 1.5})
    assert fingerprint({"a": np.arange(3)}) is None
