"""Benchmark of the simulator and the identification at full speed, every sensor on; prints
figures, asserts nothing.

1. ``simulate()`` of the default scene, every sensor of the shipped layout (and without the
   tail-beam accelerometer), against scipy's Radau at rtol 1e-8 solving the same impact, timed
   in alternating rounds (tail_beam_sim.physics.benchmark.simulate_speed): the speed-up, a
   ratio within one run.
2. ``simulate_many``: distinct drawn impacts (coal and gangue, 25-100 mm, 0.5-4 m, over the
   impact zone, ``--batch`` of them at once) per second with full streams, one process: per
   wall second and per CPU second of the process (one core's figure on a shared machine).
3. The stream simulator at sim_node's shipped layout (sim_node.yaml: pressure and IMU at 2 kHz,
   the accelerometer at 25.6 kHz, the modal tier), advanced in 10 ms chunks with an impact
   every 0.3 s: CPU seconds (process time) per simulated second, the share of a core it needs
   in real time.
4. Identification of drawn impacts (the training's ``varied`` set) replayed in id_node's 10 ms
   chunks and in one delivery (as training replays them): ms per impact and their ratio, and
   whether every label and feature agrees.

Usage: python test/bench/bench_speed.py [--repeats 5] [--impacts 40] [--batch 200] [--stream-s 2]
Each figure is a median of repeated runs; the machine is shared: quote the ratios.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.replay import replay
from tail_beam_id.study.dataset import evaluation_params, settings, simulate_set
from tail_beam_id.study.runs import REPLAY_CHUNK_S, WHOLE_STREAM_CHUNK_S
from tail_beam_sim.config import default_config_dir, load_parameters
from tail_beam_sim.physics import benchmark
from tail_beam_sim.physics.fidelity import shipped_settings
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.stream import StreamSimulator

IMPACTS = (
    {"material": "coal", "radius_m": 0.04, "drop_height_m": 3.0, "position_m": 1.0},
    {"material": "marble", "radius_m": 0.06, "drop_height_m": 2.0, "position_m": 0.5},
)


def stream_cpu_per_s(seconds: float, repeats: int) -> float:
    """Median CPU s per simulated s of the stream simulator at sim_node's layout."""
    params = load_parameters([str(default_config_dir() / "sim_node.yaml")])
    times = []
    for _ in range(repeats):
        stream = StreamSimulator.from_params(params)
        for k in range(int(seconds / 0.3)):
            stream.submit(IMPACTS[k % 2], contact_stamp_s=0.1 + 0.3 * k)
        start, t = time.process_time(), 0.0
        while t < seconds:
            t += 0.01
            stream.advance(t)
        times.append(time.process_time() - start)
    return statistics.median(times) / seconds


def replay_ms(results: list, chunk_s: float, repeats: int) -> tuple[float, list]:
    """Median ms per impact to identify ``results`` (threshold method), and the labels."""
    params = load_parameters()
    section = dict(params["identification"])
    times, labels = [], []
    for _ in range(repeats):
        start = time.perf_counter()
        labels = [
            replay(
                StreamIdentifier("threshold", section, params),
                r.pressure,
                r.imu,
                [r.rebound],
                vibration=r.vibration,
                chunk_s=chunk_s,
            )
            for r in results
        ]
        times.append(time.perf_counter() - start)
    return statistics.median(times) / len(results) * 1e3, labels


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--impacts", type=int, default=40)
    parser.add_argument("--batch", type=int, default=200)
    parser.add_argument("--stream-s", type=float, default=2.0)
    args = parser.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.2f} ({os.cpu_count()} cores, shared)")
    params = load_parameters()
    scene = Scene.from_params(params, {})
    fidelity = shipped_settings()
    speed = benchmark.simulate_speed(scene, fidelity, args.repeats)
    print(
        f"simulate(), default scene, every sensor: {speed['speedup']:.0f} x Radau rtol 1e-8 "
        f"({speed['speedup_no_vibration']:.0f} x without the accelerometer; target >= 100 x); "
        f"medians {speed['simulate_median_s'] * 1e3:.3f} ms against "
        f"{speed['radau_median_s'] * 1e3:.1f} ms; rebound error {speed['rebound_error']:.1e}"
    )
    many = benchmark.simulate_throughput(scene, fidelity, args.batch, args.repeats)
    print(
        f"simulate_many, {args.batch} drawn impacts at once, full streams: "
        f"{many['impacts_per_s']:,.0f} impacts/s, {many['impacts_per_cpu_s']:,.0f} per CPU "
        f"second (target >= 5,000 on one core); each at {many['sensor_settings']} sensor "
        f"settings: {many['results_per_s_at_settings']:,.0f} results/s"
    )
    cpu = stream_cpu_per_s(args.stream_s, args.repeats)
    print(
        f"stream simulator at sim_node's layout (10 ms chunks, an impact every 0.3 s): "
        f"{cpu:.3f} CPU s per simulated s ({cpu:.0%} of a core in real time)"
    )
    seed = int(evaluation_params(params)["training_seed"]) + 2
    results = [
        result
        for impact in simulate_set(
            params, "varied", args.impacts, seed, settings(params, every_rate=True), None
        )
        for result in impact.results.values()
    ]
    chunked, labels_chunked = replay_ms(results, REPLAY_CHUNK_S, args.repeats)
    whole, labels_whole = replay_ms(results, WHOLE_STREAM_CHUNK_S, args.repeats)
    same = all(
        [(label.decision(), dict(label.features)) for label in a]
        == [(label.decision(), dict(label.features)) for label in b]
        for a, b in zip(labels_chunked, labels_whole)
    )
    print(
        f"identification of {len(results)} drawn impacts: {chunked:.1f} ms per impact in 10 ms "
        f"chunks, {whole:.1f} ms in one delivery ({chunked / whole:.2f} x); labels and "
        f"features the same: {same}"
    )
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
