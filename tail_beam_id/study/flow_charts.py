"""PNG chart of the flow scene set: the share's error against the flow rate for every support
and layout, and the estimated share against the truth over time on the nominal support."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from tail_beam_id.study.flow_evaluation import LEVELS, FlowCase
from tail_beam_sim.plotting import pyplot, save_figure


def flow_chart(cases: Sequence[FlowCase], path: Path) -> Path:
    """Left: MAE per interval (points) against lumps/s, one line per support and layout (solid:
    shipped layout, dashed: IMU alone). Right: the nominal support's shipped-layout estimate
    (lines) and truth (dots) per interval end, one colour per rate."""
    plt = pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(11.0, 4.2), constrained_layout=True)
    groups: dict[tuple[str, str], list[FlowCase]] = {}
    for case in cases:
        groups.setdefault((case.support, case.layout), []).append(case)
    colours: dict[str, str] = {}
    for (support, layout), items in groups.items():
        items = sorted(items, key=lambda c: c.rate_per_s)
        colour = colours.setdefault(support, f"C{len(colours) % 10}")
        left.plot(
            [c.rate_per_s for c in items],
            [100 * c.mae for c in items],
            marker="o",
            ls="-" if layout == "shipped" else "--",
            color=colour,
            label=f"{support}, {layout}",
        )
    left.axhline(5.0, color="k", lw=0.8, ls=":")
    left.set_xscale("log")
    left.set_xlabel("flow rate (lumps/s)")
    left.set_ylabel("share MAE per 1 s interval (points)")
    left.grid(alpha=0.3)
    left.legend(fontsize=7)
    nominal = sorted(
        (c for c in cases if c.support == "nominal" and c.layout == "shipped"),
        key=lambda c: c.rate_per_s,
    )
    for k, case in enumerate(nominal):
        colour = f"C{k % 10}"
        ends = [end for end, _, _ in case.series]
        right.plot(
            ends,
            [math.nan if est is None else 100 * est for _, _, est in case.series],
            color=colour,
            label=f"{case.rate_per_s:g}/s",
        )
        right.plot(ends, [100 * t for _, t, _ in case.series], ".", color=colour, ms=3)
    for level in LEVELS:
        right.axhline(100 * level, color="k", lw=0.8, ls=":")
    right.set_xlabel("interval end (s)")
    right.set_ylabel("gangue share by count (%)")
    right.set_title("nominal support, shipped layout: estimate (line), truth (dots)", fontsize=9)
    right.grid(alpha=0.3)
    right.legend(fontsize=7)
    return save_figure(fig, path, 100, "--out")
