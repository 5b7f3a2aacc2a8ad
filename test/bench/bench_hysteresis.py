"""What reading the support's contact hysteresis from its recording buys on a law no training
saw (the independent evaluation's supports follow a hysteresis law of their own): the
hysteresis network (tail_beam_id.methods.hysteresis) refitted with one law left out, and the
foreign supports of that law self-calibrated and identified with it and without the hysteresis (the
shipped statistical networks either way, which did see every law: the "without" column is if
anything flattered). Prints a table, asserts nothing, ships nothing.

    # once (6.5 min):
    python -m tail_beam_id.study.training --count 300 --varied-count 3000 --cache records.json
    python test/bench/bench_hysteresis.py --cache records.json          # about 6 minutes here
    # simulates its own, quicker, wider intervals:
    python test/bench/bench_hysteresis.py --varied 1000 --supports 10

Training: the training cache's drawn-support records (``--cache``), or ``--varied`` stream-scene
and a fifth as many paper-scene impacts on drawn supports identified knowing their support
(training's seeds 9 and 10). Test: ``--supports`` foreign supports x 20 impacts of each scene
(seed 41004, shipped sensors), each self-calibrated on its own recording.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path


def main() -> int:
    from tail_beam_id.calibration.offline import calibrate, with_profile
    from tail_beam_id.methods import load_model
    from tail_beam_id.stream.label import match, match_tolerance_s
    from tail_beam_id.study.dataset import evaluation_params, settings, support_streams
    from tail_beam_id.study.evaluation import wilson
    from tail_beam_id.study.training import collect, fit_hysteresis, load_cache
    from tail_beam_sim.config import load_parameters

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--cache",
        default=None,
        help="training records (python -m tail_beam_id.study.training --cache)",
    )
    parser.add_argument(
        "--varied",
        type=int,
        default=1000,
        help="without --cache: stream-scene training impacts on drawn supports",
    )
    parser.add_argument(
        "--supports", type=int, default=30, help="foreign supports (20 impacts of each scene)"
    )
    args = parser.parse_args()
    params = load_parameters()
    ev = evaluation_params(params)
    section = params["identification"]["statistical"]["hysteresis"]
    started = time.perf_counter()
    if args.cache:
        records, _ = load_cache(Path(args.cache))
    else:
        seed = int(ev["training_seed"])
        records = collect(params, "varied", args.varied, seed + 2, None, true_profile=True)
        records += collect(
            params, "varied_paper", max(args.varied // 5, 50), seed + 3, None, true_profile=True
        )
    shipped = settings(params, [1.0], ["shipped"])[0]
    streams = {
        scene: list(
            support_streams(
                params,
                args.supports,
                20,
                int(ev["seeds"]["foreign"]),
                setting=shipped,
                scene=scene,
            )
        )
        for scene in ("paper", "stream")
    }
    print(
        f"{len(records)} training records, {args.supports} foreign supports x 2 scenes "
        f"(ready in {time.perf_counter() - started:.0f} s)",
        file=sys.stderr,
    )
    tolerance = match_tolerance_s(params["identification"])
    base_model = load_model("statistical")
    laws = sorted({recorded.support.contact_model for recorded in streams["paper"]})
    print(
        "| law left out (foreign supports) | paper: without → with the hysteresis | stream: "
        "without → with |"
    )
    print("| --- | --- | --- |")
    with tempfile.TemporaryDirectory() as folder:
        for law in laws:
            kept = [r for r in records if r.contact_model != law]
            model = {**base_model, "hysteresis": fit_hysteresis(kept, section, 7)}
            path = Path(folder) / f"statistical_without_{law}.json"
            path.write_text(json.dumps(model), encoding="utf-8")
            cells = []
            for scene in ("paper", "stream"):
                right = {"without": 0, "with": 0}
                n = 0
                for recorded in (r for r in streams[scene] if r.support.contact_model == law):
                    identify = _identifier(params, recorded, str(path))
                    v = recorded.vibration
                    profile = calibrate(
                        params,
                        (recorded.pressure.stamp_s, recorded.pressure.pressure_pa),
                        (recorded.imu.stamp_s, recorded.imu.linear_acceleration_mps2[:, 2]),
                        identify,
                        (v.sample_stamps_s(), v.accel_mps2) if v is not None and v.count else None,
                        [r.stamp_s for r in recorded.rebounds],
                        model["hysteresis"],
                    )
                    known = with_profile(params, profile)
                    unknown = json.loads(json.dumps(known))
                    unknown.get("calibration", {}).pop("hysteresis_weights", None)
                    for name, model_params in (("with", known), ("without", unknown)):
                        labels = identify(model_params)
                        matching = match(recorded.truths, labels, tolerance)
                        right[name] += sum(
                            1
                            for k, truth in enumerate(recorded.truths)
                            if matching.label_index(k) is not None
                            and labels[matching.label_index(k)].material == truth["label"]
                        )
                    n += len(recorded.truths)
                low, high = wilson(right["with"], n)
                cells.append(
                    f"{100 * right['without'] / n:.1f} → {100 * right['with'] / n:.1f} % "
                    f"({100 * low:.1f}–{100 * high:.1f}, n {n})"
                )
            print(f"| {law} ({n // 20}) | {cells[0]} | {cells[1]} |", flush=True)
    print(f"\n({time.perf_counter() - started:.0f} s)", file=sys.stderr)
    return 0


def _identifier(params, recorded, model_path: str):
    """identify(model_params): the recording's labels, the statistical method from
    ``model_path``."""
    from tail_beam_id.stream.identifier import StreamIdentifier
    from tail_beam_id.stream.replay import replay

    section = params["identification"]

    def identify(model_params):
        detection = {
            **section.get("detection", {}),
            **(model_params.get("identification", {}).get("detection") or {}),
        }
        identifier = StreamIdentifier(
            "statistical", {**section, "detection": detection}, model_params, model_path=model_path
        )
        return replay(
            identifier,
            recorded.pressure,
            recorded.imu,
            recorded.rebounds,
            vibration=recorded.vibration,
        )

    return identify


if __name__ == "__main__":
    raise SystemExit(main())
