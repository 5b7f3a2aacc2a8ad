"""The stream simulator: continuous sampling, beam state carried across impacts, the queue."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tail_beam_sim.config import deep_merge, load_parameters
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.stream import BlockNoise, StreamSimulator

COAL = {"material": "coal", "radius_m": 0.025, "drop_height_m": 3.5, "position_m": 1.0}
MARBLE = {"material": "marble", "radius_m": 0.06, "drop_height_m": 2.0, "position_m": 0.4}
NO_NOISE = {
    "pressure_noise_pa": 0.0,
    "imu_accel_noise_mps2": 0.0,
    "imu_gyro_noise_radps": 0.0,
    "camera_velocity_noise_mps": 0.0,
    "camera_velocity_noise_fraction": 0.0,
}


def make_stream(**sections) -> StreamSimulator:
    params = load_parameters([_config("sim_node.yaml")])
    deep_merge(params, sections)
    return StreamSimulator.from_params(params)


def _config(name: str) -> str:
    from tail_beam_sim.config import default_config_dir

    return str(default_config_dir() / name)


def test_beam_at_rest_reads_setting_pressure_and_gravity_with_configured_noise():
    """With no impact the streams sit on the k / rate grid from 0, reading the setting pressure
    and +g with the configured noise RMS, and no rebound or truth."""
    stream = make_stream()
    chunk = stream.advance(2.0)
    spec = stream.sensors
    # Absolute grid k / rate from t = 0 inclusive.
    assert chunk.pressure.stamp_s.size == int(2.0 * spec.pressure_rate_hz) + 1
    assert chunk.imu.stamp_s.size == int(2.0 * spec.imu_rate_hz) + 1
    n = chunk.pressure.stamp_s.size
    pressure = chunk.pressure.pressure_pa
    # A plate at rest: static setting pressure; the accelerometer reads +g along z
    # (docs/physics.md).
    assert abs(
        pressure.mean() - stream.support.setting_pressure_pa
    ) < 4 * spec.pressure_noise_pa / math.sqrt(n)
    assert pressure.std() == pytest.approx(spec.pressure_noise_pa, rel=0.05)
    accel = chunk.imu.linear_acceleration_mps2
    assert accel[:, 2].mean() == pytest.approx(
        stream.support.gravity_mps2, abs=4 * spec.imu_accel_noise_mps2 / math.sqrt(n)
    )
    assert accel.std(axis=0) == pytest.approx([spec.imu_accel_noise_mps2] * 3, rel=0.05)
    assert chunk.imu.angular_velocity_radps.std(axis=0) == pytest.approx(
        [spec.imu_gyro_noise_radps] * 3, rel=0.05
    )
    assert chunk.rebounds == [] and chunk.truths == []


def test_output_does_not_depend_on_how_time_is_chunked():
    """Advancing in 41 random chunks gives the same stamps, noise, signals, rebounds and truths
    as advancing at once."""
    whole, pieces = make_stream(), make_stream()
    for stream in (whole, pieces):
        stream.submit(COAL, 0.1)
        stream.submit(MARBLE)
    one = whole.advance(1.0)
    rng = np.random.default_rng(3)
    ends = np.sort(rng.uniform(0.0, 1.0, 40)).tolist() + [1.0]
    chunks = [pieces.advance(end) for end in ends]
    np.testing.assert_array_equal(
        np.concatenate([c.pressure.stamp_s for c in chunks]), one.pressure.stamp_s
    )
    # The same noise sample for sample; the signal to rounding (vectorised sums over other sizes).
    np.testing.assert_allclose(
        np.concatenate([c.pressure.pressure_pa for c in chunks]),
        one.pressure.pressure_pa,
        rtol=1e-13,
    )
    np.testing.assert_allclose(
        np.concatenate([c.imu.linear_acceleration_mps2 for c in chunks]),
        one.imu.linear_acceleration_mps2,
        rtol=0,
        atol=1e-12,
    )
    assert (
        [r[0] for c in chunks for r in c.rebounds]
        == [r[0] for r in one.rebounds]
        == ["sim-0001", "sim-0002"]
    )
    assert [t[1]["impact_id"] for c in chunks for t in c.truths] == ["sim-0001", "sim-0002"]


def test_an_imu_behind_a_low_pass_is_the_same_however_time_is_chunked():
    """sensors.imu_antialias_order 4: the filter's state is carried from chunk to chunk, so 41
    random chunks give the samples of one advance; the impact reaches the filtered IMU."""
    sensors = {"sensors": {"imu_antialias_order": 4, "imu_rate_hz": 5000.0}}
    whole, pieces = make_stream(**sensors), make_stream(**sensors)
    for stream in (whole, pieces):
        stream.submit(COAL, 0.1)
        stream.submit(MARBLE)
    one = whole.advance(1.0)
    ends = np.sort(np.random.default_rng(5).uniform(0.0, 1.0, 40)).tolist() + [1.0]
    chunks = [pieces.advance(end) for end in ends]
    for field in ("linear_acceleration_mps2", "angular_velocity_radps"):
        np.testing.assert_allclose(
            np.concatenate([getattr(c.imu, field) for c in chunks]),
            getattr(one.imu, field),
            rtol=0,
            atol=1e-12,
        )
    accel = one.imu.linear_acceleration_mps2[:, 2]
    rest = accel[one.imu.stamp_s < 0.09]
    assert np.max(np.abs(accel - np.median(rest))) > 20 * np.std(rest)


def test_block_noise_is_the_same_whole_or_in_pieces():
    """Block noise taken sample by sample equals the block taken at once, and another seed gives
    other noise."""
    noise = BlockNoise(seed=5, stream=1, width=2, block_samples=7)
    whole = noise.take(3, 30)
    pieces = np.concatenate([BlockNoise(5, 1, 2, 7).take(3 + i, 1) for i in range(30)])
    np.testing.assert_array_equal(whole, pieces)
    assert not np.array_equal(whole, BlockNoise(6, 1, 2, 7).take(3, 30))


def oscillator_pressure(
    stream: StreamSimulator, truths: list[dict], t_s: np.ndarray
) -> np.ndarray:
    """Jack pressure of the rigid beam struck by short impulses: closed-form impulse response.

    An independent model of the carried state: each impact gives the beam the angular
    impulse m (v_in + v_out) x at mid-contact, and the responses of the damped 1-DOF
    oscillator (I_C, c_Q d^2, K_Q d^2) simply add.
    """
    s = stream.support
    inertia, k, c = (
        s.beam_inertia_about_hinge_kgm2,
        s.rotational_stiffness_nmprad,
        s.rotational_damping_nmsprad,
    )
    wn = math.sqrt(k / inertia)
    zeta = c / (2 * math.sqrt(k * inertia))
    wd = wn * math.sqrt(1 - zeta**2)
    phi, rate = np.zeros_like(t_s), np.zeros_like(t_s)
    for truth in truths:
        impulse = (
            truth["mass_kg"]
            * (truth["impact_speed_mps"] + truth["rebound_speed_mps"])
            * truth["position_m"]
        )
        t0 = 0.5 * (truth["contact_start_stamp"] + truth["contact_end_stamp"])
        tau = np.clip(t_s - t0, 0.0, None)
        decay = impulse / (inertia * wd) * np.exp(-zeta * wn * tau)
        phi += decay * np.sin(wd * tau)
        rate += decay * (wd * np.cos(wd * tau) - zeta * wn * np.sin(wd * tau)) * (t_s > t0)
    lever = s.jack_lever_arm_m
    return (
        s.setting_pressure_pa
        + (s.jack_stiffness_npm * lever * phi + s.jack_damping_nspm * lever * rate)
        / s.piston_area_m2
    )


def test_ringing_carries_across_impacts_like_superposed_impulse_responses():
    # The rigid tier: the closed-form oscillator below is the rigid beam on its jack.
    """An impact on a still-ringing beam adds to the ringing like superposed impulse responses
    of the rigid oscillator, within 3 % of the swing, and unlike the second impact alone."""
    stream = make_stream(sensors=NO_NOISE, stream={"min_impact_gap_s": 0.01, "tier": "rigid"})
    first = stream.submit(MARBLE, 0.1)
    second = stream.submit(
        {**MARBLE, "position_m": 1.2}, 0.1 + 0.3 / 39.0
    )  # mid-ring, beam moving
    chunk = stream.advance(0.4)
    truths = [t for _, t in chunk.truths]
    assert [t["impact_id"] for t in truths] == [first.impact_id, second.impact_id]
    stamps, pressure = chunk.pressure.stamp_s, chunk.pressure.pressure_pa
    expected = oscillator_pressure(stream, truths, stamps)
    swing = np.ptp(expected)
    assert swing > 1e5  # a real ringing, not noise
    late = stamps > second.contact_stamp_s + 2e-3
    # Short-impulse model vs the solved contacts: within 3 % of the swing after both impacts.
    assert np.max(np.abs(pressure[late] - expected[late])) < 0.03 * swing
    # The second impact alone (on a beam at rest) would give a different history: the state
    # matters.
    alone = oscillator_pressure(stream, truths[1:], stamps)
    assert np.max(np.abs(pressure[late] - alone[late])) > 0.1 * swing


def test_contact_stamps_respect_the_gap_and_the_lead():
    """A contact comes no sooner than command_lead_s after the produced samples and
    min_impact_gap_s after the previous particle left; a future stamp is granted as asked."""
    stream = make_stream()
    stream.advance(0.5)
    gap, lead = stream.params.min_impact_gap_s, stream.params.command_lead_s
    first = stream.submit(COAL)
    assert first.contact_stamp_s == pytest.approx(0.5 + lead)
    second = stream.submit(COAL, contact_stamp_s=0.0)  # asks for the past: moved on
    assert second.contact_stamp_s == pytest.approx(first.free_after_s + gap)
    third = stream.submit(COAL, contact_stamp_s=5.0)  # asks for the future: granted
    assert third.contact_stamp_s == 5.0
    assert [first.impact_id, second.impact_id, third.impact_id] == [
        "sim-0001",
        "sim-0002",
        "sim-0003",
    ]


def test_queue_is_bounded_and_a_refusal_names_the_limit():
    """Beyond max_queued_impacts a command is refused naming the limit, without taking an id;
    once the queue drains commands are taken again."""
    stream = make_stream(stream={"max_queued_impacts": 2})
    stream.submit(COAL)
    stream.submit(COAL)
    with pytest.raises(InputError, match="max_queued_impacts"):
        stream.submit(COAL)
    assert stream.queued == 2
    stream.advance(stream.earliest_contact_s)  # both have started
    assert stream.queued == 0
    assert stream.submit(COAL).impact_id == "sim-0003"


@pytest.mark.parametrize(
    "command, field",
    [
        ({**COAL, "material": "granite"}, "material"),
        ({**COAL, "radius_m": -0.01}, "radius_m"),
        ({**COAL, "position_m": float("nan")}, "position_m"),
        ({**COAL, "colour": "black"}, "colour"),
    ],
)
def test_bad_command_is_refused_and_leaves_the_stream_untouched(command, field):
    """A bad command is an InputError naming its field, and queues nothing nor takes an id."""
    stream = make_stream()
    with pytest.raises(InputError) as info:
        stream.submit(command)
    assert info.value.field == field
    assert stream.queued == 0
    assert stream.submit(COAL).impact_id == "sim-0001"


def test_each_rebound_and_truth_comes_once_with_contract_fields():
    """Each impact's rebound and truth come exactly once, in order, the rebound stamped at the
    first camera frame after separation and the truth after the contact."""
    stream = make_stream()
    ids = [stream.submit({**COAL, "impact_id": f"x{i}"}).impact_id for i in range(3)]
    out = [stream.advance(t) for t in np.arange(0.05, 2.0, 0.05)]
    rebounds = [r for c in out for r in c.rebounds]
    truths = [t for c in out for t in c.truths]
    assert [r[0] for r in rebounds] == ids and [t[1]["impact_id"] for t in truths] == ids
    for (_, rebound), (stamp, truth) in zip(rebounds, truths):
        # The camera stamps the first frame at or after separation; the truth says when contact
        # was.
        assert (
            truth["final_separation_stamp"]
            <= rebound.stamp_s
            < truth["final_separation_stamp"] + 1 / stream.sensors.camera_frame_rate_hz + 1e-9
        )
        assert truth["contact_start_stamp"] < truth["contact_end_stamp"] < stamp
        assert truth["label"] == "coal" and rebound.velocity_mps[2] > 0


def test_the_gap_holds_after_the_previous_impact_is_long_reported():
    """The minimum gap after the previous particle left still holds once that impact's truth is
    out."""
    stream = make_stream()
    first = stream.submit(COAL)
    stream.advance(first.truth_stamp_s + 0.01)  # rebound and truth are out; the beam still rings
    second = stream.submit(COAL)
    assert second.contact_stamp_s == pytest.approx(
        first.free_after_s + stream.params.min_impact_gap_s
    )
