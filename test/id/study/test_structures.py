"""Supports drawn by structure (tail_beam_id.study.supports.draw_structure, the ``structures``
scene set): bending modes derived from a beam of their own, within the configured ranges."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tail_beam_id.study.dataset import evaluation_params
from tail_beam_id.study.supports import draw_support, support_ranges
from tail_beam_sim.physics.fidelity import FidelitySettings, get_tier, structure_for
from tail_beam_sim.physics.scene import Scene


def test_drawn_structures_keep_to_their_ranges_and_build(params):
    """Thirty structures of the structures set's ranges: the first mode (held at the jack pin)
    at the drawn frequency, inside 80-4000 Hz, its modal mass inside 100-1000 kg, the second
    mode 2-8 x the first, 1-4 modes all below 5 kHz but the first, the IMU within 0.5-1.55 m;
    each builds a coupled structure (positive mass matrix) with the nominal jack lever arm, and
    their second/first ratios and modal masses spread across the ranges (not one table
    rescaled)."""
    ranges = support_ranges(evaluation_params(params), "structures")
    rng = np.random.default_rng(3)
    nominal = Scene.from_params(params).support
    ratios, masses = [], []
    for _ in range(30):
        draw = draw_support(ranges, rng, np.random.default_rng(4), params["modes"])
        v = draw.values
        frequencies = draw.mode_frequencies_hz
        assert 1 <= len(frequencies) <= 4
        assert frequencies[0] == pytest.approx(v["bending_1_frequency_hz"])
        assert 80.0 <= frequencies[0] <= 4000.0
        assert all(f < 5000.0 for f in frequencies[1:])
        assert 0.5 <= v["imu_from_hinge_m"] <= 1.55
        varied = draw.apply(params)
        modes = varied["modes"]
        first = modes["bending_1"]
        assert 100.0 <= first["modal_mass_kg"] <= 1000.0
        masses.append(first["modal_mass_kg"])
        if len(frequencies) > 1:
            ratio = frequencies[1] / frequencies[0]
            assert 2.0 - 1e-9 <= ratio <= 8.0 + 1e-9
            ratios.append(ratio)
        scene = Scene.from_params(varied)
        assert scene.support.jack_lever_arm_m == pytest.approx(nominal.jack_lever_arm_m)
        structure = structure_for(
            get_tier("modal"), scene.support, FidelitySettings.from_params(varied).modes
        )
        assert np.linalg.eigvalsh(structure.mass).min() > 0.0
    assert min(ratios) < 4.0 and max(ratios) > 6.0
    assert min(masses) < 250.0 and max(masses) > 600.0


def test_a_structure_draw_is_repeatable_and_leaves_the_foreign_draws_alone(params):
    """The same seed draws the same structure; the foreign set's ranges (no structure) draw
    every support as before."""
    ev = evaluation_params(params)
    ranges = support_ranges(ev, "structures")
    a = draw_support(ranges, np.random.default_rng(8), None, params["modes"])
    b = draw_support(ranges, np.random.default_rng(8), None, params["modes"])
    assert a.values == b.values
    foreign = support_ranges(ev, "foreign")
    with_modes = draw_support(foreign, np.random.default_rng(8), None, params["modes"])
    without = draw_support(foreign, np.random.default_rng(8))
    assert with_modes.values == without.values
    assert not any(k.startswith("structure_") for k in without.values)
    assert math.isfinite(a.values["structure_held_at_m"])


def test_evaluate_scores_the_structures_sets(capsys):
    """`tail-beam evaluate --sets structures,structures_paper`: both sets are scored, each with
    its target line (the paper scene's on every support)."""
    import argparse

    from tail_beam_id.cli import evaluate_cmd

    parser = argparse.ArgumentParser()
    evaluate_cmd.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(
        [
            "evaluate",
            "--sets",
            "structures,structures_paper",
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
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert "structures       nominal/x1/nominal" in out
    assert "structures_paper nominal/x1/nominal" in out
    lines = [x.strip() for x in out.splitlines()]
    assert any(x.startswith("structures nominal/x1/nominal threshold") for x in lines)
    assert any(
        x.startswith("paper scene on structures supports nominal/x1/nominal threshold")
        for x in lines
    )


def test_training_draws_structures_for_its_share_of_supports(params):
    """The training ranges' structure_share: about that fraction of the drawn training supports
    have modes from a beam of their own (the rest the nominal modes rescaled), each within the
    training's narrower structure ranges (second mode 2.2-7 x the first); a share of 0 draws
    none, 1 every one; a share outside [0, 1] is refused by name."""
    import copy

    from tail_beam_sim.errors import InputError

    ev = evaluation_params(params)
    ranges = support_ranges(ev, "training")
    share = float(ranges["structure_share"])
    assert 0.0 < share < 1.0
    draws = [
        draw_support(ranges, np.random.default_rng(seed), None, params["modes"])
        for seed in range(60)
    ]
    structured = [d for d in draws if d.mode_frequencies_hz]
    # binomial(60, share): well inside 5 standard deviations
    assert abs(len(structured) - 60 * share) < 5 * math.sqrt(60 * share * (1 - share))
    for draw in structured:
        f = draw.mode_frequencies_hz
        if len(f) > 1:
            assert 2.2 - 1e-9 <= f[1] / f[0] <= 7.0 + 1e-9
    for value, expected in ((0.0, 0), (1.0, 20)):
        edited = copy.deepcopy(dict(ev))
        edited["supports"]["training"]["structure_share"] = value
        fixed = support_ranges(edited, "training")
        got = sum(
            bool(
                draw_support(fixed, np.random.default_rng(s), None, params["modes"]).values.get(
                    "structure_modes"
                )
            )
            for s in range(20)
        )
        assert got == expected
    edited = copy.deepcopy(dict(ev))
    edited["supports"]["training"]["structure_share"] = 1.5
    with pytest.raises(InputError, match="training.structure_share"):
        support_ranges(edited, "training")


@pytest.mark.parametrize(
    ("name", "value", "field"),
    [
        ("held_at_m", [0.65], "structure.held_at_m"),
        ("mode_ratio", [8.0, 2.0], "structure.mode_ratio"),
        ("tip_mass_kg", [-1.0, 10.0], "structure.tip_mass_kg"),
        ("max_mode_frequency_hz", 0.0, "structure.max_mode_frequency_hz"),
    ],
)
def test_a_bad_structure_range_is_refused_by_name(params, name, value, field):
    """A structure range that is no [low, high] (one value, low above high, a negative tip
    mass) or a top frequency that is no positive number: an InputError naming the field, not a
    traceback from the draw."""
    import copy

    from tail_beam_sim.errors import InputError

    ev = copy.deepcopy(dict(evaluation_params(params)))
    ev["supports"]["structures"]["structure"][name] = value
    with pytest.raises(InputError, match=field.replace(".", r"\.")):
        support_ranges(ev, "structures")
