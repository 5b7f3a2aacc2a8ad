"""Start-up scenarios: a YAML list of impacts and a generated caving stream."""

from __future__ import annotations

import pytest

from tail_beam_sim.config import deep_merge, default_config_dir, load_parameters
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.materials import material_table
from tail_beam_sim.physics.scenario import (
    generate_caving_stream,
    load_scenario,
    read_scenario_file,
)
from tail_beam_sim.physics.support import Support


@pytest.fixture(scope="module")
def node_params():
    return load_parameters([default_config_dir() / "sim_node.yaml"])


def scenario(node_params, **changes):
    params = deep_merge({}, node_params)
    deep_merge(params, {"scenario": changes})
    materials = material_table(params)
    return load_scenario(
        params["scenario"], materials, Support.from_params(params["support"], materials)
    )


def test_generated_stream_has_the_exact_gangue_share_and_stays_in_its_ranges(node_params):
    """A generated stream of 40 has exactly 10 gangue impacts, every size, height, position,
    restitution and gap in its configured range, and unique ids."""
    planned = scenario(node_params, source="generated", count=40, gangue_fraction=0.25, seed=7)
    materials = material_table(node_params)
    gangue = [p for p in planned if materials[p.command["material"]].material_class == "gangue"]
    assert len(planned) == 40 and len(gangue) == 10
    for p in planned:
        c = p.command
        material = materials[c["material"]]
        assert (
            0.025 <= c["radius_m"] <= 0.10
            and 1.5 <= c["drop_height_m"] <= 4.0
            and 0.2 <= c["position_m"] <= 1.4
        )
        assert material.restitution_range[0] <= c["restitution"] <= material.restitution_range[1]
    gaps = [b.contact_stamp_s - a.contact_stamp_s for a, b in zip(planned, planned[1:])]
    assert planned[0].contact_stamp_s == 0.5 and all(0.4 <= g <= 0.7 for g in gaps)
    assert len({p.command["impact_id"] for p in planned}) == 40


def test_generated_stream_is_reproducible_by_seed(node_params):
    """The same seed generates the same stream, another seed another."""
    a = scenario(node_params, source="generated", seed=3)
    b = scenario(node_params, source="generated", seed=3)
    c = scenario(node_params, source="generated", seed=4)
    assert a == b and a != c


def test_scenario_file_keeps_order_and_requested_stamps(tmp_path, node_params):
    """A scenario file's impacts keep their order and requested contact stamps, which are not
    passed on as command fields."""
    path = tmp_path / "impacts.yaml"
    path.write_text(
        "- {material: coal, radius_m: 0.03, drop_height_m: 2.0, position_m: 0.5, contact_stamp_s: "
        "1.5}\n"
        "- {material: marble, radius_m: 0.03, impact_speed_mps: 7.0, position_m: 0.9}\n"
    )
    planned = scenario(node_params, source="file", file=str(path))
    assert [p.command["material"] for p in planned] == ["coal", "marble"]
    assert [p.contact_stamp_s for p in planned] == [1.5, None]
    assert "contact_stamp_s" not in planned[0].command


@pytest.mark.parametrize(
    "changes, field",
    [
        ({"source": "random"}, "scenario.source"),
        ({"source": "file", "file": "/nonexistent/impacts.yaml"}, "scenario.file"),
        ({"source": "generated", "count": -1}, "scenario.count"),
        ({"source": "generated", "gangue_fraction": 1.5}, "scenario.gangue_fraction"),
        ({"source": "generated", "radius_m": [0.1, 0.05]}, "scenario.radius_m[1]"),
        (
            {"source": "generated", "position_m": [1.5, 3.0]},
            "scenario[0].position_m",
        ),  # every one off the plate
    ],
)
def test_bad_scenario_fails_at_start_up_naming_the_field(node_params, changes, field):
    """Each bad scenario setting is an InputError whose field names it, down to the index of a
    bad range bound or impact."""
    with pytest.raises(InputError) as info:
        scenario(node_params, **changes)
    assert info.value.field == field


def test_bad_item_in_a_scenario_file_is_named_by_index(tmp_path, node_params):
    """A bad impact in a scenario file is named by its index and field."""
    path = tmp_path / "impacts.yaml"
    path.write_text(
        "impacts:\n- {material: coal, radius_m: 0.03, drop_height_m: 2.0, position_m: 0.5}\n- "
        "{material: chalk}\n"
    )
    with pytest.raises(InputError) as info:
        scenario(node_params, source="file", file=str(path))
    assert info.value.field == "scenario[1].material"


def test_generator_needs_both_classes_when_mixing(node_params):
    """Asking for a gangue share with no gangue material in the table is refused, naming gangue."""
    materials = {
        k: v for k, v in material_table(node_params).items() if v.material_class != "gangue"
    }
    with pytest.raises(InputError, match="gangue"):
        generate_caving_stream({**node_params["scenario"], "gangue_fraction": 0.5}, materials)


def test_a_hostile_scenario_file_is_refused_by_name(tmp_path):
    """A scenario file whose anchors multiply (a billion laughs) or that is binary junk is
    refused naming scenario.file, without expanding it, as tail-beam send's files are."""
    laughs = ["a: &a [x, x, x, x, x, x, x, x, x, x]"]
    for level in range(1, 9):
        previous = chr(ord("a") + level - 1)
        name = chr(ord("a") + level)
        laughs.append(f"{name}: &{name} [" + ", ".join(f"*{previous}" for _ in range(10)) + "]")
    hostile = {"laughs.yaml": "\n".join(laughs) + "\n", "junk.yaml": b"\xff\xfe\x00junk"}
    for name, content in hostile.items():
        path = tmp_path / name
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
        with pytest.raises(InputError, match="scenario.file"):
            read_scenario_file(str(path))
