"""PNG charts of an evaluation: accuracy against latency (every method, setting and data
window), accuracy against particle size, and accuracy against noise."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tail_beam_id.study.dataset import FOREIGN_SCENES, SCENE_SETS
from tail_beam_id.study.evaluation import Summary
from tail_beam_sim.plotting import pyplot, save_figure

MARKERS = {"threshold": "s", "statistical": "o", "physics": "^"}


def _noise(setting: str) -> float:
    """The noise factor of a setting key 'rates/xN' or 'rates/xN/profile' (NaN for sensors
    drawn with each support, whose noise is their own)."""
    return float(setting.split("/x")[1].split("/")[0]) if "/x" in setting else math.nan


def accuracy_vs_latency(items: Sequence[Summary], path: Path) -> Path:
    """Accuracy (95 % CI bars) against median data latency plus median compute time, ms: one
    panel per scene set, at most three to a row."""
    plt = pyplot()
    sets = _in_order({s.scene_set for s in items})
    columns = max(1, min(3, len(sets)))
    rows = max(1, math.ceil(len(sets) / columns))
    fig, axes = plt.subplots(
        rows,
        columns,
        figsize=(4.8 * columns, 3.9 * rows),
        squeeze=False,
        constrained_layout=True,
    )
    flat = list(axes.flat)
    colours: dict[str, str] = {}
    for ax, scene_set in zip(flat, sets):
        for s in (i for i in items if i.scene_set == scene_set):
            x = s.data_latency_ms["median"] + s.compute_ms["median"]
            colour = colours.setdefault(s.setting, f"C{len(colours) % 10}")
            ax.errorbar(
                x,
                100 * s.accuracy,
                yerr=[
                    [100 * (s.accuracy - s.accuracy_ci[0])],
                    [100 * (s.accuracy_ci[1] - s.accuracy)],
                ],
                fmt=MARKERS.get(s.method, "x"),
                color=colour,
                ms=5,
                capsize=2,
                alpha=0.85,
            )
        ax.set_title(scene_set)
        ax.set_xlabel("data + compute latency after contact, median (ms)")
        ax.set_ylabel("accuracy (%)")
        ax.grid(alpha=0.3)
    for ax in flat[len(sets) :]:
        ax.axis("off")
    handles = [
        plt.Line2D([], [], marker=m, ls="", color="k", label=name) for name, m in MARKERS.items()
    ]
    handles += [
        plt.Line2D([], [], marker="o", ls="", color=c, label=k) for k, c in colours.items()
    ]
    legend_ax = flat[len(sets)] if len(sets) < len(flat) else flat[-1]
    legend_ax.legend(handles=handles, fontsize=7, loc="center" if len(sets) < len(flat) else 0)
    fig.suptitle(
        "accuracy against latency (shape: method; colour: sensor setting; "
        "one point per data window; bars: 95 % interval)"
    )
    return save_figure(fig, path, 100, "--out")


def _in_order(sets: set[str]) -> list[str]:
    """Scene sets in SCENE_SETS' order (nominal support first), any other after, by name."""
    return sorted(sets, key=lambda n: (SCENE_SETS.index(n) if n in SCENE_SETS else 99, n))


def _panels(plt, items: Sequence[Summary]):  # type: ignore[no-untyped-def]
    """One subplot per scene set, side by side (one empty panel saying so when there is nothing
    to chart, e.g. a run too small to fill two size bins)."""
    sets = _in_order({s.scene_set for s in items})
    fig, axes = plt.subplots(
        1,
        max(len(sets), 1),
        figsize=(4.6 * max(len(sets), 1), 4.2),
        squeeze=False,
        constrained_layout=True,
    )
    if not sets:
        axes[0][0].text(0.5, 0.5, "no data for this chart in this run", ha="center", va="center")
    return fig, dict(zip(sets, axes[0]))


def accuracy_vs_size(items: Sequence[Summary], path: Path, window_s: float) -> Path:
    """Accuracy per radius bin at nominal noise and the configured data window: one panel per
    scene set with sizes, one line per rates and method."""
    plt = pyplot()
    chosen = [
        s
        for s in items
        if (_noise(s.setting) == 1.0 or s.scene_set in FOREIGN_SCENES)
        and len(s.by_size) > 1
        and s.window_s == window_s
    ]
    fig, axes = _panels(plt, chosen)
    for s in chosen:
        rates = s.setting.split("/x")[0]
        centres = [1e3 * (b["radius_m"][0] * b["radius_m"][1]) ** 0.5 for b in s.by_size]
        axes[s.scene_set].plot(
            centres,
            [100 * b["accuracy"] for b in s.by_size],
            marker=MARKERS.get(s.method, "x"),
            ls="-" if rates == "nominal" else "--",
            label=f"{rates} {s.method}",
        )
    return _save_log_x_panels(
        plt,
        fig,
        axes,
        path,
        f"noise x1, window {1e3 * window_s:g} ms",
        "particle radius (mm, bin centre)",
    )


def accuracy_vs_noise(items: Sequence[Summary], path: Path, window_s: float) -> Path:
    """Accuracy against the noise factor at the configured data window: one panel per scene
    set, one line per rates and method."""
    plt = pyplot()
    chosen = [s for s in items if s.window_s == window_s and s.scene_set not in FOREIGN_SCENES]
    fig, axes = _panels(plt, chosen)
    lines: dict[tuple[str, str, str], list[tuple[float, float]]] = {}
    for s in chosen:
        lines.setdefault((s.scene_set, s.setting.split("/x")[0], s.method), []).append(
            (_noise(s.setting), 100 * s.accuracy)
        )
    for (scene_set, rates, method), points in sorted(lines.items()):
        points.sort()
        axes[scene_set].plot(
            [p[0] for p in points],
            [p[1] for p in points],
            marker=MARKERS.get(method, "x"),
            ls="-" if rates == "nominal" else "--",
            label=f"{rates} {method}",
        )
    return _save_log_x_panels(
        plt, fig, axes, path, f"window {1e3 * window_s:g} ms", "sensor noise (x nominal RMS)"
    )


def _save_log_x_panels(
    plt: Any, fig: Any, axes: dict[str, Any], path: Path, subtitle: str, xlabel: str
) -> Path:
    """Finish accuracy panels on a log x axis, titled ``<scene set> (<subtitle>)``, and save."""
    for name, ax in axes.items():
        ax.set_xscale("log")
        ax.set_title(f"{name} ({subtitle})")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("accuracy (%)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return save_figure(fig, path, 100, "--out")


def reliability_diagram(items: Sequence[Summary], path: Path, window_s: float) -> Path:
    """Stated confidence against the accuracy actually reached, per confidence bin: one panel per
    scene set, one line per setting and method; on the diagonal a label's confidence is honest,
    below it the method is overconfident. The legend gives each line's ECE."""
    plt = pyplot()
    chosen = [s for s in items if s.window_s == window_s and s.extra.get("reliability")]
    fig, axes = _panels(plt, chosen)
    for s in chosen:
        bins = s.extra["reliability"]
        ax = axes[s.scene_set]
        ax.plot(
            [b["confidence"] for b in bins],
            [b["accuracy"] for b in bins],
            marker=MARKERS.get(s.method, "x"),
            label=f"{s.setting} {s.method} (ECE {s.extra['ece']:.3f})",
        )
    for name, ax in axes.items():
        ax.plot([0.5, 1.0], [0.5, 1.0], color="k", lw=0.8, ls="--")
        ax.set_xlim(0.5, 1.0)
        ax.set_ylim(0.0, 1.02)
        ax.set_title(name)
        ax.set_xlabel("stated confidence (bin mean)")
        ax.set_ylabel("accuracy in the bin")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6, loc="lower right")
    fig.suptitle("reliability: stated confidence against accuracy")
    return save_figure(fig, path, 100, "--out")


def write_all(items: Sequence[Summary], directory: Path, window_s: float) -> list[Path]:
    """All four charts into ``directory`` (size, noise and reliability at data window
    ``window_s``)."""
    directory.mkdir(parents=True, exist_ok=True)
    return [
        reliability_diagram(items, directory / "reliability.png", window_s),
        accuracy_vs_latency(items, directory / "accuracy_vs_latency.png"),
        accuracy_vs_size(items, directory / "accuracy_vs_size.png", window_s),
        accuracy_vs_noise(items, directory / "accuracy_vs_noise.png", window_s),
    ]
