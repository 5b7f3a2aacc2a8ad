"""`tail-beam simulate --flow SECONDS`: a flow's share intervals, its bag, and bad input."""

from __future__ import annotations

import json

from tail_beam_sim import topics
from tail_beam_sim.bags.read import read_sensors
from tail_beam_sim.cli import main


def test_simulate_flow_prints_share_intervals_and_writes_a_bag(tmp_path, capsys):
    """`simulate --flow --json` prints the share intervals the bag it writes holds."""
    override = tmp_path / "fast.yaml"
    override.write_text(
        "/**:\n  ros__parameters:\n    flow:\n      lumps_per_s: 100.0\n"
        "      share_drawn_mass_kg: [0.0, 30.0, 60.0]\n      share_gangue: [0.0, 0.0, 1.0]\n"
    )
    bag = tmp_path / "bag"
    code = main(
        ["simulate", "--flow", "3", "--config", str(override), "--json", "--bag", str(bag)]
    )
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    assert out["lumps"] > 150 and [s["start_stamp_s"] for s in out["shares"]] == [0.0, 1.0, 2.0]
    assert out["windows"] == [{"stamp_s": 0.0, "action": "open"}]
    assert read_sensors(bag).json_topics[topics.GANGUE_SHARE_TRUTH] == out["shares"]


def test_simulate_flow_refuses_bad_input_by_name(tmp_path, capsys):
    """`simulate --flow` refuses a bad duration, an impact option, a bad flow config or a
    negative seed by name (exit 2)."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("/**:\n  ros__parameters:\n    flow:\n      lumps_per_s: 5000.0\n")
    cases = [
        (["--flow", "-1"], "--flow = '-1': must be in (0, 3600] s"),
        (["--flow", "1", "--material", "coal"], "--material = 'coal': is not taken with --flow"),
        (["--flow", "1", "--config", str(bad)], "flow.lumps_per_s = 5000"),
        (["--flow", "1", "--seed", "-5"], "flow.seed = -5: must be an integer >= 0"),
    ]
    for argv, message in cases:
        assert main(["simulate", *argv]) == 2
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err
