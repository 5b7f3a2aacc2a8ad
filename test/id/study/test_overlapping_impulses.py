"""Two lumps striking the simulated support a few milliseconds apart, identified from the
streams as a dense flow's are: each label's moment impulses, the jack pressure's and the
accelerometer's velocity step's, are its own lump's (each fit reads the neighbour's impulse
with it), where a fit of one impulse reads a mixture of both."""

from __future__ import annotations

import pytest
from id_helpers import replay_chunk

from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.study.dataset import evaluation_params, study_simulator

LUMPS = (
    {"material": "sandstone", "radius_m": 0.05, "drop_height_m": 2.0, "position_m": 1.1},
    {"material": "coal", "radius_m": 0.06, "drop_height_m": 2.5, "position_m": 0.7},
)


def read_moments(
    params, gap_s: float, neighbour_fit: bool, lumps=LUMPS, fit: str = "neighbour_fit"
) -> tuple[list, list, list]:
    """(true moment impulses, labels' pressure moment impulses (N m s), labels' features) of the
    two lumps ``gap_s`` apart, in stamp order, with the ``fit``'s neighbour columns on or off."""
    varied = dict(params)
    varied["sensors"] = {**varied["sensors"], "seed": 3}
    simulator = study_simulator(varied, evaluation_params(params)["tier"], len(lumps))
    for n, lump in enumerate(lumps):
        simulator.submit(lump, contact_stamp_s=0.3 + n * gap_s)
    chunk = simulator.advance(0.6)
    section = {**varied["identification"], fit: neighbour_fit}
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


# A smaller lump first: the larger one's pulse stands out of its ringing, so both labels carry
# the accelerometer's velocity step.
PULSED_LUMPS = (
    {"material": "coal", "radius_m": 0.04, "drop_height_m": 2.0, "position_m": 1.1},
    {"material": "sandstone", "radius_m": 0.05, "drop_height_m": 2.5, "position_m": 0.7},
)


@pytest.mark.parametrize("gap_s", [0.003, 0.008, 0.012])
def test_each_overlapping_lump_reads_its_own_velocity_step(params, gap_s):
    """Lumps 3, 8 and 12 ms apart, both found on the accelerometer: each label's moment
    impulse from the velocity step is its own lump's within 10 % (the beam takes the lump's
    momentum change m (v_in + v_out) at x, and the responses add), the earlier lump's kick
    being its own column of the fit; with the background fitted across that kick
    (``impulse_neighbour_fit`` off) one of them reads more than 25 % off (here 60-140 %)."""
    moments = {}
    for on in (True, False):
        true, _, features = read_moments(
            params, gap_s, on, PULSED_LUMPS, "impulse_neighbour_fit"
        )
        assert len(features) == 2
        moments[on] = [f["moment_impulse_imu_nms"] for f in features]
    assert moments[True] == pytest.approx(true, rel=0.1)
    assert max(abs(m / t - 1.0) for m, t in zip(moments[False], true)) > 0.25


def test_the_velocity_steps_window_takes_in_the_impacts_that_reach_it(params):
    """impulse_neighbours: no other onset within the lone background's reach (50 ms and the
    5 ms after an earlier onset) or the data window, the lone read-out; one there, a joint fit
    reaching impulse_pre_s before the earliest, never beyond impulse_background_s; one closer
    than impulse_skip_s is read with the impact's; later ones within the window count too;
    off, never joint."""
    from tail_beam_id.stream.config import IdentifierConfig
    from tail_beam_id.stream.decision import impulse_neighbours

    section = params["identification"]
    cfg = IdentifierConfig.from_params(section)
    pre, post, least = 0.01, 0.006, cfg.impulse_pre_s
    assert impulse_neighbours(1.0, [0.9, 1.2], pre, post, cfg) == ([], pre)
    among, reach = impulse_neighbours(1.0, [0.988], pre, post, cfg)
    assert among == [0.988] and reach == pytest.approx(0.012 + least)
    among, reach = impulse_neighbours(1.0, [0.97], pre, post, cfg)
    assert among == [0.97] and reach == pytest.approx(0.03 + least)
    among, reach = impulse_neighbours(1.0, [0.947], pre, post, cfg)
    assert among == [0.947] and reach == pytest.approx(cfg.impulse_background_s)
    among, reach = impulse_neighbours(1.0, [0.975, 0.985, 0.99], pre, post, cfg)
    assert among == [0.975, 0.985, 0.99] and reach == pytest.approx(0.025 + least)
    capped = IdentifierConfig.from_params({**section, "impulse_background_s": 0.02})
    among, reach = impulse_neighbours(1.0, [0.975, 0.985, 0.99], pre, post, capped)
    assert among == [0.985, 0.99] and reach == pytest.approx(0.02)
    assert impulse_neighbours(1.0, [1.0005], pre, post, cfg) == ([], pre)
    assert impulse_neighbours(1.0, [1.004], pre, post, cfg) == ([1.004], pre)
    off = IdentifierConfig.from_params({**section, "impulse_neighbour_fit": False})
    assert impulse_neighbours(1.0, [0.995], pre, post, off) == ([], pre)


def test_a_sample_that_is_no_number_leaves_the_joint_step_unread(params):
    """A non-finite sample inside the joint fit's window: no velocity step (None, the models
    then decide without it), never a traceback or a NaN read as a moment."""
    import numpy as np

    from tail_beam_id.signals.features import BeamModel, imu_impulse
    from tail_beam_id.signals.imu_detection import Pulse

    model = BeamModel.from_params(params)
    period = 1.0 / 25600.0
    stamps = np.arange(0.0, 0.2, period)
    accel = np.random.default_rng(1).normal(9.81, 0.3, stamps.size)
    pulse = Pulse(0.1, 0.1, 1, period, 10.0, 0.1, period, 0, 0)
    clean = imu_impulse(model, stamps, accel, pulse, 0.02, 0.0015, 0.006, False, (0.095,))
    assert clean is not None and np.isfinite(clean.velocity_mps)
    accel[np.searchsorted(stamps, 0.097)] = np.nan
    assert imu_impulse(model, stamps, accel, pulse, 0.02, 0.0015, 0.006, False, (0.095,)) is None
