"""A lump that strikes while the beam still rings from the one before: with
``identification.detection.onset_past_ringing`` its onset and contact duration read as if it
had struck alone (the dense flows of docs/results/gangue_share.md)."""

from __future__ import annotations

import copy

import pytest
from id_helpers import replay_chunk, stream_chunk

from tail_beam_id.stream.identifier import StreamIdentifier

FIRST = {"material": "coal", "radius_m": 0.07, "drop_height_m": 3.0, "position_m": 1.3}
SECOND = {"material": "sandstone", "radius_m": 0.035, "drop_height_m": 2.0, "position_m": 0.9}
CONTACT_S = 0.3
GAP_S = 0.012  # the second lump 12 ms after the first: its 2.2 kHz mode rings 20-60 noise RMS


def _label_near(params, commands, at_s, rate_hz):
    """The label of the impact at ``at_s`` (s) among a simulated stream's, with an
    accelerometer at ``rate_hz`` fed, the onset read past an earlier pulse's ringing."""
    params = copy.deepcopy(params)
    params["sensors"]["vibration_rate_hz"] = rate_hz
    params["identification"]["detection"]["onset_past_ringing"] = True
    chunk = stream_chunk(params, commands, CONTACT_S + 0.3)
    identifier = StreamIdentifier("statistical", params["identification"], params)
    labels = replay_chunk(identifier, chunk)
    near = [lab for lab in labels if abs(lab.impact_stamp_s - at_s) < 0.005]
    assert len(near) == 1, [lab.impact_stamp_s for lab in labels]
    return near[0]


@pytest.mark.parametrize("rate_hz", [25600.0, 51200.0])
def test_a_lump_in_the_ringing_of_the_one_before_reads_its_own_onset_and_duration(
    params, rate_hz
):
    """A 35 mm sandstone 12 ms after a 70 mm coal lump, with config/'s 25.6 kHz accelerometer
    and one twice as fast (the look-back's run then spans twice the samples): its pulse is
    found in the vibration stream, its onset within 0.1 ms of its contact (the ringing's first
    lobe in the 1 ms look-back put it 0.8 ms early), and its contact duration within 25 % of
    what the same lump reads alone (read from that early onset it was 1.3 ms, eleven times too
    long, and the lump was labelled coal)."""
    alone = _label_near(params, [(CONTACT_S, SECOND)], CONTACT_S, rate_hz)
    after = _label_near(
        params, [(CONTACT_S, FIRST), (CONTACT_S + GAP_S, SECOND)], CONTACT_S + GAP_S, rate_hz
    )
    assert "vibration" in after.signals
    assert abs(after.impact_stamp_s - (CONTACT_S + GAP_S)) < 1e-4
    assert after.features["contact_duration_s"] == pytest.approx(
        alone.features["contact_duration_s"], rel=0.25
    )
    assert after.material == alone.material == "gangue"
