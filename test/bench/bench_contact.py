"""What the contact's duration read from the acceleration pulse buys
(tail_beam_id.signals.contact_fit, feature ``contact_duration_s``): networks like the
statistical method's three-signal one, retrained without it, with it, and with the true contact
duration (from impact_truth) or the force read-out's (``contact_force_duration_s``,
tail_beam_id.signals.contact_force) in its place, scored on the paper and stream scenes of the
nominal support, on foreign supports and on supports drawn by structure (the ``structures``
set's; the true support known), all at the shipped sensors (25.6 kHz accelerometer, 5 kHz
camera). Prints a table, asserts nothing, ships nothing.

    python test/bench/bench_contact.py                  # about 3 minutes here
    python test/bench/bench_contact.py --varied 800 --supports 5   # quicker, wider intervals

Training: ``--varied`` impacts on drawn training supports (true profile) and ``--stream``
impacts of the nominal support (training's seeds 9 and 7); tests: the paper scene (seed 41001),
the stream scene (41002), ``--supports`` foreign supports x 20 impacts (41004) of the stream
scene and, the same supports, of the paper scene (``foreign_paper``), and ``--supports``
structures supports x 20 impacts of the stream scene (41006). Each row's
network is fitted from two seeded starts and both are scored (a / b).
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

ROWS = (
    "without contact_duration_s",
    "contact_duration_s read from the pulse",
    "contact_force_duration_s (the force read-out) instead",
    "true contact duration instead",
)
FORCE_ROW, TRUE_ROW = 2, 3


def main() -> int:
    import tail_beam_id.study.runs as runs
    from tail_beam_id.methods.statistical import base_vector, feature_list, network_logit
    from tail_beam_id.study.dataset import evaluation_params, settings
    from tail_beam_id.study.evaluation import wilson
    from tail_beam_id.study.training import fit_network
    from tail_beam_sim.cli.common import add_config_option
    from tail_beam_sim.config import load_parameters

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--varied", type=int, default=1500, help="training impacts on drawn supports"
    )
    parser.add_argument(
        "--stream", type=int, default=600, help="training impacts of the nominal support"
    )
    parser.add_argument(
        "--supports", type=int, default=10, help="foreign supports (20 impacts each)"
    )
    add_config_option(parser)
    args = parser.parse_args()
    params = load_parameters(args.config)
    seeds = evaluation_params(params)["seeds"]
    shipped = settings(params, [1.0], ["shipped"])
    started = time.perf_counter()
    train = list(
        runs.run_set(params, "varied", args.varied, 9, shipped, ["statistical"], true_profile=True)
    )
    train += list(runs.run_set(params, "stream", args.stream, 7, shipped, ["statistical"]))
    tests = {
        "paper, nominal support": list(
            runs.run_set(params, "paper", 200, int(seeds["paper"]), shipped, ["statistical"])
        ),
        "stream, nominal support": list(
            runs.run_set(params, "stream", 300, int(seeds["stream"]), shipped, ["statistical"])
        ),
        "stream, foreign supports, true profile": [],
        "paper, foreign supports, true profile": [],
        "stream, structures supports, true profile": [],
    }
    for scene, column, which in (
        ("stream", "stream, foreign supports, true profile", "foreign"),
        ("paper", "paper, foreign supports, true profile", "foreign"),
        ("stream", "stream, structures supports, true profile", "structures"),
    ):
        streams = runs.support_streams(
            params,
            args.supports,
            20,
            int(seeds[which]),
            which=which,
            setting=shipped[0],
            scene=scene,
        )
        for number, recorded in enumerate(streams):
            tests[column] += list(
                runs.foreign_records(
                    params, recorded, number, 20, ["statistical"], ["true"], "shipped"
                )
            )
    print(
        f"{len(train)} training impacts (simulated and identified in "
        f"{time.perf_counter() - started:.0f} s)",
        file=sys.stderr,
    )
    every = feature_list(("jack_pressure", "imu", "rebound_velocity"))
    without = [(n, f) for n, f in every if n != "contact_duration_s"]
    column = [n for n, _ in every].index("contact_duration_s")

    def inputs(records, row):
        """(inputs, is coal, impacts without a three-signal label, which count as wrong)."""
        kept = [
            r
            for r in records
            if r.label is not None and all(n in r.label.features for n, _ in every)
        ]
        rows = []
        for r in kept:
            x = list(base_vector(r.label.features, without if row == 0 else every))
            if row == TRUE_ROW:
                x[column] = math.log(r.duration_s)
            elif row == FORCE_ROW:
                # Where the force was not read (a channel too slow for a ring-down), the
                # half-sine's reading (the sample period) stays.
                force = r.label.features.get("contact_force_duration_s")
                if force is not None:
                    x[column] = math.log(max(force, 1e-5))
            rows.append(x)
        return np.array(rows), np.array([r.is_coal for r in kept]), len(records) - len(kept)

    print("| inputs | " + " | ".join(tests) + " |")
    print("| --- |" + " --- |" * len(tests))
    for row, label in enumerate(ROWS):
        x, y, _ = inputs(train, row)
        low, high = np.percentile(x, [0.1, 99.9], axis=0)
        mean, scale = np.clip(x, low, high).mean(axis=0), np.clip(x, low, high).std(axis=0) + 1e-9
        networks = [
            fit_network((np.clip(x, low, high) - mean) / scale, y.astype(float), seed=seed)
            for seed in (3, 4)
        ]
        cells = []
        for records in tests.values():
            xt, yt, lost = inputs(records, row)
            right = [
                int(np.sum((network_logit(n, (np.clip(xt, low, high) - mean) / scale) > 0) == yt))
                for n in networks
            ]
            n = len(yt) + lost
            lo, hi = wilson(min(right), n)
            cells.append(
                f"{100 * right[0] / n:.1f} / {100 * right[1] / n:.1f} % "
                f"({100 * lo:.0f}-{100 * hi:.0f}, n {n})"
            )
        print(f"| {label} | " + " | ".join(cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
