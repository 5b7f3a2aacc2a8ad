"""The caving study's identified sources: the drawn flow through the simulated sensors and the
identifier into the rules. A short face (2 supports, 1 m of top coal, coarse cells) keeps each
run to seconds."""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
import pytest

from tail_beam_id.caving.events import LabelEvent, ShareEstimate, Tick
from tail_beam_id.caving.rules import Rule, rule_factories
from tail_beam_id.study.caving import LabelModel, run_one, run_study
from tail_beam_id.study.caving_pipeline import Pipeline, pipeline_parameters
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.face import FaceParams, load_face_parameters


@pytest.fixture(scope="module")
def setup():
    """A short face, the shipped caving section, and an IMU-layout pipeline (no accelerometer:
    the cheapest layout with the beam's vibration)."""
    params = load_face_parameters()
    face = FaceParams.from_params(params).with_changes(
        supports=2, group_size=2, cell_size_m=0.25, top_coal_height_m=1.0, max_window_s=10.0
    )
    caving = params["caving"]
    pipeline = Pipeline(
        pipeline_parameters(), "imu", "struck", caving["labels"]["impacts_per_tonne"]
    )
    return face, caving, pipeline, LabelModel.from_params(caving["labels"])


class Never(Rule):
    """A rule that never closes; it keeps what it was fed."""

    name = "never"

    def __init__(self) -> None:
        super().__init__()
        self.fed: list = []

    def feed(self, event):
        self.fed.append(event)
        return None


def test_a_rule_that_never_closes_draws_what_the_truth_draws(setup):
    """Whatever the sensors and the identifier say, a window the rule never closes draws to
    face.max_window_s: the same cells, recovery and gangue content as on the truth source (the
    pipeline draws its lumps' properties from a generator of its own, never the face's)."""
    face, _, pipeline, model = setup
    truth = run_one(face, Never, "never", "truth", model, 3)
    identified = run_one(face, Never, "never", "identified:imu", model, 3, pipeline)
    assert truth.timed_out == identified.timed_out == face.supports
    assert identified.drawing_s == pytest.approx(truth.drawing_s, abs=1e-9)
    assert (identified.recovery, identified.gangue_content) == (
        truth.recovery,
        truth.gangue_content,
    )


def test_labels_are_the_struck_lumps_in_stamp_order_with_their_latency(setup):
    """The identifier's labels on the face's clock: about one per lump, each near a lump of
    the window (the truth source's lumps: same stamps), known after its impact by a latency
    under a second and fed when the clock reaches that; share estimates in the window."""
    face, caving, pipeline, model = setup
    rules: list[Never] = []

    def make() -> Never:
        rules.append(Never())
        return rules[-1]

    truth_rules: list[Never] = []

    def make_truth() -> Never:
        truth_rules.append(Never())
        return truth_rules[-1]

    run_one(face, make, "never", "identified:imu", model, 5, pipeline)
    run_one(face, make_truth, "never", "truth", model, 5)
    for rule, truth_rule in zip(rules, truth_rules):
        labels = [e for e in rule.fed if isinstance(e, LabelEvent)]
        lumps = sorted(e.stamp_s for e in truth_rule.fed if isinstance(e, LabelEvent))
        assert 0.8 * len(lumps) <= len(labels) <= 1.1 * len(lumps)
        # Each label is fed once the face's clock has reached its known time (no tick at or
        # after it came before it), and soon after (the cell it came out in: under 0.2 s).
        ticks = [k for k, e in enumerate(rule.fed) if isinstance(e, Tick)]
        for k, e in enumerate(rule.fed):
            if isinstance(e, LabelEvent):
                after = [rule.fed[t].stamp_s for t in ticks if t > k]
                before = [rule.fed[t].stamp_s for t in ticks if t < k]
                assert not after or after[0] >= e.known_s - 1e-9
                assert not before or before[-1] <= e.known_s + 0.2
        near = [min(abs(e.stamp_s - s) for s in lumps) for e in labels]
        assert sorted(near)[int(0.9 * len(near))] < 0.005  # 90 % within 5 ms of a lump
        for e in labels:
            assert e.stamp_s < e.known_s < e.stamp_s + 1.0
        shares = [e for e in rule.fed if isinstance(e, ShareEstimate)]
        assert shares and all(s.stamp_s >= rule.fed[0].stamp_s for s in shares)


def test_the_identified_source_is_deterministic_by_seed(setup):
    """The same seed gives the same run, wall time aside; the rule closes windows before the
    fixed-time bound."""
    face, caving, pipeline, model = setup
    maker = rule_factories(caving)["sprt"]

    def once(seed):
        run = run_one(face, maker, "sprt", "identified:imu", model, seed, pipeline)
        return dataclasses.replace(run, wall_s=0.0)

    a, b = once(1), once(1)
    assert a == b
    assert a.timed_out < face.supports


def test_a_bad_layout_is_refused_by_name(setup):
    """identified:<layout> with no such layout, a Pipeline of one, a lump mode that is none:
    InputError naming what was given."""
    face, caving, pipeline, model = setup
    with pytest.raises(InputError, match="identified:camera"):
        run_one(face, rule_factories(caving)["sprt"], "sprt", "identified:camera", model, 0)
    with pytest.raises(InputError, match="identified:camera"):
        run_study(face, caving, [0], ["sprt"], ["identified:camera"])
    with pytest.raises(InputError, match="layout = 'camera'"):
        Pipeline(pipeline.params, "camera")
    with pytest.raises(InputError, match="caving.pipeline.lumps"):
        Pipeline(pipeline.params, "imu", "some")
    with pytest.raises(InputError, match="needs the pipeline"):
        run_one(face, rule_factories(caving)["sprt"], "sprt", "identified:shipped", model, 0)


def test_worker_processes_give_the_runs_one_process_gives(setup):
    """--jobs: the plan's runs in two worker processes, in the plan's order, equal to one
    process's (wall time aside)."""
    face, caving, _, _ = setup

    def strip(runs):
        return [dataclasses.replace(r, wall_s=0.0) for r in runs]

    one = run_study(face, caving, [0, 1], ["sprt", "oracle"], ["truth", "stand-in"])
    two = run_study(face, caving, [0, 1], ["sprt", "oracle"], ["truth", "stand-in"], jobs=2)
    assert strip(one) == strip(two) and len(one) == 6


def test_the_impact_point_layout_reports_where_each_lump_struck(setup):
    """The flow simulator of the impact_point layout gives one camera point per lump, near the
    strike position asked (noise 1 cm); the other layouts none."""
    _, _, pipeline, _ = setup
    pointed = Pipeline(pipeline.params, "impact_point")
    for layout, expected in ((pointed, 3), (pipeline, 0)):
        sim = layout.simulator(1)
        for k, position in enumerate((0.4, 0.8, 1.2)):
            command = dict(layout.command(False, np.full(5, 0.5), f"p{k}")[0])
            command["position_m"] = position
            sim.submit(command, 0.1 + 0.1 * k)
        points = sim.advance(0.6).points
        assert len(points) == expected
        for (_, point), position in zip(points, (0.4, 0.8, 1.2)):
            assert abs(point.point_m[0] - position) < 0.05


def test_the_caving_verb_runs_an_identified_source(tmp_path, capsys):
    """`tail-beam caving --sources identified:imu` on one short support: its row, its speed
    line and a progress line per window; a bad layout refused by name before any run."""
    from tail_beam_id.cli import caving_cmd

    config = tmp_path / "short.yaml"
    config.write_text(
        "/**:\n  ros__parameters:\n    face:\n      supports: 1\n      group_size: 1\n"
        "      cell_size_m: 0.25\n      top_coal_height_m: 1.0\n      max_window_s: 10.0\n"
    )
    parser = argparse.ArgumentParser(prog="tail-beam")
    caving_cmd.register(parser.add_subparsers(dest="command"))

    def parse(argv):
        return parser.parse_args(["caving", "--config", str(config), "--chart", "", *argv])

    with pytest.raises(InputError, match="identified:camera"):
        caving_cmd.run(parse(["--sources", "truth,identified:camera"]))
    args = parse(["--sources", "identified:imu", "--rules", "sprt", "--seeds", "1"])
    assert caving_cmd.run(args) == 0
    captured = capsys.readouterr()
    assert "sprt            identified:imu     1" in captured.out
    assert "identified:imu (struck lumps):" in captured.out
    assert "caving: run 1/1 sprt identified:imu seed 0: 1 window(s)" in captured.err


def test_each_layouts_simulator_samples_its_sensors_alone(setup):
    """A layout's simulator samples the sensors the layout has and no other (the accelerometer
    at 25.6 kHz is most of the sampling cost: the IMU layout does not pay for it)."""
    _, _, pipeline, _ = setup
    for layout, present in (
        ("shipped", {"pressure", "imu", "vibration"}),
        ("imu", {"pressure", "imu"}),
        ("pressure", {"pressure"}),
    ):
        sim = Pipeline(pipeline.params, layout).simulator(1)
        sim.submit(dict(pipeline.command(True, np.full(5, 0.5), "g")[0]), 0.1)
        chunk = sim.advance(0.3)
        sampled = {
            name
            for name, count in (
                ("pressure", chunk.pressure.stamp_s.size),
                ("imu", chunk.imu.stamp_s.size),
                ("vibration", chunk.vibration.count),
            )
            if count
        }
        assert sampled == present, layout
        assert len(chunk.rebounds) == 1  # the camera whatever the layout
