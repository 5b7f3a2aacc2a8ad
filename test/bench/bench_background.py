"""How closely the moment impulse is read with the beam's free sway fitted over a short and a
long stretch before the onset: the jack-pressure fit (tail_beam_id.signals.features.fit_pressure)
over 20 ms against 0.1 s with the sway's drift, and the accelerometer's velocity step
(features.imu_impulse) over 10 ms against 50 ms with the drift. Supports of the held-out
``structures`` draws struck by the paper scene's and by the stream's impacts at the shipped
layout, each one continuous recording (the beam swaying from the impacts before), read at the
truth's onsets with the support's true parameters, so that the read-out alone is compared.
Prints, per scene, the RMS relative error of the pressure's read impulse against the truth
(m (v0 + v1) x), and per support the spread of the accelerometer's read / true impulse (its
standard deviation over its median: the gain aside, which calibration sets), median and worst
over the supports. Asserts nothing.

    python test/bench/bench_background.py                 # 40 supports per scene, ~1 min
    python test/bench/bench_background.py --supports 12
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from tail_beam_id.signals.features import BeamModel, background_s, fit_pressure, imu_impulse
from tail_beam_id.signals.imu_detection import Pulse
from tail_beam_id.study.dataset import evaluation_params, settings, support_streams
from tail_beam_sim.config import load_parameters

PRESSURE = {"20 ms": (0.02, False), "0.1 s + drift": (0.1, True)}
IMPULSE = {"10 ms": (0.01, False), "50 ms + drift": (0.05, True)}
SCENES = {"structures_paper": "paper", "structures": "stream"}


def true_moment_nms(truth: dict) -> float:
    """The impact's moment impulse about the hinge, N m s."""
    return truth["mass_kg"] * (truth["impact_speed_mps"] + truth["rebound_speed_mps"]) * truth[
        "position_m"
    ]


def read(recorded, identification: dict) -> tuple[dict, dict]:
    """Per stretch: the pressure's relative errors, and the accelerometer's read / true ratios
    (both over the recording's impacts)."""
    model = BeamModel.from_params(recorded.params)
    onsets = [t["contact_start_stamp"] for t in recorded.truths]
    truth = np.array([true_moment_nms(t) for t in recorded.truths])
    after_s = float(identification["background_after_onset_s"])
    window_s = float(identification["window_s"])
    pressure = {name: [] for name in PRESSURE}
    ratio = {name: [] for name in IMPULSE}
    stamp_v = recorded.vibration.sample_stamps_s()
    accel = recorded.vibration.accel_mps2
    period = float(np.median(np.diff(stamp_v)))
    for k, onset in enumerate(onsets):
        others = onsets[:k] + onsets[k + 1 :]
        for name, (most, drift) in PRESSURE.items():
            pre = background_s(onset, others, 0.02, most, after_s)
            fit = fit_pressure(
                model,
                recorded.pressure.stamp_s,
                recorded.pressure.pressure_pa,
                onset,
                pre,
                window_s,
                sway_drift=drift and pre > 0.02,
                other_onsets_s=others,
                min_separation_s=float(identification["neighbour_min_separation_s"]),
            )
            pressure[name].append((fit.moment_impulse_nms - truth[k]) / truth[k])
        pulse = Pulse(onset, onset, 1, period, 10.0, 0.1, period, 0, 0)
        for name, (most, drift) in IMPULSE.items():
            pre = background_s(onset, others, 0.01, most, after_s)
            step = imu_impulse(
                model,
                stamp_v,
                accel,
                pulse,
                pre,
                float(identification["impulse_skip_s"]),
                float(identification["vibration_window_s"]),
                drift and pre > 0.01,
            )
            ratio[name].append(step.velocity_mps / truth[k])
    return pressure, ratio


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--supports", type=int, default=40, help="supports per scene")
    args = parser.parse_args()
    params = load_parameters([])
    ev = evaluation_params(params)
    shipped = settings(params, [1.0], ["shipped"])[0]
    identification = dict(params["identification"])
    for scene_set, scene in SCENES.items():
        started = time.perf_counter()
        pressure = {name: [] for name in PRESSURE}
        spreads = {name: [] for name in IMPULSE}
        for recorded in support_streams(
            params,
            args.supports,
            20,
            int(ev["seeds"][scene_set]),
            "structures",
            setting=shipped,
            scene=scene,
        ):
            errors, ratios = read(recorded, identification)
            for name in PRESSURE:
                pressure[name] += errors[name]
            for name in IMPULSE:
                r = np.asarray(ratios[name])
                spreads[name].append(float(np.std(r) / abs(np.median(r))))
        print(
            f"{scene_set}: {args.supports} supports x 20 impacts, shipped layout, "
            f"{time.perf_counter() - started:.0f} s"
        )
        for name, errors in pressure.items():
            rms = float(np.sqrt(np.mean(np.square(errors))))
            print(f"  pressure, background {name:14s} RMS relative error {rms:.3f}")
        for name, values in spreads.items():
            print(
                f"  accelerometer, background {name:14s} spread per support: median "
                f"{np.median(values):.3f}, worst {np.max(values):.2f}"
            )


if __name__ == "__main__":
    main()
