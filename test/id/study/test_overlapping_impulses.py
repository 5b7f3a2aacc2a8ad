"""Two lumps striking the simulated support a few milliseconds apart, identified from the
streams as a dense flow's are: each label's jack-pressure moment impulse is its own lump's
(the pressure fit reads the neighbour's impulse with it), where a fit of one impulse reads a
mixture of both."""

from __future__ import annotations

import pytest
from id_helpers import replay_chunk

from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.study.dataset import evaluation_params, study_simulator

LUMPS = (
    {"material": "sandstone", "radius_m": 0.05, "drop_height_m": 2.0, "position_m": 1.1},
    {"material": "coal", "radius_m": 0.06, "drop_height_m": 2.5, "position_m": 0.7},
)


def read_moments(params, gap_s: float, neighbour_fit: bool) -> tuple[list, list, list]:
    """(true moment impulses, labels' pressure moment impulses (N m s), labels' features) of the
    two lumps ``gap_s`` apart, in stamp order."""
    varied = dict(params)
    varied["sensors"] = {**varied["sensors"], "seed": 3}
    simulator = study_simulator(varied, evaluation_params(params)["tier"], len(LUMPS))
    for n, lump in enumerate(LUMPS):
        simulator.submit(lump, contact_stamp_s=0.3 + n * gap_s)
    chunk = simulator.advance(0.6)
    section = {**varied["identification"], "neighbour_fit": neighbour_fit}
    identifier = StreamIdentifier(None, params=section, model_params=varied)
    labels = replay_chunk(identifier, chunk)
    truths = [t for _, t in chunk.truths]
    true = [
        t["mass_kg"] * (t["impact_speed_mps"] + t["rebound_speed_mps"]) * t["position_m"]
        for t in truths
    ]
    return (
        true,
        [lab.features["moment_impulse_pressure_nms"] for lab in labels],
        [lab.features for lab in labels],
    )


@pytest.mark.parametrize("gap_s", [0.003, 0.008, 0.015])
def test_each_overlapping_lump_reads_its_own_moment_impulse(params, gap_s):
    """Lumps 3, 8 and 15 ms apart (the second one's pulse lost in the first one's ringing: it is
    found from its rebound): both labels come, each reads its lump's moment impulse within
    10 % and the later one says it read the earlier one's with it; one impulse per fit
    misreads one of them by more than 25 %."""
    true, joint, features = read_moments(params, gap_s, True)
    assert len(joint) == 2
    assert joint == pytest.approx(true, rel=0.1)
    assert features[1]["pressure_neighbours"] == 1.0
    assert "pressure_unresolved" not in features[1]
    _, single, _ = read_moments(params, gap_s, False)
    assert max(abs(s / t - 1.0) for s, t in zip(single, true)) > 0.25
