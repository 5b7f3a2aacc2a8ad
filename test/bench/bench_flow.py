"""Benchmark of the flow simulator's core (tail_beam_sim.physics.flow); prints figures, asserts
nothing.

For each flow rate, :func:`simulate_flow` over a stretch of stream with the shipped layout
(modal tier, pressure and IMU at 2 kHz, accelerometer at 25.6 kHz) and the window open from
t = 0; CPU seconds (process time) of the run, median of ``--repeat`` runs. Reported:

* CPU per second of stream, and per lump (after taking away the cost of a quiet stream: the
  window closed, the sensors sampling the beam at rest);
* the ratio of CPU per lump at the densest rate to the sparsest: flat when the cost grows with
  the number of contacts, and proportional to the rate if it grew with contacts x stream length;
* doubling the stream at the densest rate: the CPU doubles (linear in time);
* the contact methods (flow.contact pulse / auto) at the densest rate.

Usage: python test/bench/bench_flow.py [--rates 5 50 200] [--seconds 4] [--repeat 3]
The machine is shared: say so when quoting figures.
"""

from __future__ import annotations

import argparse
import copy
import statistics
import time

from tail_beam_sim.config import default_config_dir, load_parameters
from tail_beam_sim.physics.flow import simulate_flow


def base_params() -> dict:
    config = default_config_dir()
    return load_parameters([config / "sim_node.yaml", config / "flow.yaml"])


def cpu_of(params: dict, seconds: float, windows, repeat: int) -> tuple[float, int]:
    """Median CPU seconds of ``repeat`` runs, and the lumps simulated."""
    times, lumps = [], 0
    for _ in range(repeat):
        start = time.process_time()
        record = simulate_flow(params, seconds, seed=1, windows=windows)
        times.append(time.process_time() - start)
        lumps = len(record.lumps)
    return statistics.median(times), lumps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", nargs="+", type=float, default=[5.0, 50.0, 200.0])
    parser.add_argument("--seconds", type=float, default=4.0)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    params = base_params()
    params["flow"]["onset_delay_s"] = 0.0
    seconds = args.seconds
    simulate_flow(params, 0.5, seed=1)  # warm-up: tables, imports
    quiet, _ = cpu_of(params, seconds, [(seconds + 1.0, seconds + 2.0)], args.repeat)
    print(f"quiet stream (window closed): {quiet / seconds * 1e3:.1f} ms CPU per s of stream")
    print(
        f"{'lumps/s':>8} {'lumps':>6} {'CPU s':>7} {'CPU/s of stream':>16} "
        f"{'ms per lump':>12} {'real-time load':>15}"
    )
    per_lump = {}
    for rate in args.rates:
        p = copy.deepcopy(params)
        p["flow"]["lumps_per_s"] = rate
        cpu, lumps = cpu_of(p, seconds, None, args.repeat)
        per_lump[rate] = (cpu - quiet) / max(lumps, 1) * 1e3
        print(
            f"{rate:8g} {lumps:6d} {cpu:7.2f} {cpu / seconds * 1e3:13.0f} ms "
            f"{per_lump[rate]:12.2f} {cpu / seconds * 100:14.0f}%"
        )
    low, high = min(args.rates), max(args.rates)
    print(
        f"CPU per lump at {high:g} lumps/s over {low:g} lumps/s: "
        f"{per_lump[high] / per_lump[low]:.2f} (flat: cost per contact; "
        f"{high / low:g} if it grew with contacts x stream length)"
    )
    p = copy.deepcopy(params)
    p["flow"]["lumps_per_s"] = high
    single, _ = cpu_of(p, seconds, None, args.repeat)
    double, _ = cpu_of(p, 2 * seconds, None, args.repeat)
    print(
        f"{high:g} lumps/s, {2 * seconds:g} s of stream over {seconds:g} s: "
        f"CPU x{double / single:.2f}"
    )
    for contact in ("pulse", "auto"):
        p["flow"]["contact"] = contact
        cpu, lumps = cpu_of(p, seconds, None, args.repeat)
        print(
            f"flow.contact {contact:5s} at {high:g} lumps/s: "
            f"{cpu / seconds * 1e3:.0f} ms CPU per s of stream, "
            f"{(cpu - quiet) / max(lumps, 1) * 1e3:.2f} ms per lump"
        )


if __name__ == "__main__":
    main()
