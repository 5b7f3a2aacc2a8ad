"""What a commissioning run buys: a few labelled impacts on a support the models never saw,
used to refine its self-calibrated labels. Prints figures, asserts nothing.

Each foreign support (`tail-beam evaluate`'s foreign set, shipped sensors, self-calibrated as
`tail-beam identify` does by default) is recorded as one stream of 20 impacts. Its first k
impacts stand for the commissioning run (their truth known); a logit offset b, and optionally
a scale a, is fitted to them by maximum a posteriori (Gaussian priors around no change:
b ~ N(0, prior_b^2), log a ~ N(0, 0.5^2)), and applied to the support's other impacts, which
are scored against the same impacts left as they were, both from the labels' logits (before
any confidence cap). Missed impacts count as wrong in both.

    python test/bench/bench_commissioning.py --supports 30      # about 1.5 minutes here

The refinement is a measurement, not shipped (docs/results/commissioning.md has its figures).
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np
from scipy.optimize import minimize

IMPACTS_PER_SUPPORT = 20
LOG_SCALE_PRIOR = 0.5  # prior standard deviation of log a


def fit_refinement(
    logits: np.ndarray, is_coal: np.ndarray, prior_b: float, with_scale: bool
) -> tuple[float, float]:
    """(a, b) maximising the labelled impacts' likelihood of sigmoid(a * logit + b) times the
    priors."""

    def loss(theta: np.ndarray) -> float:
        log_a = theta[1] if with_scale else 0.0
        z = math.exp(log_a) * logits + theta[0]
        log_p = -np.logaddexp(0.0, -z)  # log sigmoid(z)
        log_q = -np.logaddexp(0.0, z)  # log (1 - sigmoid(z))
        prior = 0.5 * (theta[0] / prior_b) ** 2 + (
            0.5 * (log_a / LOG_SCALE_PRIOR) ** 2 if with_scale else 0.0
        )
        return float(-np.sum(np.where(is_coal, log_p, log_q)) + prior)

    theta = minimize(loss, np.zeros(2 if with_scale else 1)).x
    return (math.exp(theta[1]) if with_scale else 1.0), float(theta[0])


def main() -> int:
    from tail_beam_id.study.dataset import evaluation_params, settings
    from tail_beam_id.study.runs import run_foreign
    from tail_beam_sim.config import load_parameters

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--supports", type=int, default=30)
    parser.add_argument(
        "--seed", type=int, default=None, help="foreign seed (default: the evaluation's)"
    )
    parser.add_argument(
        "--labelled",
        type=int,
        nargs="+",
        default=[4, 6, 10],
        help="commissioning impacts per support",
    )
    args = parser.parse_args()
    params = load_parameters()
    seed = (
        args.seed if args.seed is not None else int(evaluation_params(params)["seeds"]["foreign"])
    )
    records = list(
        run_foreign(
            params,
            args.supports,
            IMPACTS_PER_SUPPORT,
            seed,
            ["statistical"],
            None,
            ["self-calibrated"],
            settings(params, [1.0], ["shipped"]),
        )
    )
    by_support: dict[int, list] = {}
    for record in records:
        by_support.setdefault(record.index // IMPACTS_PER_SUPPORT, []).append(record)
    print(
        f"{args.supports} foreign supports x {IMPACTS_PER_SUPPORT} impacts, seed {seed}, shipped "
        "sensors, self-calibrated; "
        f"all impacts: {100 * np.mean([r.correct for r in records]):.1f} % right"
    )
    print(
        "| labelled per support | refinement | scored impacts | as identified | refined | wrong "
        "at >= 0.9: as identified / refined |"
    )
    print("| --- | --- | --- | --- | --- | --- |")
    for k in args.labelled:
        for prior_b, with_scale in ((1.0, False), (2.0, False), (1.0, True)):
            n = right = refined_right = confident = refined_confident = 0
            for rows in by_support.values():
                rows = sorted(rows, key=lambda r: r.index)
                known = [r for r in rows[:k] if r.label is not None]
                a, b = (
                    fit_refinement(
                        np.array([r.label.features["logit"] for r in known]),
                        np.array([r.is_coal for r in known]),
                        prior_b,
                        with_scale,
                    )
                    if known
                    else (1.0, 0.0)
                )
                for r in rows[k:]:
                    n += 1
                    if r.label is None:
                        continue
                    for logit, counts in (
                        (r.label.features["logit"], 0),
                        (a * r.label.features["logit"] + b, 1),
                    ):
                        p_coal = 1.0 / (1.0 + math.exp(-logit))
                        ok = (p_coal >= 0.5) == r.is_coal
                        sure = max(p_coal, 1.0 - p_coal) >= 0.9
                        if counts == 0:
                            right += ok
                            confident += (not ok) and sure
                        else:
                            refined_right += ok
                            refined_confident += (not ok) and sure
            what = f"offset (prior sd {prior_b:g})" + (" and scale" if with_scale else "")
            print(
                f"| {k} | {what} | {n} | {100 * right / n:.1f} % | {100 * refined_right / n:.1f} "
                f"% | {confident} / {refined_confident} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
