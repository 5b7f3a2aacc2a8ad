"""A high-rate tail-beam accelerometer (StreamIdentifier.add_vibration): while it is fed it is
the acceleration channel for pulse detection and the IMU impulse; without it nothing changes."""

from __future__ import annotations

import numpy as np
import pytest
from id_helpers import impact

from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.replay import replay

VIBRATION_RATE_HZ = 20000.0
DECIMATION = 10  # the IMU at 2 kHz: the mean of every 10 vibration samples


@pytest.fixture(scope="module")
def fast_impact(params):
    """One 40 mm sandstone impact with the accelerometer sampled at 20 kHz."""
    return impact(
        params,
        material="sandstone",
        radius_m=0.04,
        seed=21,
        sensors={"imu_rate_hz": VIBRATION_RATE_HZ},
    )


def _slow_imu(imu):
    """The 20 kHz IMU averaged over blocks of DECIMATION samples, stamped at each block's end:
    what a 2 kHz IMU reporting the mean specific force over its period gives."""
    n = imu.stamp_s.size // DECIMATION * DECIMATION
    stamps = imu.stamp_s[DECIMATION - 1 : n : DECIMATION]
    gyro = imu.angular_velocity_radps[:n].reshape(-1, DECIMATION, 3).mean(axis=1)
    accel = imu.linear_acceleration_mps2[:n].reshape(-1, DECIMATION, 3).mean(axis=1)
    return stamps, gyro, accel


def _feed(identifier, result, slow, vibration_until_s=np.inf, chunk_s=0.01):
    """Deliver pressure, the 2 kHz IMU, the vibration stream (up to ``vibration_until_s``) and
    the rebound in chunks of stamp time, polling after each; then flush."""
    stamps, gyro, accel = slow
    vib_t = result.imu.stamp_s
    vib_a = result.imu.linear_acceleration_mps2[:, 2]
    labels = []
    edges = np.arange(0.0, max(stamps[-1], result.pressure.stamp_s[-1]) + 2 * chunk_s, chunk_s)
    rebound_sent = False
    for low, high in zip(edges[:-1], edges[1:]):
        take = (result.pressure.stamp_s >= low) & (result.pressure.stamp_s < high)
        identifier.add_pressure(result.pressure.stamp_s[take], result.pressure.pressure_pa[take])
        take = (stamps >= low) & (stamps < high)
        identifier.add_imu(stamps[take], gyro[take], accel[take])
        take = (vib_t >= low) & (vib_t < high) & (vib_t <= vibration_until_s)
        if take.any():
            identifier.add_vibration(vib_t[take], vib_a[take])
        if not rebound_sent and result.rebound.stamp_s < high:
            identifier.add_rebound(result.rebound.stamp_s, result.rebound.velocity_mps)
            rebound_sent = True
        labels += identifier.poll()
    return labels + identifier.flush()


def test_vibration_stream_is_the_acceleration_channel(params, fast_impact):
    """With the 20 kHz vibration stream fed beside a 2 kHz IMU, the one impact is detected and
    its impulse measured in the vibration stream: signals name it, the pulse period is its."""
    labels = _feed(
        StreamIdentifier("statistical", params["identification"], params),
        fast_impact,
        _slow_imu(fast_impact.imu),
    )
    assert len(labels) == 1
    label = labels[0]
    assert label.signals == ("jack_pressure", "vibration", "rebound_velocity")
    assert label.features["imu_period_s"] == pytest.approx(1.0 / VIBRATION_RATE_HZ, rel=1e-6)
    assert label.material == "gangue"
    # The 20 kHz channel places the onset within one of its periods and a half of the contact.
    assert abs(label.impact_stamp_s - fast_impact.contact_stamp_s) < 1.5 / VIBRATION_RATE_HZ


def test_without_vibration_the_imu_is_the_channel(params, fast_impact):
    """The same streams without the vibration: the IMU's 2 kHz accel z detects the impact and
    the label is the one the plain replay of pressure, IMU and camera gives."""
    slow = _slow_imu(fast_impact.imu)
    labels = _feed(
        StreamIdentifier("statistical", params["identification"], params),
        fast_impact,
        slow,
        vibration_until_s=-1.0,
    )
    assert len(labels) == 1
    assert labels[0].signals == ("jack_pressure", "imu", "rebound_velocity")
    assert labels[0].features["imu_period_s"] == pytest.approx(
        1.0 / (VIBRATION_RATE_HZ / DECIMATION), rel=1e-6
    )
    from tail_beam_sim.physics.sensors import ImuStream

    imu = ImuStream(slow[0], slow[1], slow[2], 0.0, 0.0)
    plain = replay(
        StreamIdentifier("statistical", params["identification"], params),
        fast_impact.pressure,
        imu,
        [fast_impact.rebound],
    )
    assert [(lab.impact_stamp_s, lab.material, lab.confidence) for lab in labels] == [
        (lab.impact_stamp_s, lab.material, lab.confidence) for lab in plain
    ]


def test_vibration_stopping_hands_back_to_the_imu(params, fast_impact):
    """The vibration stream ending well before the impact is declared stopped (it lags the
    others by more than stream_timeout_s); the impact is then detected in the IMU."""
    until = fast_impact.contact_stamp_s - 0.1
    labels = _feed(
        StreamIdentifier("statistical", params["identification"], params),
        fast_impact,
        _slow_imu(fast_impact.imu),
        vibration_until_s=until,
    )
    assert len(labels) == 1
    assert "imu" in labels[0].signals and "vibration" not in labels[0].signals
    assert abs(labels[0].impact_stamp_s - fast_impact.contact_stamp_s) < 1e-3


def test_vibration_with_mismatched_lengths_is_refused(params):
    """One value per stamp, or a clear InputError naming the field."""
    from tail_beam_sim.errors import InputError

    identifier = StreamIdentifier("threshold", params["identification"], params)
    with pytest.raises(InputError, match="vibration"):
        identifier.add_vibration(np.arange(3) * 1e-4, np.zeros(2))


def test_evaluation_feeds_the_accelerometer_where_the_setting_has_one(params):
    """tail-beam evaluate and training feed the vibration blocks as id_node does: at the
    shipped setting the labels name `vibration` and carry its period, at the IMU-only `nominal`
    setting the same impacts (the same IMU noise) are labelled from the IMU, and the shipped
    setting is the default."""
    from tail_beam_id.study.dataset import evaluation_params, settings
    from tail_beam_id.study.runs import run_set

    ev = evaluation_params(params)
    assert ev["default_rates"][0] == "shipped"
    chosen = settings(params, [1.0], ["shipped", "nominal"])
    shipped, nominal = chosen
    assert (
        shipped.has_vibration
        and shipped.vibration_rate_hz == params["sensors"]["vibration_rate_hz"]
    )
    assert not nominal.has_vibration and dict(shipped.rates_hz) == dict(nominal.rates_hz)
    records = list(run_set(params, "stream", 3, 9003, chosen, ["statistical"]))
    assert len(records) == 6 and all(r.label is not None for r in records)
    for r in records:
        channel = "vibration" if r.setting == "shipped/x1" else "imu"
        assert channel in r.label.signals, (r.setting, r.label.signals)
        expected_period_s = 1.0 / (
            params["sensors"]["vibration_rate_hz"]
            if channel == "vibration"
            else nominal.rates_hz["imu_rate_hz"]
        )
        assert r.label.features["imu_period_s"] == pytest.approx(expected_period_s, rel=1e-6)
        assert bool(r.label.features.get("vibration_channel")) == (channel == "vibration")


def test_a_setting_with_a_bad_accelerometer_rate_names_the_field(params):
    """A vibration rate that is neither 0 (none) nor within the sensor's range is refused in
    one line naming the setting's field."""
    import copy

    from tail_beam_id.study.dataset import settings
    from tail_beam_sim.errors import InputError

    bad = copy.deepcopy(params)
    bad["identification"]["evaluation"]["rates"]["shipped"]["vibration_rate_hz"] = 500.0
    with pytest.raises(InputError, match=r"rates\.shipped\.vibration_rate_hz"):
        settings(bad, [1.0], ["shipped"])


def test_shipped_models_are_trained_with_the_accelerometer():
    """The shipped models were trained with the accelerometer fed where the layout has one: the
    training records include impacts whose acceleration features came from the vibration
    stream, and the physics method's lag table for that channel is learnt from them."""
    import json

    from tail_beam_id.methods import MODELS_DIR

    statistical = json.loads((MODELS_DIR / "statistical.json").read_text(encoding="utf-8"))
    provenance = statistical["provenance"][0]
    assert (
        provenance["vibration_records"] >= 1000
        and provenance["records"] - provenance["vibration_records"] >= 5000
    )
    physics = json.loads((MODELS_DIR / "physics.json").read_text(encoding="utf-8"))
    assert physics["timing_vibration"] and all(
        band["count"] >= 10 for band in physics["timing_vibration"]
    )


def test_an_impact_the_accelerometer_found_is_decided_on_its_shorter_window(params, fast_impact):
    """Found in the accelerometer's stream, an impact is decided vibration_window_s (6 ms) of
    data after its onset; found by the IMU alone, window_s (12 ms) after. A vibration window
    longer than window_s is refused, naming the field and its range."""
    from tail_beam_sim.errors import InputError

    section = params["identification"]
    with_vibration = _feed(
        StreamIdentifier("statistical", section, params), fast_impact, _slow_imu(fast_impact.imu)
    )
    imu_only = _feed(
        StreamIdentifier("statistical", section, params),
        fast_impact,
        _slow_imu(fast_impact.imu),
        vibration_until_s=-1.0,
    )
    assert "vibration" in with_vibration[0].signals and "vibration" not in imu_only[0].signals
    # data_latency_ms runs to the later of the window's end and the camera's stamp (about 0.5 ms).
    assert with_vibration[0].data_latency_ms == pytest.approx(
        1e3 * section["vibration_window_s"], abs=0.1
    )
    assert imu_only[0].data_latency_ms == pytest.approx(1e3 * section["window_s"], abs=0.1)
    assert with_vibration[0].material == imu_only[0].material
    with pytest.raises(InputError, match="vibration_window_s"):
        StreamIdentifier(
            "statistical", {**section, "vibration_window_s": 2 * section["window_s"]}, params
        )


@pytest.mark.parametrize("channel", ["vibration", "imu", "imu beside the accelerometer"])
def test_an_acceleration_channel_that_comes_back_after_a_gap_is_taken_up_again(params, channel):
    """The acceleration channel's samples stop for 300 ms (longer than stream_timeout_s) and come
    again: its driver restarted, its cable back. Every impact is labelled once. ``vibration``:
    the IMU stands in for the accelerometer beside it from the stop until the accelerometer has
    had a sway and a baseline window of its new samples. ``imu``: the IMU alone; the jack
    pressure stands in from its stop until it is back, and only there. Every impact after the
    channel is back is decided from it. ``imu beside the accelerometer``: the IMU's gap is
    covered by the accelerometer, so the pressure never stands in (its detector never
    scans)."""
    from tail_beam_id.stream.label import match
    from tail_beam_id.study.dataset import settings, support_streams

    (recorded,) = support_streams(
        params, 1, 20, 41004, setting=settings(params, [1.0], ["shipped"])[0]
    )
    gap = (1.0, 1.3)
    identifier = StreamIdentifier("statistical", params["identification"], params)
    pressure, imu = recorded.pressure, recorded.imu
    stamps, accel = recorded.vibration.sample_stamps_s(), recorded.vibration.accel_mps2
    imu_kept = np.ones(imu.stamp_s.size, dtype=bool)
    if channel == "vibration":
        kept = ~((stamps >= gap[0]) & (stamps < gap[1]))
        stamps, accel = stamps[kept], accel[kept]
    else:
        if channel == "imu":
            stamps, accel = stamps[:0], accel[:0]  # the IMU alone
        imu_kept = ~((imu.stamp_s >= gap[0]) & (imu.stamp_s < gap[1]))
    rebounds = sorted(recorded.rebounds, key=lambda r: r.stamp_s)
    first = min(pressure.stamp_s[0], imu.stamp_s[0])
    last = max(pressure.stamp_s[-1], imu.stamp_s[-1])
    edges = first + 0.005 * np.arange(
        int((last - first) / 0.005) + 3
    )  # shared edges: no sample twice or lost
    labels, taken = [], 0
    for low, high in zip(edges[:-1], edges[1:]):
        inside = (pressure.stamp_s >= low) & (pressure.stamp_s < high)
        if inside.any():
            identifier.add_pressure(pressure.stamp_s[inside], pressure.pressure_pa[inside])
        inside = (imu.stamp_s >= low) & (imu.stamp_s < high) & imu_kept
        if inside.any():
            identifier.add_imu(
                imu.stamp_s[inside],
                imu.angular_velocity_radps[inside],
                imu.linear_acceleration_mps2[inside],
            )
        inside = (stamps >= low) & (stamps < high)
        if inside.any():
            identifier.add_vibration(stamps[inside], accel[inside])
        while taken < len(rebounds) and rebounds[taken].stamp_s < high:
            identifier.add_rebound(rebounds[taken].stamp_s, rebounds[taken].velocity_mps)
            taken += 1
        labels += identifier.poll()
    labels += identifier.flush()
    matching = match(recorded.truths, labels, 0.005)
    assert not matching.missed and not matching.extra
    outages = identifier.vibration_outages if channel == "vibration" else identifier.imu_outages
    assert len(outages) == 1 and outages[0][0] < gap[0]
    back_s = outages[0][1]
    assert gap[1] < back_s < gap[1] + 0.05
    if channel == "imu beside the accelerometer":
        assert identifier.pressure_detector.scanned_s == float("-inf")
        assert all("vibration" in label.signals for label in labels)
        return
    assert all(channel in label.signals for label in labels if label.impact_stamp_s > back_s)
    assert all(
        channel not in label.signals for label in labels if gap[0] < label.impact_stamp_s < back_s
    )
