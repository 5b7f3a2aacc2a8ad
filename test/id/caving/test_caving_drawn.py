"""What a window drew from a flow, drawn again from its seed, and where the oracle closes."""

from __future__ import annotations

import copy
import math

import pytest

from tail_beam_id.caving.drawn import Drawn, drawn_between, oracle_close_s
from tail_beam_sim.config import default_config_dir, load_parameters
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.lumps import FlowParams, LumpSource
from tail_beam_sim.physics.materials import material_table
from tail_beam_sim.physics.support import Support

BASE = load_parameters(
    [default_config_dir() / "sim_node.yaml", default_config_dir() / "flow.yaml"]
)
MATERIALS = material_table(BASE)
SUPPORT = Support.from_params(BASE["support"], MATERIALS)


def source(seed: int = 5, **flow) -> LumpSource:
    section = copy.deepcopy(BASE["flow"]) | flow
    return LumpSource(FlowParams.from_params(section, MATERIALS, SUPPORT), MATERIALS, seed)


def test_pure_coal_draws_no_gangue_at_the_poisson_rate():
    """A share curve of 0 draws only coal; 100 s at 20 lumps/s draws 2000 lumps within four
    standard deviations (sqrt(2000) = 45); the same seed and stamps draw the same lumps."""
    coal = {"lumps_per_s": 20.0, "share_drawn_mass_kg": [0.0], "share_gangue": [0.0]}
    drawn = drawn_between(source(**coal), 10.0, 110.0)
    assert drawn.gangue_kg == 0.0 and drawn.gangue_content == 0.0
    assert abs(drawn.lumps - 2000) < 4 * math.sqrt(2000)
    assert drawn_between(source(**coal), 10.0, 110.0) == drawn
    assert drawn_between(source(seed=6, **coal), 10.0, 110.0) != drawn


def test_the_oracle_closes_at_the_end_of_the_first_interval_where_gangue_comes():
    """Pure coal for 100 kg, then pure gangue: the oracle (level 0.3, 1 s intervals) closes at
    the end of the interval of the first gangue lump's strike when that interval's gangue
    reaches 0.3 of its mass, and everything struck before that interval is coal."""
    flow = {"lumps_per_s": 20.0, "share_drawn_mass_kg": [0.0, 100.0, 100.001]}
    flow["share_gangue"] = [0.0, 0.0, 1.0]
    probe = source(**flow)
    probe.open(2.0)
    lumps = probe.take_until(1000.0)
    first = next(lump for lump in lumps if lump.is_gangue)
    assert first.drawn_mass_kg >= 100.0
    close = oracle_close_s(source(**flow), 2.0, 1.0, 0.3, 600.0)
    start = math.floor(first.contact_stamp_s)
    interval = Drawn.of([lump for lump in lumps if start <= lump.contact_stamp_s < start + 1])
    expected = start + 1.0 if interval.gangue_content >= 0.3 else start + 2.0
    assert close == expected
    before = Drawn.of([lump for lump in lumps if lump.contact_stamp_s < start])
    assert before.gangue_kg == 0.0 and before.mass_kg > 0.0


def test_the_oracle_never_closes_a_flow_below_its_level_and_bad_stamps_are_refused():
    """A flow of 10 % gangue never reaches 0.5: no closing within the limit; a closing before
    the opening is refused naming closed_s."""
    thin = {"share_drawn_mass_kg": [0.0], "share_gangue": [0.1]}
    assert oracle_close_s(source(**thin), 0.0, 1.0, 0.9, 30.0) is None
    with pytest.raises(InputError, match="closed_s"):
        drawn_between(source(), 5.0, 4.0)
    with pytest.raises(InputError, match="interval_s"):
        oracle_close_s(source(), 0.0, 0.0, 0.3, 10.0)
