"""Where identification breaks when a support's sensors differ from what the simulator and the
training assume: the foreign set's recordings, changed the way another sensor, DAQ or simulator
could change them, each identified as `tail-beam identify` does (self-calibrated, shipped
sensors). Prints a table; asserts nothing.

    python test/bench/bench_robustness.py    # 10 supports x 20 impacts, about 3 minutes here
    python test/bench/bench_robustness.py --changes baseline,camera_late_0.2ms

Each change is applied to the recorded streams, not simulated afresh, so every row scores the
same impacts as the baseline. Compare each row's accuracy and its wrong labels at confidence
>= 0.9 with the baseline's: a change that costs accuracy but not confidence is honest, one that
makes labels surely wrong is what to guard against.
"""

from __future__ import annotations

import argparse
import copy
import sys
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np
from scipy import signal

IMPACTS_PER_SUPPORT = 20


def _vibration(recorded, change: Callable[[np.ndarray, float], np.ndarray]):
    """The stream with its accelerometer samples changed (``change(samples m/s^2, period s)``)."""
    v = recorded.vibration
    return replace(
        recorded,
        vibration=replace(
            v,
            accel_mps2=change(np.asarray(v.accel_mps2, dtype=float), v.period_s).astype(
                np.float32
            ),
        ),
    )


def _ac_coupled(samples: np.ndarray, period_s: float) -> np.ndarray:
    """A piezoelectric (AC-coupled) sensor's view: no gravity, a 0.5 Hz high-pass."""
    sos = signal.butter(1, 0.5, btype="high", fs=1.0 / period_s, output="sos")
    return signal.sosfilt(sos, samples - samples[:2000].mean())


def _lowpass(samples: np.ndarray, period_s: float) -> np.ndarray:
    """A steeper, lower anti-alias filter on top of the sensor's (8th order at 0.2 x the rate)."""
    sos = signal.butter(8, 0.2 / period_s, fs=1.0 / period_s, output="sos")
    return signal.sosfilt(sos, samples - samples[0]) + samples[0]


def _camera_rate(recorded, rate_hz: float):
    """The rebounds as a camera at ``rate_hz`` stamps them: the first frame after separation."""
    separations = np.array([t["final_separation_stamp"] for t in recorded.truths])
    rebounds = [
        replace(
            r,
            stamp_s=float(
                np.ceil(separations[np.argmin(np.abs(separations - r.stamp_s))] * rate_hz)
                / rate_hz
            ),
        )
        for r in recorded.rebounds
    ]
    return replace(recorded, rebounds=rebounds)


def _thinned(series, step: int):
    """Every ``step``-th sample of a pressure or IMU stream (a slower sensor)."""
    fields = {
        name: getattr(series, name)[::step]
        for name in (
            "stamp_s",
            "pressure_pa",
            "angular_velocity_radps",
            "linear_acceleration_mps2",
        )
        if hasattr(series, name)
    }
    return replace(series, **fields)


def _noisier(recorded, factor: float):
    """Every continuous stream with its noise RMS times ``factor`` (white noise added)."""
    rng = np.random.default_rng(5)

    def more(values: np.ndarray, axis_noise: float) -> np.ndarray:
        return values + rng.normal(0.0, axis_noise * np.sqrt(factor**2 - 1.0), values.shape)

    def rms(
        values: np.ndarray,
    ) -> float:  # from sample-to-sample differences, s.t. the sway does not count
        return float(1.4826 * np.median(np.abs(np.diff(values[:2000]))) / np.sqrt(2.0))

    v, imu, p = recorded.vibration, recorded.imu, recorded.pressure
    accel = imu.linear_acceleration_mps2.copy()
    accel[:, 2] = more(accel[:, 2], rms(accel[:, 2]))
    return replace(
        recorded,
        vibration=replace(
            v,
            accel_mps2=more(
                np.asarray(v.accel_mps2, float), rms(np.asarray(v.accel_mps2, float))
            ).astype(np.float32),
        ),
        imu=replace(imu, linear_acceleration_mps2=accel),
        pressure=replace(p, pressure_pa=more(p.pressure_pa, rms(p.pressure_pa))),
    )


CHANGES: dict[str, tuple[str, Callable]] = {
    "baseline": ("as simulated (shipped sensors)", lambda r: r),
    "accelerometer_upside_down": (
        "accelerometer reads -g and mirrored",
        lambda r: _vibration(r, lambda a, p: -a),
    ),
    "accelerometer_ac_coupled": (
        "piezoelectric: no gravity",
        lambda r: _vibration(r, _ac_coupled),
    ),
    "accelerometer_ac_upside_down": (
        "piezoelectric, upside down",
        lambda r: _vibration(r, lambda a, p: -_ac_coupled(a, p)),
    ),
    "accelerometer_gain_x3": (
        "accelerometer gain x 3",
        lambda r: _vibration(r, lambda a, p: 3.0 * a),
    ),
    "accelerometer_gain_x0.3": (
        "accelerometer gain x 0.3",
        lambda r: _vibration(r, lambda a, p: 0.3 * a),
    ),
    "accelerometer_lowpass": (
        "8th-order low-pass at 0.2 x rate",
        lambda r: _vibration(r, _lowpass),
    ),
    "accelerometer_late_0.3ms": (
        "accelerometer stamps 0.3 ms late",
        lambda r: replace(r, vibration=replace(r.vibration, stamp_s=r.vibration.stamp_s + 3e-4)),
    ),
    "camera_20kHz": ("camera at 20 kHz", lambda r: _camera_rate(r, 20000.0)),
    "camera_2kHz": ("camera at 2 kHz", lambda r: _camera_rate(r, 2000.0)),
    "camera_1kHz": ("camera at 1 kHz", lambda r: _camera_rate(r, 1000.0)),
    "camera_500Hz": ("camera at 500 Hz", lambda r: _camera_rate(r, 500.0)),
    "camera_250Hz": ("camera at 250 Hz", lambda r: _camera_rate(r, 250.0)),
    "camera_late_0.2ms": (
        "camera stamps 0.2 ms late",
        lambda r: replace(r, rebounds=[replace(b, stamp_s=b.stamp_s + 2e-4) for b in r.rebounds]),
    ),
    "camera_late_0.5ms": (
        "camera stamps 0.5 ms late",
        lambda r: replace(r, rebounds=[replace(b, stamp_s=b.stamp_s + 5e-4) for b in r.rebounds]),
    ),
    "pressure_offset_10MPa": (
        "jack set 10 MPa higher",
        lambda r: replace(
            r, pressure=replace(r.pressure, pressure_pa=r.pressure.pressure_pa + 1e7)
        ),
    ),
    "pressure_500Hz": (
        "pressure at 500 Hz",
        lambda r: replace(r, pressure=_thinned(r.pressure, 4)),
    ),
    "imu_1kHz": ("IMU at 1 kHz", lambda r: replace(r, imu=_thinned(r.imu, 2))),
    "imu_500Hz": ("IMU at 500 Hz", lambda r: replace(r, imu=_thinned(r.imu, 4))),
    "noise_x3": ("every stream's noise x 3", lambda r: _noisier(r, 3.0)),
    "no_accelerometer": ("no accelerometer (IMU only)", lambda r: replace(r, vibration=None)),
}


def main() -> int:
    from tail_beam_id.study.dataset import evaluation_params, settings, support_streams
    from tail_beam_id.study.evaluation import wilson
    from tail_beam_id.study.runs import foreign_records
    from tail_beam_sim.config import load_parameters

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--supports", type=int, default=10)
    parser.add_argument(
        "--seed", type=int, default=None, help="foreign seed (default: the evaluation's)"
    )
    parser.add_argument(
        "--changes", default=",".join(CHANGES), help=f"comma-separated, of: {', '.join(CHANGES)}"
    )
    args = parser.parse_args()
    names = [n for n in args.changes.split(",") if n]
    unknown = [n for n in names if n not in CHANGES]
    if unknown:
        parser.error(f"--changes: {unknown[0]!r} is not one of {', '.join(CHANGES)}")
    params = load_parameters()
    seed = (
        args.seed if args.seed is not None else int(evaluation_params(params)["seeds"]["foreign"])
    )
    started = time.perf_counter()
    streams = list(
        support_streams(
            params,
            args.supports,
            IMPACTS_PER_SUPPORT,
            seed,
            setting=settings(params, [1.0], ["shipped"])[0],
        )
    )
    print(
        f"{args.supports} foreign supports x {IMPACTS_PER_SUPPORT} impacts, seed {seed}, shipped "
        "sensors, self-calibrated "
        f"(recorded in {time.perf_counter() - started:.0f} s)",
        file=sys.stderr,
    )
    print("| change | accuracy (95 % CI) | extra | missed | wrong at >= 0.9 | mean confidence |")
    print("| --- | --- | --- | --- | --- | --- |")
    for name in names:
        what, change = CHANGES[name]
        records = []
        for number, recorded in enumerate(streams):
            records += foreign_records(
                params,
                change(copy.deepcopy(recorded)),
                number,
                IMPACTS_PER_SUPPORT,
                ["statistical"],
                ["self-calibrated"],
                name,
            )
        n = len(records)
        right = sum(r.correct for r in records)
        extra = sum(r.extra_labels for r in records)
        low, high = wilson(right, n + extra)
        confident = sum(
            1
            for r in records
            if r.label is not None and not r.correct and r.label.confidence >= 0.9
        )
        labelled = [r.label.confidence for r in records if r.label is not None]
        print(
            f"| {what} | {100 * right / (n + extra):.1f} % ({100 * low:.1f}-{100 * high:.1f}) | "
            f"{extra} | "
            f"{sum(r.label is None for r in records)} | {confident} | {np.mean(labelled):.3f} |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
