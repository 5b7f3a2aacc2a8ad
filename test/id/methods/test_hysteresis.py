"""The support's contact hysteresis read from a recording (tail_beam_id.methods.hysteresis): the
latent's definition, the bins' weights from a recording's impacts (mix-invariant, unsure when the
impacts cannot tell), and the profile's weights checked by name."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tail_beam_id.methods import load_model
from tail_beam_id.methods.hysteresis import (
    applied_shift,
    hysteresis_latent,
    hysteresis_shift,
    latent_bin,
    support_weights,
)
from tail_beam_id.methods.statistical import StatisticalMethod
from tail_beam_sim.errors import InputError


def test_the_latent_is_zero_for_the_calibrated_law_and_follows_the_scale():
    """The calibrated law as published is the reference (u = 0); a support's scale on chi adds
    its log; Hunt-Crossley's chi = 3 (1 - e) / 2 (1 - 0.35 -> 0.975) over the calibrated one's."""
    from tail_beam_sim.physics.contact import calibrated_chi

    assert hysteresis_latent("calibrated", 1.0, 0.35) == pytest.approx(0.0, abs=1e-12)
    assert hysteresis_latent("calibrated", 2.0, 0.35) == pytest.approx(math.log(2.0), rel=1e-12)
    assert hysteresis_latent("hunt_crossley", 1.0, 0.35) == pytest.approx(
        math.log(0.975 / float(calibrated_chi(0.35))), rel=1e-9
    )
    # Hunt-Crossley under-damps a low restitution (its formula holds near e = 1): u < 0.
    assert hysteresis_latent("hunt_crossley", 1.0, 0.35) < -0.6
    assert [latent_bin(u, [-1.0, 0.0, 1.0]) for u in (-2.0, -1.0, -0.5, 0.0, 0.5, 2.0)] == [
        0,
        1,
        1,
        2,
        2,
        3,
    ]


def _gaussian_joint(
    x: np.ndarray, means: dict[tuple[int, int], float], sigma: float = 0.5
) -> tuple[np.ndarray, np.ndarray]:
    """Joint posteriors (N, 4) of a two-bin model with 1-D Gaussian classes of equal training
    shares (gangue b0, gangue b1, coal b0, coal b1) and that prior."""
    order = [(0, 0), (0, 1), (1, 0), (1, 1)]  # (is coal, bin)
    density = np.stack([np.exp(-0.5 * ((x - means[key]) / sigma) ** 2) for key in order], axis=1)
    joint = density / density.sum(axis=1, keepdims=True)
    return joint, np.full(4, 0.25)


MEANS = {
    (0, 0): -2.0,
    (1, 0): 0.0,
    (0, 1): 0.0,
    (1, 1): 2.0,
}  # bin 1's classes sit 2 higher: bin 0's coal is bin 1's gangue


def test_a_face_dropping_mostly_coal_is_not_read_as_another_hysteresis():
    """Bin 0's classes at -1 (gangue) and +1 (coal), bin 1's at +0.5 and +1.5: a support of bin 0
    whose face drops 90 % coal looks, at even shares, like bin 1's mix. With each bin's coal
    share fitted bin 0 is named (median weight over 20 recordings of 40 impacts >= 0.95); with
    the shares held at the training's even mix it was not (median 0.01)."""
    means = {(0, 0): -1.0, (1, 0): 1.0, (0, 1): 0.5, (1, 1): 1.5}
    named = []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        coal = rng.uniform(size=40) < 0.9
        x = np.where(coal, means[(1, 0)], means[(0, 0)]) + rng.normal(0.0, 0.6, 40)
        joint, prior = _gaussian_joint(x, means, sigma=0.6)
        named.append(support_weights(joint, prior)[0])
    assert float(np.median(named)) >= 0.95, np.round(named, 2)


def test_a_mixed_recording_names_its_bin_whatever_its_coal_share():
    """Impacts of bin 0 name bin 0 whether the face dropped 20 % or 80 % coal."""
    rng = np.random.default_rng(1)
    for coal_share in (0.2, 0.8):
        coal = rng.uniform(size=40) < coal_share
        x = np.where(coal, MEANS[(1, 0)], MEANS[(0, 0)]) + rng.normal(0.0, 0.5, 40)
        joint, prior = _gaussian_joint(x, MEANS)
        weights = support_weights(joint, prior)
        assert weights[0] > 0.99, (coal_share, weights)


def test_a_recording_that_cannot_tell_the_bins_apart_stays_unsure():
    """Bin 0's coal and bin 1's gangue look alike: a recording of them alone (all coal of one
    support, or all rock of the other) fits both bins, and the weights stay near even instead of
    naming one (a confident wrong bin would move every label)."""
    rng = np.random.default_rng(2)
    x = MEANS[(1, 0)] + rng.normal(0.0, 0.5, 30)
    joint, prior = _gaussian_joint(x, MEANS)
    weights = support_weights(joint, prior)
    assert 0.3 < weights[0] < 0.7, weights


@pytest.fixture(scope="module")
def model():
    return load_model("statistical")


def test_the_shift_is_nothing_when_the_support_says_what_the_impact_says(model):
    """Weighing the bins as the impact alone does adds nothing to its logit; weighing them
    otherwise moves it (both ways across the bins)."""
    hysteresis = model["hysteresis"]
    rng = np.random.default_rng(3)
    z = rng.normal(0.0, 1.0, len(hysteresis["features"]))
    from tail_beam_id.methods.hysteresis import joint_probabilities

    joint = joint_probabilities(hysteresis, z[None, :])[0]
    k = joint.size // 2
    alone = (joint[:k] + joint[k:]) / (joint[:k] + joint[k:]).sum()
    assert hysteresis_shift(hysteresis, z, alone) == pytest.approx(0.0, abs=1e-9)
    shifts = [hysteresis_shift(hysteresis, z, np.eye(k)[b]) for b in range(k)]
    assert max(shifts) - min(shifts) > 0.1


@pytest.mark.parametrize(
    "weights",
    [
        [0.5, 0.5],
        [1.2, -0.2, 0.0, 0.0, 0.0, 0.0],
        [0.2] * 5 + [0.3],
        ["a"] * 6,
        [math.nan] + [0.2] * 5,
    ],
)
def test_a_profiles_weights_are_checked_by_name(params, model, weights):
    """A profile whose hysteresis weights are not one non-negative weight per bin of the models,
    summing to 1, is refused naming calibration.hysteresis_weights (a profile made with other
    models would weigh the wrong bins)."""
    with pytest.raises(InputError, match=r"calibration\.hysteresis_weights"):
        StatisticalMethod.from_model(
            model, {**params, "calibration": {"hysteresis_weights": weights}}
        )


def test_a_profiles_weights_reach_the_method(params, model):
    """Weights that fit are taken as the profile gives them."""
    k = len(model["hysteresis"]["bin_edges"]) + 1
    weights = [0.0] * k
    weights[1] = 1.0
    method = StatisticalMethod.from_model(
        model, {**params, "calibration": {"hysteresis_weights": weights}}
    )
    assert method.hysteresis_weights == weights
    assert StatisticalMethod.from_model(model, params).hysteresis_weights is None


def test_training_records_carry_their_supports_law_and_scale(params):
    """What the hysteresis network learns from: a nominal stream impact's support is config/'s
    (the calibrated law, scale 1: latent 0), a drawn one's is its own law and scale, and a
    mismatch impact's its law at config/'s scale."""
    from tail_beam_id.study.dataset import draw_commands, settings, simulate_set
    from tail_beam_id.study.runs import run_set

    shipped = settings(params, [1.0], ["shipped"])
    (nominal,) = list(run_set(params, "stream", 1, 5, shipped, ["statistical"]))
    assert (nominal.contact_model, nominal.contact_damping_scale) == ("calibrated", 1.0)
    assert hysteresis_latent(nominal.contact_model, nominal.contact_damping_scale, 0.35) == 0.0
    drawn = list(run_set(params, "varied", 1, 5, shipped, ["statistical"]))
    (impact,) = list(simulate_set(params, "varied", 1, 5, shipped))
    assert drawn and all(
        (r.contact_model, r.contact_damping_scale)
        == (impact.support.contact_model, impact.support.values["contact_damping_scale"])
        for r in drawn
    )
    ((_, _, law),) = list(draw_commands(params, "mismatch", 1, 5))
    (mismatch,) = list(run_set(params, "mismatch", 1, 5, shipped, ["statistical"]))
    assert (mismatch.contact_model, mismatch.contact_damping_scale) == (law, 1.0)


@pytest.mark.parametrize(
    "change, field",
    [
        ({"bin_edges": [0.0, -0.5]}, "bin_edges"),
        ({"bin_edges": []}, "bin_edges"),
        ({"bin_edges": [0.0, "x"]}, "bin_edges"),
        ({"reference_restitution": 1.0}, "reference_restitution"),
        ({"reference_restitution": 0.0}, "reference_restitution"),
    ],
)
def test_training_refuses_a_bad_hysteresis_section_by_name(params, change, field):
    """Unsorted or empty bins would put supports in the wrong bin silently, and a reference
    restitution of 1 (no hysteresis) or 0 has no latent: refused naming the field."""
    from tail_beam_id.study.training import hysteresis_section

    section = {**params["identification"]["statistical"]["hysteresis"], **change}
    with pytest.raises(InputError, match=rf"identification\.statistical\.hysteresis\.{field}"):
        hysteresis_section(section)


def test_a_profile_made_with_other_bins_is_refused_by_name(params, model):
    """Weights of as many bins as the models' but of other edges (a profile calibrated with
    other models) would weigh the wrong hysteresis: refused naming
    calibration.hysteresis_bin_edges; the models' own edges are taken."""
    edges = model["hysteresis"]["bin_edges"]
    weights = [1.0] + [0.0] * len(edges)
    other = [e + 0.25 for e in edges]
    with pytest.raises(InputError, match=r"calibration\.hysteresis_bin_edges"):
        StatisticalMethod.from_model(
            model,
            {
                **params,
                "calibration": {"hysteresis_weights": weights, "hysteresis_bin_edges": other},
            },
        )
    method = StatisticalMethod.from_model(
        model,
        {**params, "calibration": {"hysteresis_weights": weights, "hysteresis_bin_edges": edges}},
    )
    assert method.hysteresis_weights == weights


@pytest.mark.parametrize(
    ("logit", "shift", "applied"),
    [
        (2.0, -1.5, -1.5),  # less sure: taken whole
        (2.0, -3.0, -3.0),  # turned over (to -1.0): taken whole
        (2.0, 1.0, 0.0),  # surer coal: refused, the impact's own 2.0 stands
        (-2.0, -1.0, 0.0),  # surer gangue: refused
        (-2.0, 5.0, 5.0),  # turned to coal at 3.0: taken whole, even though surer than 2.0
        (0.5, 0.0, 0.0),
    ],
)
def test_the_hysteresis_moves_the_boundary_but_never_makes_a_label_surer(logit, shift, applied):
    """The shift a label takes (applied_shift): all of it when it makes the label less sure or
    turns it over, none when it would make the label surer in the direction it already had."""
    assert applied_shift(logit, shift) == applied
