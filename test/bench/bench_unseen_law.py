"""What a contact law no training impact had costs (the independent evaluation's
supports follow a hysteresis law of their own): networks like the statistical method's
three-signal one, fitted on drawn training supports with every law and again with one law left
out, scored on the foreign supports of that law (the stream and the paper scene, shipped
sensors, the true support known). Prints a table, asserts nothing, ships nothing.

    python test/bench/bench_unseen_law.py                 # about 4 minutes here
    python test/bench/bench_unseen_law.py --no-scale      # training's hysteresis as published

Training: ``--varied`` stream-scene and a fifth as many paper-scene impacts on drawn training
supports (sensors drawn with each, identified knowing their support; training's seeds 9 and 10)
and ``--stream`` impacts of the nominal support at the shipped sensors (seed 7). With
``--no-scale`` the drawn supports keep each law's hysteresis as published
(``identification.evaluation.supports.training.contact_damping_scale`` left out). Test:
``--supports`` foreign supports x 20 impacts of each scene (seed 41004).
Each network is fitted from two seeded starts and both are scored.
"""

from __future__ import annotations

import argparse
import copy
import sys
import time

import numpy as np


def main() -> int:
    import tail_beam_id.study.runs as runs
    from tail_beam_id.methods.statistical import base_vector, feature_list, network_logit
    from tail_beam_id.study.dataset import (
        FOREIGN_SCENES,
        evaluation_params,
        settings,
        simulate_set,
    )
    from tail_beam_id.study.evaluation import wilson
    from tail_beam_id.study.training import fit_network
    from tail_beam_sim.config import load_parameters

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--varied", type=int, default=1500, help="stream-scene training impacts on drawn supports"
    )
    parser.add_argument(
        "--stream", type=int, default=300, help="training impacts of the nominal support"
    )
    parser.add_argument(
        "--supports", type=int, default=30, help="foreign supports (20 impacts of each scene)"
    )
    parser.add_argument(
        "--no-scale", action="store_true", help="train on the laws' hysteresis as published"
    )
    args = parser.parse_args()
    params = load_parameters()
    if args.no_scale:
        params = copy.deepcopy(params)
        params["identification"]["evaluation"]["supports"]["training"].pop(
            "contact_damping_scale", None
        )
    seeds = evaluation_params(params)["seeds"]
    shipped = settings(params, [1.0], ["shipped"])
    law_of: dict[tuple[str, int], str] = {}  # (scene set, index) -> the contact law of its support

    def remembering(*args_, **kwargs):
        """simulate_set, keeping each drawn impact's contact law."""
        for impact in simulate_set(*args_, **kwargs):
            law_of[(args_[1], impact.index)] = impact.contact_model
            yield impact

    runs.simulate_set = remembering  # run_set looks it up in its module
    started = time.perf_counter()
    train = list(
        runs.run_set(params, "varied", args.varied, 9, shipped, ["statistical"], true_profile=True)
    )
    train += list(
        runs.run_set(
            params,
            "varied_paper",
            max(args.varied // 5, 1),
            10,
            shipped,
            ["statistical"],
            true_profile=True,
        )
    )
    train += list(runs.run_set(params, "stream", args.stream, 7, shipped, ["statistical"]))
    tests: dict[str, list] = {}
    foreign_laws: dict[
        int, str
    ] = {}  # foreign support number -> its contact law (the same supports in both scenes)
    for scene_set, scene in FOREIGN_SCENES.items():
        tests[scene_set] = []
        for number, recorded in enumerate(
            runs.support_streams(
                params, args.supports, 20, int(seeds["foreign"]), setting=shipped[0], scene=scene
            )
        ):
            foreign_laws[number] = recorded.support.contact_model
            tests[scene_set] += runs.foreign_records(
                params, recorded, number, 20, ["statistical"], ["true"], "shipped", scene_set
            )
    print(
        f"{len(train)} training impacts, {sum(map(len, tests.values()))} foreign test impacts "
        f"(simulated in {time.perf_counter() - started:.0f} "
        f"s){' (hysteresis as published)' if args.no_scale else ''}",
        file=sys.stderr,
    )
    names = feature_list(("jack_pressure", "imu", "rebound_velocity"))

    def inputs(records):
        """(inputs, is coal, impacts without a three-signal label, which count as wrong)."""
        kept = [
            r
            for r in records
            if r.label is not None and all(n in r.label.features for n, _ in names)
        ]
        return (
            np.array([base_vector(r.label.features, names) for r in kept]),
            np.array([r.is_coal for r in kept]),
            len(records) - len(kept),
        )

    def fitted(records):
        x, y, _ = inputs(records)
        low, high = np.percentile(x, [0.1, 99.9], axis=0)
        mean, scale = np.clip(x, low, high).mean(axis=0), np.clip(x, low, high).std(axis=0) + 1e-9
        return [
            (
                fit_network((np.clip(x, low, high) - mean) / scale, y.astype(float), seed=seed),
                low,
                high,
                mean,
                scale,
            )
            for seed in (3, 4)
        ]

    def scored(models, records) -> str:
        x, y, lost = inputs(records)
        n = len(y) + lost
        if not n:
            return "-"
        right = [
            int(np.sum((network_logit(net, (np.clip(x, low, high) - mean) / scale) > 0) == y))
            for net, low, high, mean, scale in models
        ]
        lo, hi = wilson(min(right), n)
        return (
            f"{100 * right[0] / n:.1f} / {100 * right[1] / n:.1f} % "
            f"({100 * lo:.0f}-{100 * hi:.0f}, n {n})"
        )

    every = fitted(train)
    print(
        "| law (foreign supports) | stream, trained with it | stream, left out | paper, trained "
        "with it | paper, left out |"
    )
    print("| --- | --- | --- | --- | --- |")
    for law in sorted(set(foreign_laws.values())):
        if law == "calibrated":
            continue  # the nominal support's own law: its stream is in every training set
        without = fitted([r for r in train if law_of.get((r.scene_set, r.index)) != law])
        cells = []
        for scene_set in FOREIGN_SCENES:
            mine = [r for r in tests[scene_set] if foreign_laws[r.support] == law]
            cells += [scored(every, mine), scored(without, mine)]
        print(
            f"| {law} ({list(foreign_laws.values()).count(law)}) | " + " | ".join(cells) + " |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
