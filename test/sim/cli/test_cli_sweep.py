"""`tail-beam sweep` as a user runs it: numeric JSON, the tier it uses (the same model as
`tail-beam simulate`), and bad input."""

from __future__ import annotations

import json

import pytest
from test_cli_simulate import run_cli

from tail_beam_sim.cli.sweep_cmd import COLUMNS


def sweep_rows(capsys, *argv: str) -> list[dict]:
    code, out, err = run_cli(capsys, "sweep", *argv, "--json")
    assert code == 0, err
    return [json.loads(line) for line in out.splitlines()]


def test_json_swept_values_are_numbers(capsys):
    """`sweep --json` writes the swept value as the number it is (as in impact_cmd), not as the
    text it was typed as."""
    rows = sweep_rows(capsys, "drop_height_m", "2.0", "3.5", "4")
    assert [r["drop_height_m"] for r in rows] == [2.0, 3.5, 4.0]
    assert all(type(r["drop_height_m"]) is float for r in rows)
    # Higher drops strike faster: the value typed is the value simulated.
    assert rows[0]["impact_speed_mps"] < rows[1]["impact_speed_mps"] < rows[2]["impact_speed_mps"]
    materials = sweep_rows(capsys, "material", "coal", "marble")
    assert [r["material"] for r in materials] == ["coal", "marble"]


@pytest.mark.parametrize("tier", ["modal", "rigid", None])
def test_row_equals_simulate_with_the_same_settings(capsys, tier):
    """A sweep row (--tier modal, rigid, or the default) is the very result `tail-beam
    simulate` gives for the same impact and tier: the README's worked example and its 3.5 m row
    agree."""
    option = ["--tier", tier] if tier else []
    (row,) = sweep_rows(
        capsys,
        "drop_height_m",
        "3.5",
        "--material",
        "coal",
        "--radius-m",
        "0.025",
        "--position-m",
        "1.0",
        *option,
    )
    code, out, err = run_cli(
        capsys,
        "simulate",
        "--material",
        "coal",
        "--radius-m",
        "0.025",
        "--drop-height-m",
        "3.5",
        "--position-m",
        "1.0",
        "--json",
        *option,
    )
    assert code == 0, err
    single = json.loads(out)
    assert (
        row["tier"] == single["tier"] == (tier or "modal")
    )  # auto picks modal for the worked example
    for column in COLUMNS:
        assert row[column] == pytest.approx(single[column], rel=1e-12), column


def test_tier_changes_the_model_and_the_table_says_which(capsys):
    """The rigid beam misses the bending modes the modal tier sees in the IMU, and the table's
    header names the tier used."""
    (modal,) = sweep_rows(capsys, "position_m", "1.0", "--tier", "modal")
    (rigid,) = sweep_rows(capsys, "position_m", "1.0", "--tier", "rigid")
    assert rigid["tier"] == "rigid" and modal["tier"] == "modal"
    assert modal["peak_imu_dynamic_accel_mps2"] > 1.3 * rigid["peak_imu_dynamic_accel_mps2"]
    code, out, _ = run_cli(capsys, "sweep", "position_m", "0.5", "1.0", "--tier", "rigid")
    assert code == 0
    assert out.splitlines()[0].startswith("# tier rigid (--tier rigid)")


@pytest.mark.parametrize(
    "argv, field",
    [
        (["drop_height_m", "3.5", "--tier", "stiff"], "--tier"),
        (["drop_height_m", "abc"], "values (drop_height_m)"),
        (["position_m", "9.0"], "values (position_m)"),
    ],
)
def test_bad_input_exits_2_with_one_line_naming_it(capsys, argv, field):
    """A tier that does not exist, or a swept value that is not a number in range, exits 2 with
    one line naming it; nothing is printed on stdout."""
    code, out, err = run_cli(capsys, "sweep", *argv)
    assert code == 2
    assert out == ""
    assert len(err.strip().splitlines()) == 1 and field in err
