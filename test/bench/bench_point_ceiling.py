"""What limits the labels when the camera reports where the particle struck: supports drawn as
the ``structures`` set draws them (a seed no training or evaluation uses), each recorded as a
stream with ``sensors.camera_reports_impact_point`` true at the shipped layout, self-calibrated
and labelled by the shipped statistical method, as ``tail-beam evaluate`` does. Prints three
tables, asserts nothing, ships nothing:

1. the shipped method's accuracy with the point and without it (its ``logit_without_point``);
2. how well each reading of the contact duration tells the true one (the standard deviation of
   log(read / true), and of the residual of the least-squares combination of every reading);
3. the ceiling: 5-fold cross-validation, by support, of a small network on the impact's
   (moment impulse, rebound speed, impact point) plus one reading of the duration, measured
   as the sensors give them or noise-free (from the simulation's truth), and with the true
   duration spoilt by log-normal noise of a given spread: how well the duration must be known
   for a target.

    python test/bench/bench_point_ceiling.py                  # about a minute here
    python test/bench/bench_point_ceiling.py --supports 30   # the results page's run
    python test/bench/bench_point_ceiling.py --camera-hz 20000  # a faster camera
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import sys
import time

import numpy as np

DEFAULT_SEED = 52006  # no training (7-10) or evaluation (41001-41006) seed
IMPACTS_PER_SUPPORT = 20
FOLDS = 5
NOISE_SPREADS = (0.05, 0.1, 0.15, 0.2)  # sd of log(duration) added to the true duration
DURATION_READINGS = (
    "contact_duration_s",
    "rebound_delay_s",
    "imu_pulse_width_s",
)


def main() -> int:
    from tail_beam_id.study.blas_threads import single_blas_thread
    from tail_beam_id.study.dataset import FOREIGN_RANGES, settings, support_streams
    from tail_beam_id.study.evaluation import wilson
    from tail_beam_id.study.runs import foreign_records
    from tail_beam_sim.config import load_parameters

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--supports", type=int, default=10, help="supports (20 impacts each)")
    parser.add_argument("--seed", type=int, default=DEFAULT_SEED, help="the supports' seed")
    parser.add_argument(
        "--camera-hz", type=float, default=None, help="camera frame rate (default: shipped)"
    )
    args = parser.parse_args()
    single_blas_thread()
    params = copy.deepcopy(dict(load_parameters()))
    params["sensors"]["camera_reports_impact_point"] = True
    (shipped,) = settings(params, [1.0], ["shipped"])
    if args.camera_hz is not None:
        shipped = dataclasses.replace(
            shipped, rates_hz={**shipped.rates_hz, "camera_frame_rate_hz": args.camera_hz}
        )
    started = time.perf_counter()
    rows = []
    for number, recorded in enumerate(
        support_streams(
            params,
            args.supports,
            IMPACTS_PER_SUPPORT,
            args.seed,
            which=FOREIGN_RANGES["structures"],
            setting=shipped,
        )
    ):
        records = foreign_records(
            params,
            recorded,
            number,
            IMPACTS_PER_SUPPORT,
            ["statistical"],
            ["self-calibrated"],
            "shipped",
            "structures",
        )
        rows += [(record, truth) for record, truth in zip(records, recorded.truths)]
    print(
        f"{len(rows)} impacts on {args.supports} supports (seed {args.seed}, camera "
        f"{shipped.rates_hz['camera_frame_rate_hz']:.0f} Hz), simulated and labelled in "
        f"{time.perf_counter() - started:.0f} s\n"
    )

    def cell(right: int, n: int) -> str:
        lo, hi = wilson(right, n)
        return f"{100 * right / max(n, 1):.1f} % ({100 * lo:.1f}-{100 * hi:.1f}, n {n})"

    n = len(rows)
    with_point = sum(r.correct for r, _ in rows)
    without = sum(
        r.label is not None
        and (r.label.features.get("logit_without_point", r.label.features.get("logit", 0.0)) > 0)
        == r.is_coal
        for r, _ in rows
    )
    print("| shipped statistical method | right |")
    print("| --- | --- |")
    print(f"| with the impact point | {cell(with_point, n)} |")
    print(f"| without it | {cell(without, n)} |\n")

    usable = [
        (r, t)
        for r, t in rows
        if r.label is not None
        and all(
            name in r.label.features
            for name in (*DURATION_READINGS, "moment_impulse_pressure_nms", "impact_x_m")
        )
    ]
    lost = n - len(usable)  # no reading of some kind: counted wrong in the ceiling table
    features = [r.label.features for r, _ in usable]
    truth_duration = np.log([t["contact_duration_s"] for _, t in usable])
    print("| duration reading | sd of log(read / true) |")
    print("| --- | --- |")
    readings = np.log([[max(abs(f[name]), 1e-6) for name in DURATION_READINGS] for f in features])
    for k, name in enumerate(DURATION_READINGS):
        print(f"| `{name}` | {np.std(readings[:, k] - truth_duration):.3f} |")
    design = np.column_stack([readings, np.ones(len(usable))])
    weights, *_ = np.linalg.lstsq(design, truth_duration, rcond=None)
    print(
        f"| least squares of all three (fitted on these impacts) | "
        f"{np.std(truth_duration - design @ weights):.3f} |\n"
    )

    measured = {
        "moment impulse": np.log([max(f["moment_impulse_pressure_nms"], 0.05) for f in features]),
        "rebound speed": np.log([max(f["rebound_speed_mps"], 0.05) for f in features]),
        "point": np.log([max(f["impact_x_m"], 0.05) for f in features]),
    }
    exact = {
        "moment impulse": np.log(
            [
                t["mass_kg"] * t["impact_speed_mps"] * (1.0 + t["restitution"]) * t["position_m"]
                for _, t in usable
            ]
        ),
        "rebound speed": np.log([t["rebound_speed_mps"] for _, t in usable]),
        "point": np.log([t["position_m"] for _, t in usable]),
    }
    delay = readings[:, DURATION_READINGS.index("rebound_delay_s")]
    half_sine = readings[:, DURATION_READINGS.index("contact_duration_s")]
    rng = np.random.default_rng(args.seed)
    durations = {
        "none": [],
        "true duration": [truth_duration],
        "rebound delay": [delay],
        "rebound delay + half-sine read": [delay, half_sine],
        **{
            f"true duration x log-normal, sd {s}": [
                truth_duration + rng.normal(0.0, s, truth_duration.size)
            ]
            for s in NOISE_SPREADS
        },
    }
    y = np.array([1.0 if r.is_coal else 0.0 for r, _ in usable])
    support = np.array([r.support for r, _ in usable])
    print("| duration input | impulse, rebound, point as measured | noise-free |")
    print("| --- | --- | --- |")
    for label, columns in durations.items():
        cells = []
        for base in (measured, exact):
            x = np.column_stack([*base.values(), *columns])
            cells.append(cell(_cross_validated(x, y, support), n))
        print(f"| {label} | {cells[0]} | {cells[1]} |", flush=True)
    if lost:
        print(f"\n{lost} impacts lacked a reading: counted wrong in the last table")
    return 0


def _cross_validated(x: np.ndarray, y: np.ndarray, support: np.ndarray) -> int:
    """Impacts a small network (8 tanh units, the training's fit) labels right when fitted on
    the other folds' supports."""
    from tail_beam_id.methods.statistical import network_logit
    from tail_beam_id.study.training import fit_network

    supports = np.unique(support)
    right = 0
    for fold in range(FOLDS):
        test = np.isin(support, supports[np.arange(supports.size) % FOLDS == fold])
        mean, scale = x[~test].mean(axis=0), x[~test].std(axis=0) + 1e-9
        network = fit_network((x[~test] - mean) / scale, y[~test], seed=1, hidden=8)
        said = network_logit(network, (x[test] - mean) / scale) > 0
        right += int(np.sum(said == (y[test] > 0.5)))
    return right


if __name__ == "__main__":
    sys.exit(main())
