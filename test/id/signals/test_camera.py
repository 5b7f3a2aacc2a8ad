"""The camera's frame period read from its rebound stamps (tail_beam_id.signals.camera), and what
the statistical method does with a camera slower than its training's."""

from __future__ import annotations

import copy
import types

import numpy as np
import pytest
from id_helpers import stream_chunk

from tail_beam_id.signals.camera import (
    GRIDLESS_PERIOD_S,
    MIN_REBOUNDS,
    FramePeriod,
    frame_period_s,
)
from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.replay import replay


def _grid_stamps(rate_hz: float, count: int, seed: int = 1, phase_s: float = 0.0) -> np.ndarray:
    """Rebound stamps of a camera at ``rate_hz`` whose frames lie at phase + k / rate: each the
    first frame after a separation 0.3-0.45 s after the one before (as a stream's), rounded to
    the nanosecond as a bag stores them."""
    separations = 0.5 + np.cumsum(0.3 + 0.15 * np.random.default_rng(seed).uniform(size=count))
    stamps = phase_s + np.ceil((separations - phase_s) * rate_hz) / rate_hz
    return np.round(stamps * 1e9) / 1e9


@pytest.mark.parametrize(
    "rate_hz", [500.0, 1000.0, 2000.0, 3000.0, 5000.0, 7777.0, 25600.0, 50000.0]
)
def test_the_frame_period_is_read_from_the_stamps_grid(rate_hz):
    """Every difference of grid stamps is a whole number of frames; the longest period that fits
    them all is the camera's, whatever the grid's phase and even when 1/rate is no whole ns."""
    stamps = _grid_stamps(rate_hz, 12, phase_s=0.000123)
    assert frame_period_s(stamps) == pytest.approx(1.0 / rate_hz, rel=1e-6)


def test_stamps_off_any_grid_give_no_period():
    """Stamps with 10 us of jitter (a camera stamped by its host's clock), or the exact moments
    of separation, lie on no frame grid of 20 us or more: no period, not a wrong one."""
    rng = np.random.default_rng(3)
    separations = 0.5 + np.cumsum(0.3 + 0.15 * rng.uniform(size=20))
    assert frame_period_s(separations) is None
    assert frame_period_s(_grid_stamps(5000.0, 20) + rng.normal(0.0, 1e-5, 20)) is None


def test_a_regular_schedule_seen_by_a_slow_camera_gives_a_multiple_never_less():
    """Contacts every 0.35 s exactly, each ending 0.1-0.9 ms after it starts, all end within the
    same frame of a 1 kHz camera: the stamps fit every divisor of 10 ms, so they cannot say the
    frame (1 ms). The estimate errs long (2 ms: decisions less sure), never short."""
    contacts = 0.3 + 0.35 * np.arange(12)
    separations = contacts + np.random.default_rng(4).uniform(1e-4, 9e-4, 12)
    assert frame_period_s(np.ceil(separations * 1000.0) / 1000.0) == pytest.approx(2e-3, rel=1e-6)
    # The 5 kHz camera of the same impacts: the contacts end in several of its frames, so the
    # grid shows; the regular schedule leaves it known to within 1 % (a period 1750 frames long
    # fits 1748 slightly longer ones to within the tolerance).
    assert frame_period_s(np.ceil(separations * 5000.0) / 5000.0) == pytest.approx(2e-4, rel=1e-2)


@pytest.mark.parametrize("seed", range(20))
def test_from_the_fewest_stamps_the_estimate_is_never_shorter_than_the_frame(seed):
    """From MIN_REBOUNDS stamps of a face's stream the estimate is the frame or longer (a
    multiple, or by chance another period that fits so few differences), never shorter."""
    for rate_hz in (1000.0, 2000.0, 5000.0):
        estimate = frame_period_s(_grid_stamps(rate_hz, MIN_REBOUNDS, seed=seed))
        assert estimate is not None and estimate >= 1.0 / rate_hz * (1 - 1e-6), (rate_hz, estimate)


def test_stamps_at_the_separation_itself_read_as_a_camera_without_lag():
    """A camera that stamps each rebound at the separation itself (a simulator's, or one that
    interpolates between its frames) lies on no grid. The fewest stamps fit some short frame by
    chance (3 differences, thousands of candidate frames of 20 us and more, each fitting within
    1 us); two stamps more leave none, and the frame is GRIDLESS_PERIOD_S, so its delays read
    as the contacts' durations. The configured frame holds before MIN_REBOUNDS stamps, and no
    estimate on the way is longer than it. Self-calibration reads the same from the whole
    recording (1 / GRIDLESS_PERIOD_S frames/s) and says so; a grid camera still gives its
    frame."""
    from tail_beam_id.calibration.offline import SupportProfile, _camera_frame_rate_hz

    for seed in range(6):
        separations = 0.5 + np.cumsum(0.3 + 0.15 * np.random.default_rng(seed).uniform(size=12))
        stamps = np.round(separations * 1e9) / 1e9  # the ns a bag keeps
        camera = FramePeriod(configured_s=2e-4)
        for stamp in stamps:
            camera.add(float(stamp))
        periods = [camera.period_at(float(t)) for t in stamps]
        assert periods[: MIN_REBOUNDS - 1] == pytest.approx([2e-4] * (MIN_REBOUNDS - 1))
        assert all(p <= 2e-4 for p in periods), periods
        assert periods[MIN_REBOUNDS + 1 :] == [GRIDLESS_PERIOD_S] * (12 - MIN_REBOUNDS - 1)
        assert camera.measured_at(float(stamps[-1])) == GRIDLESS_PERIOD_S
        assert _camera_frame_rate_hz(stamps) == pytest.approx(1.0 / GRIDLESS_PERIOD_S)
    assert _camera_frame_rate_hz(stamps[: MIN_REBOUNDS - 1]) is None
    assert _camera_frame_rate_hz(_grid_stamps(5000.0, 12)) == pytest.approx(5000.0, rel=1e-6)
    said = SupportProfile.describe_camera(
        types.SimpleNamespace(camera_frame_rate_hz=1.0 / GRIDLESS_PERIOD_S)
    )
    assert "no frame grid" in said


def test_a_configured_camera_slower_than_the_stamps_can_tell_is_believed_while_they_agree():
    """Stamps of a 250 Hz camera lie on a 2 ms grid too, the slowest read from stamps; configured
    as 250 Hz, its 4 ms frame is used while every stamp lies on that grid, and the stamps' own
    estimate from the first one that does not. A configured frame shorter than the stamps' never
    wins (the shipped 5 kHz against a slower camera)."""
    rng = np.random.default_rng(3)
    stamps = np.cumsum(rng.integers(50, 120, 8)) * 0.004
    slow = FramePeriod(0.004)
    for t in stamps:
        slow.add(float(t))
    assert frame_period_s(stamps) == pytest.approx(0.002)
    assert slow.period_at(float(stamps[-1])) == pytest.approx(0.004)
    slow.add(float(stamps[-1] + 0.006))  # a stamp off the 4 ms grid, on the 2 ms one
    assert slow.period_at(float(stamps[-1] + 0.006)) == pytest.approx(0.002)
    assert slow.period_at(float(stamps[-1])) == pytest.approx(
        0.004
    )  # earlier decisions keep theirs
    shipped = FramePeriod(1 / 5000.0)
    for t in stamps:
        shipped.add(float(t))
    assert shipped.period_at(float(stamps[-1])) == pytest.approx(0.002)


def test_too_few_stamps_give_no_period():
    """Fewer stamps than MIN_REBOUNDS give no estimate."""
    assert frame_period_s(_grid_stamps(2000.0, MIN_REBOUNDS - 1)) is None


def test_a_decision_uses_only_the_stamps_up_to_its_rebound():
    """Before MIN_REBOUNDS stamps the configured period holds, after them the measured one; the
    period an earlier rebound is decided with does not change when later rebounds come (live
    and offline decisions agree however the rebounds arrive)."""
    stamps = _grid_stamps(1000.0, 10)
    camera = FramePeriod(configured_s=1.0 / 5000.0)
    for stamp in stamps:
        camera.add(float(stamp))
    assert camera.period_at(stamps[MIN_REBOUNDS - 2]) == pytest.approx(2e-4)
    assert camera.period_at(stamps[MIN_REBOUNDS - 1]) == pytest.approx(1e-3, rel=1e-6)
    assert camera.period_at(stamps[-1]) == pytest.approx(1e-3, rel=1e-6)
    assert FramePeriod(None).period_at(1.0) is None


@pytest.fixture(scope="module")
def slow_camera_stream(params):
    """Ten impacts of 25-90 mm coal and mudstone 0.3-0.45 s apart on the nominal support, its
    camera at 1 kHz (lagging the contact's end by up to 1 ms, five times the shipped camera's
    frame)."""
    varied = copy.deepcopy(params)
    varied["sensors"]["camera_frame_rate_hz"] = 1000.0
    radii = np.geomspace(0.025, 0.09, 10)
    starts = 0.3 + np.cumsum(
        0.3 + 0.15 * np.random.default_rng(7).uniform(size=10)
    )  # as a face: 0.3-0.45 s apart
    commands = [
        (
            float(starts[k]),
            {
                "material": "coal" if k % 2 else "mudstone",
                "radius_m": float(r),
                "drop_height_m": 3.0,
                "position_m": 1.0,
            },
        )
        for k, r in enumerate(radii)
    ]
    return stream_chunk(varied, commands, float(starts[-1]) + 0.1)


def test_a_slow_camera_is_recognised_and_its_lag_averaged_over(params, slow_camera_stream):
    """Identified with the shipped config/ (a 5 kHz camera), the labels say 200 us for the first
    rebounds, then the camera's 1 ms read from the stamps (or, from the fewest, a period longer
    still). A camera between the training's reference (5 kHz) and its slowest (2 kHz), here
    2.5 kHz, is averaged over the lag it may add: the delays read shorter contacts, and a
    shorter contact is a stiffer particle, so P(coal) falls on average against the decision that
    takes the whole delay for contact (among those the training envelope does not cap: a delay
    longer than any trained is capped taken whole, and the cap, not the lag, sets it), and no
    decision leaves the range of the lags' own."""
    chunk = slow_camera_stream
    labels = replay(
        StreamIdentifier("statistical", params["identification"], params),
        chunk.pressure,
        chunk.imu,
        [r for _, r in chunk.rebounds],
        vibration=chunk.vibration,
    )
    assert len(labels) == 10
    periods = [label.features["camera_frame_period_s"] for label in labels]
    assert periods[: MIN_REBOUNDS - 1] == pytest.approx([2e-4] * (MIN_REBOUNDS - 1))
    assert all(period >= 1e-3 * (1 - 1e-6) for period in periods[MIN_REBOUNDS - 1 :]), (
        periods
    )  # erring long at first
    assert periods[-1] == pytest.approx(1e-3, rel=1e-6)
    method = StreamIdentifier("statistical", params["identification"], params).method
    shifts = []
    for label in labels:
        taken_whole = method.decide({**label.features, "camera_frame_period_s": 2e-4})
        unaware = taken_whole.p_coal
        averaged = method.decide({**label.features, "camera_frame_period_s": 4e-4}).p_coal
        lags = [
            method.decide(
                {
                    **label.features,
                    "camera_frame_period_s": 2e-4,
                    "rebound_delay_s": label.features["rebound_delay_s"] + shift,
                }
            ).p_coal
            for shift in np.linspace(1e-4, -3e-4, 33)
        ]
        assert min(lags) - 1e-6 <= averaged <= max(lags) + 1e-6
        if not taken_whole.outside_training:
            shifts.append(averaged - unaware)
    assert len(shifts) >= 6 and np.mean(shifts) < 0.0, shifts


def test_a_camera_slower_than_any_trained_is_decided_without_the_delay(params, slow_camera_stream):
    """A 1 kHz camera lags by up to 1 ms, more than the contact durations the delay tells apart:
    its impacts are decided by the models trained without the delay, so moving the rebound stamp
    anywhere within the frame changes nothing, and no timing check is made of a delay that
    cannot show a clock offset. (Averaged over the lag instead, a 1 kHz camera's foreign supports
    scored 76 and 74 % on the stream and the paper scene, against 83 and 94 % this way.)"""
    chunk = slow_camera_stream
    labels = replay(
        StreamIdentifier("statistical", params["identification"], params),
        chunk.pressure,
        chunk.imu,
        [r for _, r in chunk.rebounds],
        vibration=chunk.vibration,
    )
    method = StreamIdentifier("statistical", params["identification"], params).method
    decided = [label for label in labels if label.features["camera_frame_period_s"] > 5e-4]
    assert len(decided) >= 10 - MIN_REBOUNDS + 1
    for label in decided:
        assert "delay_residual" not in label.features
        base = method.decide(label.features).p_coal
        for shift in (-4e-4, -1e-4, 3e-4, 9e-4):
            moved = {
                **label.features,
                "rebound_delay_s": label.features["rebound_delay_s"] + shift,
            }
            assert method.decide(moved).p_coal == base
        # The same features with a camera the training knew: the delay counts again.
        assert (
            method.decide(
                {**label.features, "camera_frame_period_s": 2e-4, "rebound_delay_s": 4e-4}
            ).p_coal
            != method.decide(
                {**label.features, "camera_frame_period_s": 2e-4, "rebound_delay_s": 9e-4}
            ).p_coal
        )
    first = len(labels) - len(decided)  # the impacts before the camera's period was read
    assert [label.material for label in decided] == [
        "gangue" if k % 2 == 0 else "coal" for k in range(first, 10)
    ]


def test_a_camera_as_fast_as_the_training_changes_nothing(params, slow_camera_stream):
    """At or below the reference frame (5 kHz) the delay is taken as it is: the decision equals
    the one without the camera's period."""
    features = replay(
        StreamIdentifier("statistical", params["identification"], params),
        slow_camera_stream.pressure,
        slow_camera_stream.imu,
        [r for _, r in slow_camera_stream.rebounds],
        vibration=slow_camera_stream.vibration,
    )[0].features
    method = StreamIdentifier("statistical", params["identification"], params).method
    bare = {k: v for k, v in features.items() if k != "camera_frame_period_s"}
    for period_s in (5e-5, 2e-4):
        assert (
            method.decide({**bare, "camera_frame_period_s": period_s}).p_coal
            == method.decide(bare).p_coal
        )
    assert (
        method.decide({**bare, "camera_frame_period_s": 1e-3}).p_coal != method.decide(bare).p_coal
    )


def test_with_an_imu_too_slow_to_read_the_contact_a_slow_cameras_delay_is_averaged_over_its_lag(
    params, slow_camera_stream
):
    """The same 1 kHz camera beside a 2 kHz IMU alone: the contact's duration is not read from
    the pulse (it says the sample period), so the delay is all the impact says of it, and the
    decision is averaged over the lags the camera may have added rather than made without the
    delay. Moving the stamp within the frame moves the decision; each average lies within the
    decisions at the lags it averages, which never exceed the delay itself (a longer lag would
    leave a contact of no duration); and no timing check is made of a delay that cannot show a
    clock offset."""
    chunk = slow_camera_stream
    labels = replay(
        StreamIdentifier("statistical", params["identification"], params),
        chunk.pressure,
        chunk.imu,
        [r for _, r in chunk.rebounds],
        vibration=None,
    )
    method = StreamIdentifier("statistical", params["identification"], params).method
    decided = [label for label in labels if label.features["camera_frame_period_s"] > 5e-4]
    assert len(decided) >= 10 - MIN_REBOUNDS + 1
    for label in decided:
        features = label.features
        assert (
            features["contact_duration_s"] == features["imu_period_s"]
        )  # not read from the pulse
        assert "delay_residual" not in features
        delay = features["rebound_delay_s"]
        averaged = method.decide(features).p_coal
        # The training's 5 kHz camera lagged 0.1 ms on average: a lag u reads as delay - u + 0.1
        # ms.
        at_lags = [
            method.decide(
                {**features, "camera_frame_period_s": 2e-4, "rebound_delay_s": delay - u + 1e-4}
            ).p_coal
            for u in np.linspace(0.0, min(delay, 1e-3), 33)
        ]
        assert min(at_lags) - 1e-6 <= averaged <= max(at_lags) + 1e-6
    moved = [
        method.decide(
            {**label.features, "rebound_delay_s": label.features["rebound_delay_s"] + 4e-4}
        ).p_coal
        != method.decide(label.features).p_coal
        for label in decided
    ]
    assert all(moved)


def test_only_a_frame_measured_well_under_the_readable_limit_proves_a_fast_camera():
    """may_be_slower: a camera slower than MAX_PERIOD_S (2 ms) has stamps that fit a frame between
    1 and 2 ms (240 Hz: 4.17 ms / 3 = 1.39 ms; 100 Hz: 10 ms / 5 = 2 ms), so only an estimate of
    1 ms or less, or none being unknown, decides; and the estimates are what frame_period_s
    reads."""
    from tail_beam_id.signals.camera import may_be_slower

    assert may_be_slower(None) and may_be_slower(2e-3) and may_be_slower(1.39e-3)
    assert not may_be_slower(2e-4) and not may_be_slower(1e-3)
    for rate_hz, read_s in ((240.0, 1.0 / 720.0), (100.0, 2e-3), (5000.0, 2e-4)):
        stamps = np.cumsum(np.random.default_rng(3).integers(30, 90, size=12)) / rate_hz
        assert frame_period_s(stamps) == pytest.approx(read_s, rel=1e-6)
        assert may_be_slower(frame_period_s(stamps)) == (rate_hz < 1000.0)
