"""id_node's self-calibration online (tail_beam_id/calibration/online), driven without ROS as
the node drives it: labels say calibrated: false until the learned window is over, then true,
and the support it measured is the one that recorded the stream."""

from __future__ import annotations

import numpy as np
import pytest

from tail_beam_id.calibration.online import OnlineCalibration
from tail_beam_id.ros.arrival import GateConfig, GatedIdentifier
from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.study.dataset import support_streams
from tail_beam_sim.physics.fidelity import TIERS, FidelitySettings, structure_for
from tail_beam_sim.physics.materials import material_table
from tail_beam_sim.physics.sensors import VibrationBlocks
from tail_beam_sim.physics.support import Support

LEARN_S = 3.0
CONFIG = GateConfig(reorder_s=0.0, stream_idle_s=0.5, time_jump_s=1.0)


@pytest.fixture(scope="module")
def recorded(params):
    """One drawn foreign support (its sway a third above the nominal 39 Hz) recorded as a
    continuous stream of 14 impacts (about 6 s)."""
    return next(support_streams(params, 1, 14, seed=4249))


def run(params, recorded, calibration) -> tuple[list[dict], GatedIdentifier]:
    """Feed the stream in 20 ms ticks of stamp time, in real time, as id_node's timer does."""
    gated = GatedIdentifier(
        lambda trained: StreamIdentifier(
            "statistical", params["identification"], params, prebuilt=trained
        ),
        CONFIG,
        calibration,
    )
    p, i = recorded.pressure, recorded.imu
    labels: list[dict] = []
    edges = np.arange(0.0, p.stamp_s[-1] + 0.04, 0.02)
    for lo, hi in zip(edges[:-1], edges[1:]):
        take_p = (p.stamp_s >= lo) & (p.stamp_s < hi)
        take_i = (i.stamp_s >= lo) & (i.stamp_s < hi)
        arrivals = {
            "jack_pressure": (p.stamp_s[take_p], p.pressure_pa[take_p].reshape(-1, 1)),
            "imu": (
                i.stamp_s[take_i],
                np.hstack([i.angular_velocity_radps, i.linear_acceleration_mps2])[take_i],
            ),
        }
        rebounds = [(r.stamp_s, r.velocity_mps) for r in recorded.rebounds if lo <= r.stamp_s < hi]
        labels += gated.tick(hi, arrivals, VibrationBlocks.empty(), rebounds)
    labels += gated.tick(edges[-1] + 2.0, {}, VibrationBlocks.empty(), [], end_of_data=True)
    return labels, gated


@pytest.fixture(scope="module")
def calibrated_run(params, recorded):
    """The stream through a gated identifier calibrating on its first LEARN_S (synchronously)."""
    return run(
        params, recorded, OnlineCalibration(params, LEARN_S, "statistical", background=False)
    )


def test_labels_say_calibrated_once_the_learned_support_is_in_use(
    params, recorded, calibrated_run
):
    """Labels before the end of the learned window say calibrated: false, after it true; the
    log line names the sway frequency it measured, which is the recording support's lowest
    natural frequency within 2 % (not the nominal support's)."""
    labels, gated = calibrated_run
    flags = [label.calibrated for label in labels]
    assert flags[0] is False and flags[-1] is True and flags == sorted(flags)
    assert all(not lab.calibrated for lab in labels if lab.impact_stamp_s < LEARN_S)
    support = Support.from_params(recorded.params["support"], material_table(recorded.params))
    truth = structure_for(
        TIERS["modal"], support, FidelitySettings.from_params(recorded.params).modes
    ).natural_frequencies_hz()[0]
    nominal = structure_for(
        TIERS["modal"],
        Support.from_params(params["support"], material_table(params)),
        FidelitySettings.from_params(params).modes,
    ).natural_frequencies_hz()[0]
    found = gated.calibration.result.profile.rigid_mode_frequency_hz
    assert found == pytest.approx(truth, rel=0.02) and abs(found - nominal) > 0.05 * nominal
    assert any(f"sway {found:.2f} Hz" in note for note in gated.notes)


def test_without_online_calibration_nothing_changes(params, recorded):
    """No calibration asked: every label says calibrated: false, and the labels are those of the
    same run whose calibration is still learning (the window longer than the stream)."""
    plain, _ = run(params, recorded, None)
    learning, gated = run(
        params, recorded, OnlineCalibration(params, 60.0, "statistical", background=False)
    )
    assert not any(lab.calibrated for lab in plain)
    assert [lab.decision() for lab in plain] == [lab.decision() for lab in learning]
    assert gated.calibration.state == "learning"


def test_the_worker_thread_gives_the_same_profile(params, recorded, calibrated_run):
    """The node's background calibration finds the same profile as the synchronous one."""
    import time

    background = OnlineCalibration(params, LEARN_S, "statistical", background=True)
    _, gated = run(params, recorded, background)
    deadline = time.monotonic() + 60.0
    while gated.calibration.result is None and time.monotonic() < deadline:
        gated.tick(1e3, {}, VibrationBlocks.empty(), [])
        time.sleep(0.05)
    assert gated.calibration.result.profile == calibrated_run[1].calibration.result.profile


def test_online_calibration_hands_the_supports_hysteresis_to_the_method(
    params, recorded, calibrated_run
):
    """The hysteresis a learned window reads reaches the identifier's statistical method with the
    rest of the profile, the log says it, and the three-signal labels after the window say how
    far it moved them, none before it; a window with fewer impacts than it needs (3 s: 7 of
    the 8 of identification.statistical.hysteresis.min_impacts) leaves it out and says so."""
    _, short = calibrated_run
    assert short.calibration.result.profile.hysteresis_weights is None
    assert any("hysteresis not read (7 impacts" in note for note in short.notes)
    labels, gated = run(
        params, recorded, OnlineCalibration(params, 5.0, "statistical", background=False)
    )
    profile = gated.calibration.result.profile
    assert profile.hysteresis_weights is not None and profile.hysteresis_impacts >= 8
    assert gated.identifier.method.hysteresis_weights == profile.hysteresis_weights
    assert any("hysteresis u in" in note for note in gated.notes)
    after = [
        lab
        for lab in labels
        if lab.calibrated and set(lab.signals) == {"jack_pressure", "imu", "rebound_velocity"}
    ]
    assert after and all("hysteresis_shift" in lab.features for lab in after)
    assert not any("hysteresis_shift" in lab.features for lab in labels if not lab.calibrated)
