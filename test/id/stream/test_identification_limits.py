"""Where identification must fail: two particles of different class whose signals agree
within the sensors' noise at the shipped sensor rates (the evidence behind the accuracy that
small particles can reach), and the single-feature threshold on the stream scene."""

from __future__ import annotations

import pytest
from id_helpers import impact


def test_coal_and_mudstone_twins_differ_only_in_contact_duration(params):
    # A 25 mm mudstone sphere and a 30.3 mm coal sphere, same drop, point and restitution:
    # the same moment impulse about the hinge (what the jack and the rigid beam feel) and the
    # same rebound speed, to within the nominal noise (camera 0.05 m/s + 2 %); only the contact
    # lasts about 0.1 ms longer for the coal, less than one 2 kHz IMU period (0.5 ms) or one
    # 5 kHz camera frame (0.2 ms) can resolve. At the shipped rates no method can tell them
    # apart; at 20 kHz the duration is resolved (evaluation: the `fast` setting).
    """A coal and a mudstone sphere can share moment impulse, rebound speed and peak pressure
    within noise, differing only by a contact 60-200 us longer."""
    fields = {"drop_height_m": 3.0, "position_m": 1.0, "restitution": 0.35}
    mud = impact(
        params, tier="rigid", noise=0.0, material="mudstone", radius_m=0.025, **fields
    ).summary
    coal = impact(
        params, tier="rigid", noise=0.0, material="coal", radius_m=0.0303, **fields
    ).summary

    def moment(s):
        return s["mass_kg"] * (s["impact_speed_mps"] + s["rebound_speed_mps"]) * s["position_m"]

    assert moment(coal) == pytest.approx(moment(mud), rel=0.03)
    camera_noise = 0.05 + 0.02 * mud["rebound_speed_mps"]
    assert abs(coal["rebound_speed_mps"] - mud["rebound_speed_mps"]) < camera_noise
    assert coal["peak_jack_pressure_change_pa"] == pytest.approx(
        mud["peak_jack_pressure_change_pa"], rel=0.05
    )
    difference = coal["contact_duration_s"] - mud["contact_duration_s"]
    assert 60e-6 < difference < 0.2e-3


def test_threshold_holds_on_the_paper_scene_and_breaks_on_the_stream(params):
    # The study's idea, one rebound-speed threshold tuned on the study's scene, separates its
    # 25 mm spheres; on the stream scene size, height and restitution confound it, while the
    # classifier that sees the moment impulse and the contact duration as well does better.
    # Seeds 9001/9002: neither training (7, 8) nor evaluation (41001-41003) uses them.
    """The study's rebound threshold is 90 % right on its own scene, at most 80 % on the stream
    scene, where the statistical method beats it by 10 points."""
    from tail_beam_id.study.dataset import settings
    from tail_beam_id.study.runs import run_set

    nominal = settings(params, [1.0], ["nominal"])

    def accuracy(records, method):
        chosen = [r for r in records if r.method == method]
        return sum(r.correct for r in chosen) / len(chosen)

    paper = list(run_set(params, "paper", 12, 9001, nominal, ["threshold"]))
    stream = list(run_set(params, "stream", 30, 9002, nominal, ["threshold", "statistical"]))
    assert accuracy(paper, "threshold") >= 0.9
    assert accuracy(stream, "threshold") <= 0.8
    assert accuracy(stream, "statistical") >= accuracy(stream, "threshold") + 0.1
