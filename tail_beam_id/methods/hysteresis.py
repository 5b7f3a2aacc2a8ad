"""The support's contact hysteresis, read from its own recording.

How much a contact dissipates belongs to the support (its wear plate, the law its contact
follows) as much as to the particle: the same mudstone rebounds at 2.5 m/s off one support and
at 5 m/s off another whose hysteresis returns low restitutions inflated, where a third
support's coal rebounds. One impact cannot tell which; a recording of many can, because all its
impacts share the support.

The support's hysteresis is summed up by one number, its latent ``u``: the log of the
hysteresis factor chi the support gives a reference gangue restitution (``reference_restitution``,
0.35), over the one the calibrated law gives it (0 for config/'s support; Hunt-Crossley's about
-1, Lankarani-Nikravesh's about -1.3, Flores' +0.1), in bins (``bin_edges``). A network trained on
drawn supports gives, for each impact, the joint probability of its class (gangue, coal) and
its support's bin. Over a recording's impacts the bins' likelihoods are summed, each with the
coal share that fits it best (so a face that drops mostly coal or mostly rock does not pass
for another hysteresis: Saerens et al. 2002's prior adjustment), and their posterior weights go
into the support profile (``calibration.hysteresis_weights``). The statistical method then
moves an impact's logit by what the support's weights say against what the impact alone
suggests (:func:`hysteresis_shift`), as far as that moves the boundary and never to make a
label surer (:func:`applied_shift`): its own network stays the judge of the impact, and the
joint network says only how knowing the support changes that (deciding by the joint network
alone labels foreign supports' paper scene and stream less well).

Pure numpy: no ROS. The network is fitted by tail_beam_id.study.training.fit_hysteresis.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from tail_beam_id.methods.base import model_array
from tail_beam_id.methods.inputs import base_vector
from tail_beam_sim.physics.contact import calibrated_chi, damping_factor

EM_ITERATIONS = 100  # iterations of the coal share's fit in each bin
SHARE_LIMITS = (0.02, 0.98)  # the coal share a bin's fit may take


def hysteresis_latent(
    law: str, contact_damping_scale: float, reference_restitution: float
) -> float:
    """The support's latent u: log(chi of ``law`` times its scale / chi of the calibrated law),
    both at ``reference_restitution``."""
    return math.log(
        float(damping_factor(law, reference_restitution, contact_damping_scale))
        / float(calibrated_chi(reference_restitution))
    )


def latent_bin(latent: float, bin_edges: Sequence[float]) -> int:
    """The bin (0 .. len(bin_edges)) a latent falls in."""
    return int(np.searchsorted(np.asarray(bin_edges, dtype=float), latent, side="right"))


def joint_inputs(model: Mapping[str, Any], features: Mapping[str, float]) -> np.ndarray | None:
    """The network's standardised inputs for one impact's features, or None when one is
    missing or any lies outside the training envelope (the impact then gives no evidence)."""
    names = [(name, floor) for name, floor in model["features"]]
    if any(name not in features for name, _ in names):
        return None
    row = base_vector(features, names)
    low, high = model_array(model, "envelope")
    if not np.all((row >= low) & (row <= high)):
        return None
    return (row - model_array(model, "mean")) / model_array(model, "scale")


def joint_probabilities(model: Mapping[str, Any], z: np.ndarray) -> np.ndarray:
    """P(class, bin | impact) for standardised inputs ``z`` (N, d): (N, 2K), gangue bins then
    coal bins."""
    hidden = np.tanh(z @ model_array(model, "w1").T + model_array(model, "b1"))
    scores = hidden @ model_array(model, "w2").T + model_array(model, "b2")
    scores -= scores.max(axis=1, keepdims=True)
    p = np.exp(scores)
    return p / p.sum(axis=1, keepdims=True)


def support_weights(joint: np.ndarray, prior: np.ndarray) -> np.ndarray:
    """The posterior weight of each bin (K) given a recording's impacts' joint probabilities
    (N, 2K) and the training's share of each (class, bin) (2K): each bin's likelihood is the
    product over impacts of sum_c share_c p(impact | c, bin), its coal share fitted by EM."""
    k = joint.shape[1] // 2
    likelihood = joint / prior  # proportional to p(impact | class, bin)
    log_l = np.empty(k)
    for b in range(k):
        gangue, coal = likelihood[:, b], likelihood[:, k + b]
        share = 0.5
        for _ in range(EM_ITERATIONS):
            mixed = coal * share + gangue * (1.0 - share)
            share = float(np.clip(np.mean(coal * share / mixed), *SHARE_LIMITS))
        log_l[b] = float(np.sum(np.log(coal * share + gangue * (1.0 - share))))
    w = np.exp(log_l - log_l.max())
    return w / w.sum()


def bin_logits(joint_row: np.ndarray) -> np.ndarray:
    """log P(coal | impact, bin) - log P(gangue | impact, bin) for each bin (K)."""
    k = joint_row.size // 2
    return np.log(np.maximum(joint_row[k:], 1e-300)) - np.log(np.maximum(joint_row[:k], 1e-300))


def hysteresis_shift(model: Mapping[str, Any], z: np.ndarray, weights: Sequence[float]) -> float:
    """What knowing the support's bins (``weights``) moves one impact's coal logit by
    (standardised inputs ``z``, d): the logit of each bin's tempered coal probability weighted
    by the support's bins, less the one weighted by the bins the impact alone suggests."""
    joint = joint_probabilities(model, z[None, :])[0]
    k = joint.size // 2
    p = 1.0 / (
        1.0 + np.exp(-np.clip(bin_logits(joint) / float(model["temperature"]), -700.0, 700.0))
    )
    alone = joint[:k] + joint[k:]
    known = float(np.dot(np.asarray(weights, dtype=float), p))
    unknown = float(np.dot(alone / alone.sum(), p))
    return _logit(known) - _logit(unknown)


def applied_shift(logit: float, shift: float) -> float:
    """The part of ``shift`` an impact's ``logit`` takes: all of it when it makes the label less
    sure or turns it over, none when it would make the label surer than the impact alone says.

    Knowing the support's hysteresis says where the boundary between coal and gangue lies on
    it; how sure a label is stays the impact's own network's word. The joint network's per-bin
    decisions transfer to unseen supports less well than the plain network's: taken whole, the
    shift makes labels surer where they are wrong too, more confidently wrong than with no
    shift at all; bounded like this, the labels stay the same and fewer wrong ones are confident
    (measured: docs/results/archive.md, "The shift taken whole")."""
    moved = logit + shift
    if (moved > 0.0) == (logit > 0.0) and abs(moved) > abs(logit):
        return 0.0
    return shift


def _logit(p: float) -> float:
    p = min(max(p, 1e-12), 1.0 - 1e-12)
    return math.log(p / (1.0 - p))


def recording_weights(
    model: Mapping[str, Any], features: Sequence[Mapping[str, float]], min_impacts: int
) -> tuple[list[float] | None, int]:
    """(the bins' weights, the impacts they rest on) for a recording's impacts' features; the
    weights are None with fewer than ``min_impacts`` usable impacts (all the model's features
    there, inside its envelope)."""
    rows = [z for z in (joint_inputs(model, f) for f in features) if z is not None]
    if len(rows) < min_impacts:
        return None, len(rows)
    weights = support_weights(joint_probabilities(model, np.array(rows)), np.array(model["prior"]))
    return [float(w) for w in weights], len(rows)


def describe(weights: Sequence[float] | None, impacts: int, bin_edges: Sequence[float]) -> str:
    """The support's hysteresis in a few words ('hysteresis u in [-1, -0.5) (0.97), 18
    impacts')."""
    if weights is None:
        return f"hysteresis not read ({impacts} impacts with every signal, too few)"
    best = int(np.argmax(weights))
    edges = [-math.inf, *bin_edges, math.inf]
    return (
        f"hysteresis u in [{edges[best]:g}, {edges[best + 1]:g}) ({weights[best]:.2f}), "
        f"{impacts} impacts"
    )
