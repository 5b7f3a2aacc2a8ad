"""What the foreign supports' gap is made of: networks like the statistical method's
three-signal one, retrained with and without an oracle input that no sensor of the contract
gives (where the particle struck the beam, where the IMU is bolted), scored on the nominal
support's stream scene and on the foreign supports (shipped sensors, the true support known:
the ceiling of any self-calibration). Prints a table, asserts nothing, ships nothing.

    python test/bench/bench_oracle.py                 # about 3 minutes here
    python test/bench/bench_oracle.py --varied 1000 --supports 10  # quicker, wider intervals

Training: ``--varied`` impacts on drawn training supports (sensors drawn with each, half of
them with the accelerometer), identified knowing their support, and ``--stream`` impacts of
the nominal support at the shipped sensors (training's seeds 9 and 7); test: the stream scene
(seed 41002) and ``--supports`` foreign supports x 20 impacts (seed 41004). Every row uses the
same impacts; each network is fitted from two seeded starts and both are scored.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

ORACLES = {
    "none": (),
    "impact position": ("position_m",),
    "IMU position": ("imu_from_hinge_m",),
    "both": ("position_m", "imu_from_hinge_m"),
}


def main() -> int:
    import tail_beam_id.study.runs as runs
    from tail_beam_id.methods.statistical import base_vector, feature_list, network_logit
    from tail_beam_id.study.dataset import evaluation_params, settings, simulate_set
    from tail_beam_id.study.evaluation import wilson
    from tail_beam_id.study.training import fit_network
    from tail_beam_sim.config import load_parameters

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--varied", type=int, default=2500, help="training impacts on drawn supports"
    )
    parser.add_argument(
        "--stream", type=int, default=600, help="training impacts of the nominal support"
    )
    parser.add_argument(
        "--supports", type=int, default=20, help="foreign supports (20 impacts each)"
    )
    args = parser.parse_args()
    params = load_parameters()
    seeds = evaluation_params(params)["seeds"]
    shipped = settings(params, [1.0], ["shipped"])
    oracle: dict[tuple[str, int], dict[str, float]] = {}  # (scene set, index) -> the oracle inputs

    def remembering(*args_, **kwargs):
        """simulate_set, keeping each impact's position and its support's IMU position."""
        for impact in simulate_set(*args_, **kwargs):
            support = impact.support.values if impact.support is not None else params["support"]
            oracle[(args_[1], impact.index)] = {
                "position_m": float(impact.command["position_m"]),
                "imu_from_hinge_m": float(support["imu_from_hinge_m"]),
            }
            yield impact

    runs.simulate_set = remembering  # run_set looks it up in its module
    started = time.perf_counter()
    train = list(
        runs.run_set(params, "varied", args.varied, 9, shipped, ["statistical"], true_profile=True)
    )
    train += list(runs.run_set(params, "stream", args.stream, 7, shipped, ["statistical"]))
    stream = list(
        runs.run_set(params, "stream", 300, int(seeds["stream"]), shipped, ["statistical"])
    )
    foreign = []
    for number, recorded in enumerate(
        runs.support_streams(params, args.supports, 20, int(seeds["foreign"]), setting=shipped[0])
    ):
        for record, truth in zip(
            runs.foreign_records(
                params, recorded, number, 20, ["statistical"], ["true"], "shipped"
            ),
            recorded.truths,
        ):
            oracle[("foreign", record.index)] = {
                "position_m": float(truth["position_m"]),
                "imu_from_hinge_m": float(recorded.support.values["imu_from_hinge_m"]),
            }
            foreign.append(record)
    print(
        f"{len(train)} training impacts, {len(stream)} stream and {len(foreign)} foreign test "
        "impacts "
        f"(simulated in {time.perf_counter() - started:.0f} s)",
        file=sys.stderr,
    )
    names = feature_list(("jack_pressure", "imu", "rebound_velocity"))

    def inputs(records, extra):
        """(inputs, is coal, impacts without a three-signal label, which count as wrong)."""
        kept = [
            r
            for r in records
            if r.label is not None and all(n in r.label.features for n, _ in names)
        ]
        x = np.array(
            [
                [
                    *base_vector(r.label.features, names),
                    *(math.log(oracle[(r.scene_set, r.index)][e]) for e in extra),
                ]
                for r in kept
            ]
        )
        return x, np.array([r.is_coal for r in kept]), len(records) - len(kept)

    print("| oracle input | stream scene, nominal support | foreign supports, true profile |")
    print("| --- | --- | --- |")
    for label, extra in ORACLES.items():
        x, y, _ = inputs(train, extra)
        low, high = np.percentile(x, [0.1, 99.9], axis=0)
        mean, scale = np.clip(x, low, high).mean(axis=0), np.clip(x, low, high).std(axis=0) + 1e-9
        networks = [
            fit_network((np.clip(x, low, high) - mean) / scale, y.astype(float), seed=seed)
            for seed in (3, 4)
        ]
        cells = []
        for records in (stream, foreign):
            xt, yt, lost = inputs(records, extra)
            right = [
                int(
                    np.sum(
                        (network_logit(network, (np.clip(xt, low, high) - mean) / scale) > 0) == yt
                    )
                )
                for network in networks
            ]
            n = len(yt) + lost
            lo, hi = wilson(min(right), n)
            cells.append(
                f"{100 * right[0] / n:.1f} / {100 * right[1] / n:.1f} % "
                f"({100 * lo:.0f}-{100 * hi:.0f}, n {n})"
            )
        print(f"| {label} | {cells[0]} | {cells[1]} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
