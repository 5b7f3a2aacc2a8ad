"""The parameter tables of tail_beam_sim.spec: checks with the InputError messages the suite
gives, agreement with config/, and the reference page they render."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tail_beam_sim import spec
from tail_beam_sim.config import deep_merge
from tail_beam_sim.errors import InputError

REPO = Path(__file__).resolve().parents[3]
# The identifier declares its sections where it reads them; the reference page joins them.
ID_SECTIONS = "tail_beam_id.ros.id_node"


def every_section() -> tuple[spec.Section, ...]:
    """The simulator's sections and the identifier's."""
    return spec.sections_of([ID_SECTIONS])


def shipped() -> dict:
    """Every config/ parameter file merged."""
    merged: dict = {}
    for params in spec.shipped_parameters().values():
        deep_merge(merged, params)
    return merged


def test_every_config_key_has_a_spec():
    """Each key of config/*.yaml (impacts.yaml aside) is declared by a section of spec.py."""
    assert spec.unspecified_keys(shipped(), every_section()) == []


def test_every_required_field_is_in_config():
    """Each field without a default is present in config/ wherever its section is."""
    assert spec.missing_keys(shipped(), every_section()) == []


def test_a_key_config_lacks_or_adds_is_found():
    """The two checks do fail: an unknown key is named, and so is a required one removed."""
    params = shipped()
    params["support"]["beam_lenght_m"] = 1.0
    del params["materials"]["coal"]["density_kgpm3"]
    assert spec.unspecified_keys(params, every_section()) == ["support.beam_lenght_m"]
    assert spec.missing_keys(params, every_section()) == ["materials.coal.density_kgpm3"]


def test_the_shipped_sections_pass_their_own_checks():
    """Every section of config/ passes its check (bounds from other sections in context)."""
    params = shipped()
    context = {
        "bending_modes": 3,
        "particle_radius_max_m": 0.5,
        "drop_height_max_m": 50.0,
    }
    for section in every_section():
        for path, body in spec._mappings(params):
            if path and spec._matches(path, section.path):
                section.check(body, where=path, context=context)


@pytest.mark.parametrize(
    "field, value, message",
    [
        (
            spec.Field("x_s", "", low=0.0, high=10.0, low_open=True, unit="s"),
            -1,
            "must be in (0, 10] s",
        ),
        (spec.Field("x", "", low=0.0), "abc", "must be >= 0 (a finite number)"),
        (spec.Field("x", "", kind="int", low=1, high=8), 2.5, "must be an integer in [1, 8]"),
        (spec.Field("x", "", kind="bool"), "yes", "must be true or false"),
        (spec.Field("x", "", kind="choice", choices=("a", "b")), "c", "must be one of a, b"),
    ],
)
def test_a_field_refuses_naming_the_field_and_range(field, value, message):
    """A refusal is ``<section>.<field> = <value>: <allowed, unit>`` as require_range words it."""
    with pytest.raises(InputError) as caught:
        spec.Section("sec", "", (field,)).check({field.name: value})
    assert str(caught.value).startswith(f"sec.{field.name} = ")
    assert str(caught.value).endswith(message)


def test_bounds_by_name_defaults_and_missing_fields():
    """A bound naming an earlier field takes its value; a default fills an absent field; an
    absent required field is named as missing, with its range."""
    section = spec.Section(
        "s",
        "",
        (
            spec.Field("length_m", "", low=0.0, low_open=True, unit="m"),
            spec.Field("pin_m", "", low=0.0, high="length_m", unit="m", default=0.5),
        ),
    )
    assert section.check({"length_m": 2.0}) == {"length_m": 2.0, "pin_m": 0.5}
    with pytest.raises(InputError, match=r"s\.pin_m = 3: must be in \[0, 2\] m"):
        section.check({"length_m": 2, "pin_m": 3})
    with pytest.raises(InputError, match=r"s\.length_m = None: missing from the config"):
        section.check({})


def test_a_pair_checks_both_ends():
    """A ``pair`` is [low, high] with its ends named [0] and [1], high no less than low."""
    field = spec.Field("r_m", "", kind="pair", low=0.0, high=1.0, low_open=True, unit="m")
    section = spec.Section("p", "", (field,))
    assert section.check({"r_m": [0.1, 0.2]}) == {"r_m": (0.1, 0.2)}
    with pytest.raises(InputError, match=r"p\.r_m\[1\] = 0\.05: must be in \[0\.1, 1\] m"):
        section.check({"r_m": [0.1, 0.05]})
    with pytest.raises(InputError, match=r"p\.r_m = 3: must be \[low, high\] in m"):
        section.check({"r_m": 3})


def test_an_off_value_outside_the_range_is_taken_and_named():
    """recorder.max_bag_duration_s: 0 (never split) is taken, 1e-9 refused naming both."""
    assert spec.RECORDER.check({"max_bag_duration_s": 0}, only=["max_bag_duration_s"]) == {
        "max_bag_duration_s": 0.0
    }
    with pytest.raises(InputError, match=r"must be in \[1, 1e\+07\] s, or 0 \(never split\)"):
        spec.RECORDER.check({"max_bag_duration_s": 1e-9}, only=["max_bag_duration_s"])


def test_the_tables_choices_are_the_models():
    """Choices spec.py lists by name are the ones the models define."""
    from tail_beam_sim.physics.contact import CONTACT_LAWS
    from tail_beam_sim.physics.fidelity import TIERS
    from tail_beam_sim.physics.scenario import MAX_GENERATED, SOURCES

    assert spec.CONTACT_LAWS == CONTACT_LAWS
    assert tuple(TIERS) == spec.TIER_NAMES
    assert spec.SCENARIO_SOURCES == SOURCES and spec.MAX_GENERATED == MAX_GENERATED


def test_the_reference_page_is_up_to_date():
    """docs/parameters.md is what ``python -m tail_beam_sim.spec tail_beam_id.ros.id_node``
    prints, and its header names that command."""
    printed = subprocess.run(
        [sys.executable, "-m", "tail_beam_sim.spec", ID_SECTIONS],
        capture_output=True,
        text=True,
        check=True,
        cwd=REPO,
    ).stdout
    command = f"python -m tail_beam_sim.spec {ID_SECTIONS} > docs/parameters.md"
    assert command in printed.split("##")[0]
    assert "| `max_bag_size_bytes` | bytes |" in printed
    assert (REPO / "docs" / "parameters.md").read_text(encoding="utf-8") == printed
