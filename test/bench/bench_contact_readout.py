"""How well the contact's duration is read from the accelerometer pulse, on supports whose
bending modes are spaced and weighted unlike the shipped one: read / true duration (median and
the 10-90 % spread) of the features ``contact_duration_s`` (the best half-sine,
tail_beam_id.signals.contact_fit) and ``contact_force_duration_s`` (the force history
deconvolved through the ringing, tail_beam_id.signals.contact_force; absent before it
existed), over 25-100 mm coal and gangue of the stream scene, at the shipped sensors (25.6 kHz
accelerometer), the true support's profile known; the whole identification's cost per impact
(the label's latency_ms: median), and the contact fit's with and without the force read-out
(each impact's samples fitted both ways, alternately, the least of three runs each; medians
over the impacts). Prints two tables, asserts nothing.

    python test/bench/bench_contact_readout.py              # 40 impacts per support, ~20 s
    python test/bench/bench_contact_readout.py --count 100

Two truths: the contact (first touch to final separation, impact_truth) and the force (the
simulated contact force above 5 % of its peak, the level the force read-out ends at): a
hysteretic contact's force falls to zero before the particle separates, and its last 5 % is a
tail at the noise's level for the smallest particles.

Supports (modal tier): the nominal one (config/modes.yaml); modes 185 / 560 Hz with 600 kg
modal masses; 300 / 1350 / 3100 Hz at 350 kg; 420 / 840 Hz (the second mode 2x the first) at
300 kg. The tabulated ones take the shipped shapes and no mass coupling with the rigid rotation
(tail_beam_id.study.supports.tabulated_modes), so each mode rings at the frequency named.
"""

from __future__ import annotations

import argparse
import copy
import sys
import time

import numpy as np

SUPPORTS: dict[str, tuple[tuple[float, float], ...] | None] = {
    "nominal": None,
    "185/560 Hz, 600 kg": ((185.0, 600.0), (560.0, 600.0)),
    "300/1350/3100 Hz, 350 kg": ((300.0, 350.0), (1350.0, 350.0), (3100.0, 350.0)),
    "420/840 Hz (2x), 300 kg": ((420.0, 300.0), (840.0, 300.0)),
}
FEATURES = ("contact_duration_s", "contact_force_duration_s")
LONG_S = 500e-6  # a contact at least this long is "long" (half a period of a 1 kHz mode), s
FORCE_END_FRACTION = 0.05  # the force's truth: above this fraction of its peak


def support_params(params: dict, table: tuple[tuple[float, float], ...] | None) -> dict:
    """The merged parameters of a support with the bending modes of ``table`` (None: as is)."""
    from tail_beam_id.study.supports import tabulated_modes

    varied = copy.deepcopy(params)
    if table is not None:
        varied["modes"] = tabulated_modes(params["modes"], table)
    return varied


def force_duration_s(history: dict) -> float:
    """How long the simulated contact force stays above FORCE_END_FRACTION of its peak, s."""
    t, f = history["time_s"], history["contact_force_n"]
    above = np.flatnonzero(f >= FORCE_END_FRACTION * f.max())
    return float(t[above[-1]] - t[above[0]])


def spread(ratios: list[float]) -> str:
    """'median (p10-p90)' of read / true ratios."""
    if not ratios:
        return "-"
    p10, p50, p90 = np.percentile(ratios, [10, 50, 90])
    return f"{p50:.2f} ({p10:.2f}-{p90:.2f})"


def main() -> int:
    from tail_beam_id.signals.contact_fit import ContactFitConfig, fit_contact
    from tail_beam_id.stream.identifier import StreamIdentifier
    from tail_beam_id.stream.replay import replay
    from tail_beam_id.study.dataset import settings, simulate_set
    from tail_beam_id.study.runs import true_profile_section
    from tail_beam_sim.cli.common import add_config_option
    from tail_beam_sim.config import load_parameters

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=40, help="impacts per support")
    parser.add_argument("--seed", type=int, default=52001, help="impacts' seed")
    add_config_option(parser)
    args = parser.parse_args()
    params = load_parameters(args.config)
    shipped = settings(params, [1.0], ["shipped"])
    print(
        "| support | feature | read / contact | read / contact, >= 500 us "
        "| read / force (5 %) | read / force, contact >= 500 us | labelled "
        "| compute ms/impact |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    config = ContactFitConfig.from_params(params["identification"]["contact_fit"])
    costs: dict[str, list[tuple[float, float]]] = {}
    for name, table in SUPPORTS.items():
        varied = support_params(params, table)
        varied["calibration"] = true_profile_section(varied)
        rows = []
        for impact in simulate_set(varied, "stream", args.count, args.seed, shipped):
            result = next(iter(impact.results.values()))
            truth = result.truth()
            identifier = StreamIdentifier("statistical", params["identification"], varied)
            labels = replay(
                identifier,
                result.pressure,
                result.imu,
                [result.rebound],
                vibration=result.vibration,
            )
            start = truth["contact_start_stamp"]
            near = [x for x in labels if abs(x.impact_stamp_s - start) < 0.005]
            rows.append(
                (
                    truth["final_separation_stamp"] - start,
                    force_duration_s(result.history),
                    near[0] if near else None,
                )
            )
            costs.setdefault(name, []).append(
                fit_cost(result.vibration, start, config, fit_contact)
            )
        cost = np.median([x.latency_ms for _, _, x in rows if x is not None])
        labelled = sum(x is not None for _, _, x in rows)
        for feature in FEATURES:
            read = [(x.features[feature], c, f) for c, f, x in rows if x and feature in x.features]
            cells = [
                [r / c for r, c, _ in read],
                [r / c for r, c, _ in read if c >= LONG_S],
                [r / f for r, _, f in read],
                [r / f for r, c, f in read if c >= LONG_S],
            ]
            print(
                f"| {name} | {feature} | "
                + " | ".join(spread(x) for x in cells)
                + f" | {len(read)}/{labelled} of {len(rows)} | {cost:.2f} |",
                flush=True,
            )
    print(
        "\n| support | contact fit, half-sine only (ms) | with the force read-out (ms) | ratio |"
    )
    print("| --- | --- | --- | --- |")
    for name, pairs in costs.items():
        without, with_force = (float(np.median(x)) for x in zip(*pairs))
        print(f"| {name} | {without:.2f} | {with_force:.2f} | {with_force / without:.2f} |")
    return 0


def fit_cost(blocks, onset_s: float, config, fit_contact) -> tuple[float, float]:
    """(ms without, ms with the force read-out) of the contact fit of one impact's samples:
    the least of three alternating runs each."""
    stamps, samples = blocks.sample_stamps_s(), blocks.accel_mps2.astype(float)
    period, noise = blocks.period_s, float(np.sqrt(blocks.noise_variance))
    best = [np.inf, np.inf]
    for _ in range(3):
        for k, with_force in enumerate((False, True)):
            started = time.perf_counter()
            fit_contact(stamps, samples, onset_s, period, noise, config, with_force=with_force)
            best[k] = min(best[k], time.perf_counter() - started)
    return best[0] * 1e3, best[1] * 1e3


if __name__ == "__main__":
    sys.exit(main())
