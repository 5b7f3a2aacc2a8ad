"""Impact association (tail_beam_id.stream.association): which rebound is an impact's, what
overlaps it, when the camera has said all it will. Expected values follow from the configured
windows."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tail_beam_id.signals.imu_detection import Pulse
from tail_beam_id.stream.association import ImpactAssociation, PendingImpact
from tail_beam_id.stream.config import IdentifierConfig


@pytest.fixture
def book(params) -> ImpactAssociation:
    return ImpactAssociation(IdentifierConfig.from_params(params["identification"]))


def pulse_impact(onset_s: float, channel: str = "vibration") -> PendingImpact:
    pulse = Pulse(
        onset_s=onset_s,
        first_stamp_s=onset_s,
        polarity=1,
        width_s=1e-4,
        peak_sigma=30.0,
        noise_mps2=0.05,
        period_s=1.0 / 25600.0,
        first_index=0,
        last_index=3,
    )
    return PendingImpact(onset_s=onset_s, pulse=pulse, channel=channel)


UP = np.array([0.0, 0.0, 2.0])


def test_a_pulse_takes_the_rebound_within_its_contact_and_no_other(book):
    """A rebound between 1 ms before the onset and max_contact_s after it is the impact's; one
    just outside is not, and a rebound once taken is nobody else's."""
    c = book.config.detection
    impact = pulse_impact(1.0)
    assert book.rebound_window(impact) == pytest.approx(
        (1.0 - c.rebound_early_tolerance_s, 1.0 + c.max_contact_s)
    )
    book.add_rebound(1.0 + c.max_contact_s + 1e-4, UP)
    assert book.matching_rebound(impact) is None
    book.add_rebound(1.0 + c.max_contact_s + 2e-4, UP)  # later still: not the impact's either
    book.rebounds.insert(0, (1.0015, UP))
    assert book.matching_rebound(impact)[0] == 1.0015
    book.take_rebound(impact)
    assert impact.rebound[0] == 1.0015 and book.matching_rebound(pulse_impact(0.9995)) is None


def test_a_slow_cameras_rebound_window_is_wider_by_its_extra_frame(params):
    """A camera stamps a rebound up to a frame after the contact ended. The windows allow for
    rebound_frame_allowance_s; a camera whose frame, as known at the onset, is longer widens the
    rebound window by the difference (a 4 ms frame: 3.5 ms later), one no longer does not."""
    config = IdentifierConfig.from_params(params["identification"])
    c = config.detection
    for period, extra in (
        (None, 0.0),
        (2e-4, 0.0),
        (c.rebound_frame_allowance_s, 0.0),
        (0.004, 0.004 - c.rebound_frame_allowance_s),
    ):
        book = ImpactAssociation(config, lambda stamp_s, period=period: period)
        impact = pulse_impact(1.0)
        assert book.slow_camera_s(1.0) == pytest.approx(extra)
        assert book.rebound_window(impact) == pytest.approx(
            (1.0 - c.rebound_early_tolerance_s, 1.0 + c.max_contact_s + extra)
        )
    book.add_rebound(
        1.0 + c.max_contact_s + 0.003, UP
    )  # a 4 ms camera's: within the widened window
    assert book.matching_rebound(impact) is not None


def test_a_rebound_that_is_no_number_is_counted_and_a_repeat_ignored(book):
    """A rebound with a non-finite stamp or velocity is left out and counted; one not after the
    newest is a repeat."""
    book.add_rebound(math.nan, UP)
    book.add_rebound(1.0, np.array([0.0, math.inf, 1.0]))
    book.add_rebound(1.0, UP)
    book.add_rebound(1.0, UP)  # the same stamp again
    assert book.refused_rebounds == 2 and len(book.rebounds) == 1


def test_overlap_needs_a_confirmed_neighbour_or_a_decided_one(book):
    """An IMU-only neighbour within the window does not make an overlap; one the pressure found,
    or an impact already decided within the window, does; beyond the window nothing does."""
    window_s = book.windows(pulse_impact(1.0))[2]
    assert window_s == pytest.approx(
        min(book.config.overlap_window_s, book.config.vibration_window_s)
    )
    impact = pulse_impact(1.0)
    book.pending = [impact, PendingImpact(onset_s=1.0 + window_s / 2, pulse=None, source="imu")]
    assert not book.overlapping(impact)
    book.pending.append(PendingImpact(onset_s=1.0 + window_s / 2, pulse=None, source="pressure"))
    assert book.overlapping(impact)
    book.pending = [impact]
    book.decided = [1.0 - 1.5 * window_s]
    assert not book.overlapping(impact)
    book.decided = [1.0 - 0.5 * window_s]
    assert book.overlapping(impact)


def test_the_camera_settles_on_a_lone_rebound_or_after_its_timeout(book):
    """Without a neighbour a matching rebound settles the impact at once; without a rebound the
    camera has camera_timeout_s past the window's end, and a later rebound ends the wait early."""
    c = book.config
    impact = pulse_impact(1.0)
    book.pending = [impact]
    end = 1.0 + c.detection.max_contact_s
    assert not book.camera_settled(impact, end + c.camera_timeout_s - 1e-6)
    assert book.camera_settled(impact, end + c.camera_timeout_s)
    book.add_rebound(end + 0.05, UP)  # the next impact's rebound: the camera has passed this one
    assert book.camera_settled(impact, end)
    lone = pulse_impact(2.0)
    book.pending = [lone]
    book.add_rebound(2.001, UP)
    assert book.camera_settled(lone, 2.001)
    assert book.data_horizon_s(lone) == pytest.approx(
        2.0 + c.detection.max_contact_s + c.camera_timeout_s
    )  # the rebound not yet taken
    book.take_rebound(lone)
    assert book.data_horizon_s(lone) == pytest.approx(
        2.0 + c.vibration_window_s
    )  # the data window, later than the rebound


def test_a_late_rebound_goes_to_the_latest_waiting_pulse_and_never_past_another_impact(book):
    """late_rebound_max_s (25 ms): a rebound no window claims, 8 ms after a waiting pulse with no
    rebound, is that pulse's (a 100 Hz camera's lag); not when the latest onset before it is
    another impact's (decided, or a pulse between), not when the pulse already has a rebound,
    not beyond 25 ms, not for an impact the camera detected."""
    a = pulse_impact(1.0)
    book.pending.append(a)
    assert book.late_claimant(1.008) is a
    assert book.late_claimant(1.026) is None  # beyond late_rebound_max_s
    assert book.late_claimant(0.999) is None  # before the onset
    b = pulse_impact(1.005)
    book.pending.append(b)
    assert book.late_claimant(1.008) is b  # the latest onset before the stamp
    book.pending.remove(b)
    book.decided.append(1.004)
    assert book.late_claimant(1.008) is None  # a decided impact lies between
    book.decided.clear()
    book.take_late_rebound(a, 1.008, UP)
    assert a.rebound is not None and a.late_rebound and 1.008 in book.used_rebounds
    assert book.late_claimant(1.012) is None  # it has its rebound now
    camera = PendingImpact(onset_s=2.0, pulse=None, rebound=None, source="rebound")
    book.pending.append(camera)
    assert book.late_claimant(2.008) is None


def test_a_pulse_with_a_rebound_in_its_window_claims_no_later_one(book):
    """A waiting pulse whose own window still holds an unused rebound (0.4 ms after it) does not
    take a rebound 5.6 ms after it late: that one is a second lump's whose pulse went unseen
    (a dense flow), and becomes an impact of its own; the first stays the pulse's."""
    a = pulse_impact(1.0)
    book.pending.append(a)
    book.add_rebound(1.0004, UP)
    book.add_rebound(1.0056, UP)
    assert not book.claimable(1.0056)
    assert book.late_claimant(1.0056) is None
    assert book.matching_rebound(a)[0] == pytest.approx(1.0004)


def test_late_rebounds_can_be_switched_off(params):
    """late_rebound_max_s: 0 turns the rule off (the rebound is then an impact of its own, as
    before)."""
    import copy

    section = copy.deepcopy(params["identification"])
    section["detection"]["late_rebound_max_s"] = 0.0
    book = ImpactAssociation(IdentifierConfig.from_params(section))
    book.pending.append(pulse_impact(1.0))
    assert book.late_claimant(1.008) is None


def mode_book(params, periods: float = 1.5) -> ImpactAssociation:
    import copy

    section = copy.deepcopy(params["identification"])
    section["vibration_window_mode_periods"] = periods
    return ImpactAssociation(IdentifierConfig.from_params(section))


def test_a_slow_bending_mode_lengthens_the_accelerometers_window_to_its_periods(params):
    """An accelerometer-found impact's data window holds vibration_window_mode_periods periods
    of the slowest mode the profile measured: 1.5 / 150 Hz = 10 ms; the velocity step's end and
    the overlap window are what they are in a window that long (at most impulse_post_s,
    overlap_window_s); an IMU-found impact keeps window_s."""
    section = params["identification"]
    book = mode_book(params)
    book.follow_profile({"ringing_modes_hz": [900.0, 150.0]})
    window, post, overlap = book.windows(pulse_impact(1.0))
    assert window == pytest.approx(0.01)
    assert post == pytest.approx(min(section["impulse_post_s"], 0.01))
    assert overlap == pytest.approx(min(section["overlap_window_s"], 0.01))
    assert book.windows(pulse_impact(1.0, channel="imu"))[0] == section["window_s"]


def test_the_accelerometers_window_stays_short_on_fast_modes_and_never_passes_window_s(params):
    """Modes fast enough that vibration_window_s holds 1.5 periods (700 Hz: 2.1 ms), no measured
    mode, or the rule off (0) keep vibration_window_s; a mode so slow that 1.5 periods pass
    window_s (80 Hz: 19 ms) gives window_s."""
    section = params["identification"]
    short = section["vibration_window_s"]
    for profile, periods, expected in (
        ({"ringing_modes_hz": [700.0]}, 1.5, short),
        ({}, 1.5, short),
        ({"ringing_modes_hz": [150.0]}, 0.0, short),
        ({"ringing_modes_hz": [80.0]}, 1.5, section["window_s"]),
    ):
        book = mode_book(params, periods)
        book.follow_profile(profile)
        assert book.windows(pulse_impact(1.0))[0] == pytest.approx(expected), profile
