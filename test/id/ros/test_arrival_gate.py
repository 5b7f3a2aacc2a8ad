"""id_node's arrival order (tail_beam_id/ros/arrival), driven without ROS the way the node drives
it: whatever order and pace the topics arrive in, the live labels are those of the offline
replay of the same data; time jumps (a restarted simulator, a clock gone wrong) are survived."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from id_helpers import replay_chunk, stream_chunk

from tail_beam_id.ros.arrival import ArrivalGate, GateConfig, GatedIdentifier
from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.label import Label
from tail_beam_id.stream.replay import replay
from tail_beam_sim.config import default_config_dir, load_parameters
from tail_beam_sim.physics.sensors import VibrationBlocks

STAMPS = [0.4, 1.0, 1.6]
UNTIL_S = 2.1


@pytest.fixture(scope="module")
def gate_config() -> GateConfig:
    """The shipped id_node arrival parameters."""
    return GateConfig.from_params(
        load_parameters([default_config_dir() / "id_node.yaml"])["id_node"]
    )


@pytest.fixture(scope="module")
def chunk(params):
    """Three impacts (coal, sandstone, coal) with every sensor of the shipped layout."""
    commands = [
        (stamp, {"material": m, "radius_m": 0.05, "drop_height_m": 3.0, "position_m": 1.0})
        for stamp, m in zip(STAMPS, ("coal", "sandstone", "coal"))
    ]
    return stream_chunk(params, commands, UNTIL_S)


@dataclass
class Plan:
    """When each message of one run of the simulator arrives (wall clock, s)."""

    pressure: tuple[np.ndarray, np.ndarray, np.ndarray]  # arrival, stamps, values (T, 1)
    imu: tuple[np.ndarray, np.ndarray, np.ndarray]  # arrival, stamps, values (T, 6)
    blocks: tuple[np.ndarray, VibrationBlocks]  # arrival per block, blocks
    rebounds: tuple[np.ndarray, list[tuple[float, np.ndarray]]]


def plan(
    chunk,
    delays_s: dict[str, float],
    speed: float = 1.0,
    start_wall_s: float = 0.0,
    stamp_shift_s: float = 0.0,
) -> Plan:
    """Each topic delivered in order ``delays_s[topic]`` after its stamp is reached, the stamps
    run ``speed`` times faster than the wall clock and shifted by ``stamp_shift_s``."""

    def wall(stamps, topic):
        return start_wall_s + np.asarray(stamps) / speed + delays_s.get(topic, 0.0)

    p, i, v = chunk.pressure, chunk.imu, chunk.vibration
    block_end = v.stamp_s + v.lengths * v.period_s
    shifted = VibrationBlocks(
        v.first_index,
        v.lengths,
        v.stamp_s + stamp_shift_s,
        v.accel_mps2,
        v.period_s,
        v.range_mps2,
        v.noise_variance,
    )
    rebounds = [(r.stamp_s + stamp_shift_s, r.velocity_mps) for _, r in chunk.rebounds]
    return Plan(
        (
            wall(p.stamp_s, "jack_pressure"),
            p.stamp_s + stamp_shift_s,
            p.pressure_pa.reshape(-1, 1),
        ),
        (
            wall(i.stamp_s, "imu"),
            i.stamp_s + stamp_shift_s,
            np.hstack([i.angular_velocity_radps, i.linear_acceleration_mps2]),
        ),
        (wall(block_end, "vibration"), shifted),
        (wall([r.stamp_s for _, r in chunk.rebounds], "rebound_velocity"), rebounds),
    )


def drive(
    gated: GatedIdentifier,
    plans: list[Plan],
    tick_s: float = 0.01,
    flush_after_idle_s: float = 1.0,
) -> list[dict]:
    """Tick the gated identifier as id_node's timer does; every label it publishes."""
    last = max(max(pl.pressure[0].max(), pl.imu[0].max(), pl.blocks[0].max()) for pl in plans)
    labels: list[dict] = []
    flushed = False
    previous = -np.inf
    for t in np.arange(0.0, last + flush_after_idle_s + 3 * tick_s, tick_s):
        for pl in plans:

            def due(arrival):
                return (arrival > previous) & (arrival <= t)

            arrivals = {}
            for name, (arrival, stamps, values) in (
                ("jack_pressure", pl.pressure),
                ("imu", pl.imu),
            ):
                take = due(arrival)
                if take.any():
                    arrivals[name] = (stamps[take], values[take])
            blocks = pl.blocks[1].select(due(pl.blocks[0]))
            rebounds = [r for r, a in zip(pl.rebounds[1], pl.rebounds[0]) if previous < a <= t]
            if arrivals or blocks.count or rebounds:
                labels += gated.tick(t, arrivals, blocks, rebounds)
        previous = t
        if not flushed and t > last + flush_after_idle_s:
            labels += gated.tick(t, {}, VibrationBlocks.empty(), [], end_of_data=True)
            flushed = True
    return labels


def gated(params, config: GateConfig) -> GatedIdentifier:
    return GatedIdentifier(
        lambda trained: StreamIdentifier(
            params=params["identification"], model_params=params, prebuilt=trained
        ),
        config,
    )


def offline(params, chunk) -> list[dict]:
    """What `tail-beam identify` gives on these streams (the bag's view)."""
    rebounds = [r for _, r in chunk.rebounds]
    return replay(
        StreamIdentifier(params=params["identification"], model_params=params),
        chunk.pressure,
        chunk.imu,
        rebounds,
        vibration=chunk.vibration,
    )


def keys(labels: list[Label]) -> list[tuple]:
    return [label.decision() for label in labels]


@pytest.mark.parametrize("speed", [1.0, 25.0, 1000.0])
@pytest.mark.parametrize(
    "delays",
    [
        {},
        {"imu": 0.15, "vibration": 0.3},  # the vibration 0.3 s behind: ungated, it looked stopped
        {"jack_pressure": 0.4, "rebound_velocity": 0.0},  # the camera far ahead of the pressure
        {
            "vibration": 0.002,
            "rebound_velocity": 0.008,
        },  # a rebound a little late (within reorder_s)
    ],
)
def test_live_labels_are_the_offline_labels_whatever_the_arrival(
    params, chunk, gate_config, delays, speed
):
    """Same impact stamps, labels and confidences as the offline replay, with topics lagging
    each other by up to 0.4 s of wall time, in real time, 25 times faster and all at once."""
    expected = offline(params, chunk)
    assert len(expected) == len(STAMPS)
    assert keys(drive(gated(params, gate_config), [plan(chunk, delays, speed)])) == keys(expected)


def test_a_restarted_simulator_is_identified_afresh(params, chunk, gate_config):
    """Stamps starting again from 0 (sim_node restarted): the first run's impacts and the
    second's are all labelled as offline, with one time jump noted."""
    runner = gated(params, gate_config)
    first = plan(chunk, {"vibration": 0.05})
    second = plan(chunk, {"vibration": 0.05}, start_wall_s=UNTIL_S + 0.3)
    labels = drive(runner, [first, second])
    assert keys(labels) == keys(offline(params, chunk)) * 2
    assert runner.time_jumps == 1
    assert any("went back" in note for note in runner.notes)


def test_simulation_time_jumping_ahead_is_a_new_epoch(params, chunk, gate_config):
    """Every stream 100 s ahead at once (a clock reset forward): both runs labelled, the second
    at its shifted stamps, nothing dropped."""
    runner = gated(params, gate_config)
    labels = drive(
        runner,
        [plan(chunk, {}), plan(chunk, {}, start_wall_s=UNTIL_S + 0.05, stamp_shift_s=100.0)],
    )
    once = keys(offline(params, chunk))
    assert [rest for _, *rest in keys(labels)] == [rest for _, *rest in once] * 2
    np.testing.assert_allclose(
        [s for s, *_ in keys(labels)],
        [s for s, *_ in once] + [s + 100.0 for s, *_ in once],
        atol=1e-9,
    )
    assert runner.time_jumps == 1 and runner.count_totals()[2] == 0


def test_one_message_from_the_future_is_set_aside_and_nothing_goes_deaf(
    params, chunk, gate_config
):
    """One IMU sample stamped 1000 s ahead, mid-stream: counted and dropped, every impact still
    labelled as offline (before, the identifier took the IMU for stopped and went deaf)."""
    runner = gated(params, gate_config)
    run = plan(chunk, {})
    arrival, stamps, values = run.imu
    k = int(np.searchsorted(stamps, 0.7))
    run.imu = (
        np.insert(arrival, k, arrival[k]),
        np.insert(stamps, k, 1000.0),
        np.insert(values, k, values[k], axis=0),
    )
    assert keys(drive(runner, [run])) == keys(offline(params, chunk))
    assert runner.count_totals()[1:3] == (1, 1) and runner.time_jumps == 0


def test_a_sensor_that_stops_no_longer_holds_the_others(params, chunk, gate_config):
    """The vibration stream stops after the first impact: the others are released once it has
    been silent stream_idle_s, and every impact is labelled, the later ones without vibration."""
    run = plan(chunk, {})
    arrival, blocks = run.blocks
    keep = blocks.stamp_s < 0.7
    run.blocks = (arrival[keep], blocks.select(keep))
    labels = drive(gated(params, gate_config), [run])
    assert [round(lab.impact_stamp_s, 2) for lab in labels] == STAMPS
    assert "vibration" in labels[0].signals and all(
        "vibration" not in lab.signals for lab in labels[1:]
    )


def test_the_gate_holds_samples_until_every_live_stream_has_passed_them(gate_config):
    """Release stops at the slowest live stream's newest stamp, only after reorder_s, and not
    before every stream was heard from (or stream_idle_s passed since the first)."""
    gate = ArrivalGate(gate_config)
    gate.add("jack_pressure", np.arange(10) * 0.01, np.zeros((10, 1)), now_s=0.0)
    gate.add("imu", np.arange(5) * 0.01, np.zeros((5, 6)), now_s=0.0)
    assert gate.release(now_s=gate_config.reorder_s).empty  # the vibration may still come
    gate.add("vibration", np.arange(8) * 0.01, np.zeros((8, 1)), now_s=0.0)
    assert gate.release(now_s=0.0).empty  # not yet held reorder_s
    out = gate.release(now_s=gate_config.reorder_s)
    assert {name: t.max() for name, (t, _) in out.streams.items()} == pytest.approx(
        {"jack_pressure": 0.04, "imu": 0.04, "vibration": 0.04}
    )
    later = gate.release(
        now_s=gate_config.reorder_s + gate_config.stream_idle_s + 0.01
    )  # all idle: everything goes
    assert {name: t.max() for name, (t, _) in later.streams.items()} == pytest.approx(
        {"jack_pressure": 0.09, "vibration": 0.07}
    )


def test_a_rebound_that_is_no_number_is_refused_live_and_offline_alike(params, chunk, gate_config):
    """A rebound_velocity of NaN/inf (a broken camera, a hostile client) is counted and left
    out, live and offline alike: every label is JSON-clean (no inf feature), the impacts are
    decided without the camera, and the live labels are the offline ones on the same data."""
    import json

    run = plan(chunk, {})
    arrival, rebounds = run.rebounds
    run.rebounds = (arrival, [(stamp, np.array([np.nan, np.inf, 1e300])) for stamp, _ in rebounds])
    runner = gated(params, gate_config)
    live = drive(runner, [run])
    broken = [
        type(r)(r.stamp_s, np.array([np.nan, np.inf, 1e300]), r.true_velocity_mps)
        for _, r in chunk.rebounds
    ]
    identifier = StreamIdentifier(params=params["identification"], model_params=params)
    offline = replay(identifier, chunk.pressure, chunk.imu, broken, vibration=chunk.vibration)
    assert keys(live) == keys(offline) and len(live) == len(STAMPS)
    assert all("rebound_velocity" not in label.signals for label in live)
    for label in live:
        json.loads(label.to_json())
    assert runner.count_totals()[3] == len(STAMPS) and identifier.refused_rebounds == len(STAMPS)
    assert any("rebounds refused (not finite" in note for note in runner.notes)


def test_samples_that_are_no_number_are_left_out_live_and_offline_alike(
    params, chunk, gate_config
):
    """A NaN jack pressure sample right after an impact, an inf IMU sample and a NaN
    accelerometer sample in the middle of another (a sensor dropout, a corrupt message) are
    counted and left out, live (noted for the log) and offline alike; every label stays strict
    JSON with a finite confidence and the same material as without them. Before, the one NaN
    pressure sample made its label gangue with confidence NaN."""
    import json
    from dataclasses import replace

    run = plan(chunk, {})
    clean = offline(params, chunk)
    p_arrival, p_stamps, p_values = run.pressure
    i_arrival, i_stamps, i_values = run.imu
    p_values, i_values = p_values.copy(), i_values.copy()
    p_values[int(np.searchsorted(p_stamps, STAMPS[0] + 0.003)), 0] = np.nan
    i_values[int(np.searchsorted(i_stamps, STAMPS[1] + 0.002)), 5] = np.inf
    run.pressure, run.imu = (p_arrival, p_stamps, p_values), (i_arrival, i_stamps, i_values)
    accel = chunk.vibration.accel_mps2.copy()
    sample = int(np.searchsorted(chunk.vibration.sample_stamps_s(), STAMPS[2] + 0.001))
    accel[sample] = np.nan
    vibration = replace(chunk.vibration, accel_mps2=accel)
    run.blocks = (run.blocks[0], replace(run.blocks[1], accel_mps2=accel))
    runner = gated(params, gate_config)
    live = drive(runner, [run])
    identifier = StreamIdentifier(params=params["identification"], model_params=params)
    broken = replay(
        identifier,
        replace(chunk.pressure, pressure_pa=p_values[:, 0]),
        replace(chunk.imu, linear_acceleration_mps2=i_values[:, 3:]),
        [r for _, r in chunk.rebounds],
        vibration=vibration,
    )
    assert keys(live) == keys(broken) and len(live) == len(STAMPS)
    assert [label.material for label in broken] == [label.material for label in clean]
    for label in live + broken:
        json.loads(label.to_json())
    assert identifier.refused_samples == {"jack_pressure": 1, "imu": 1, "vibration": 1}
    assert any(
        "3 sample(s) with a non-finite stamp or value left out" in note for note in runner.notes
    )
    # A restarted simulator sends the same broken run again: the log's totals keep counting
    # across the time jump (they started again from 0 with the new identifier).
    again = plan(chunk, {}, start_wall_s=UNTIL_S + 0.3)
    again.pressure, again.imu, again.blocks = run.pressure, run.imu, run.blocks
    again.pressure = (again.pressure[0] + UNTIL_S + 0.3, *again.pressure[1:])
    again.imu = (again.imu[0] + UNTIL_S + 0.3, *again.imu[1:])
    again.blocks = (again.blocks[0] + UNTIL_S + 0.3, again.blocks[1])
    restarted = gated(params, gate_config)
    drive(restarted, [run, again])
    assert restarted.time_jumps == 1
    assert any(
        "6 sample(s) with a non-finite stamp or value left out" in note for note in restarted.notes
    )


def arrivals_between(chunk, lo_s: float, hi_s: float):
    """The chunk's samples, blocks (by first stamp) and rebounds stamped in (lo_s, hi_s], as
    GatedIdentifier.admit takes them."""
    p, i, v = chunk.pressure, chunk.imu, chunk.vibration
    take_p = (p.stamp_s > lo_s) & (p.stamp_s <= hi_s)
    take_i = (i.stamp_s > lo_s) & (i.stamp_s <= hi_s)
    arrivals = {
        "jack_pressure": (p.stamp_s[take_p], p.pressure_pa[take_p].reshape(-1, 1)),
        "imu": (
            i.stamp_s[take_i],
            np.hstack([i.angular_velocity_radps, i.linear_acceleration_mps2])[take_i],
        ),
    }
    blocks = v.select((v.stamp_s > lo_s) & (v.stamp_s <= hi_s))
    rebounds = [(r.stamp_s, r.velocity_mps) for _, r in chunk.rebounds if lo_s < r.stamp_s <= hi_s]
    return arrivals, blocks, rebounds


def test_each_batch_is_held_from_its_own_arrival_and_the_next_horizon_is_known(
    params, chunk, gate_config
):
    """What id_node does with arrival times: a batch admitted at wall clock t is released at t +
    reorder_s, not before and not held for a later batch's sake; while the first impact waits
    for its data window, next_horizon_s is its onset plus vibration_window_s (what id_node's
    wake waits for), and inf once it is labelled."""
    hold = gate_config.reorder_s
    window_s = params["identification"]["vibration_window_s"]
    runner = gated(params, gate_config)
    early = (
        STAMPS[0] + window_s - 0.0015
    )  # the first pulse and its ringing are in, its data window not
    assert runner.admit(10.0, *arrivals_between(chunk, -np.inf, early)) == []
    assert runner.admit(10.0 + hold / 2, *arrivals_between(chunk, early, STAMPS[0] + 0.1)) == []
    assert runner.decide(10.0 + 0.9 * hold) == [] and runner.gate.released_s == -np.inf
    assert runner.decide(10.0 + hold) == []
    assert early - 0.001 < runner.gate.released_s <= early  # the first batch only
    onset = runner.next_horizon_s() - window_s
    assert abs(onset - STAMPS[0]) < 0.001
    labels = runner.decide(10.0 + 1.5 * hold)
    assert [round(label.impact_stamp_s, 2) for label in labels] == [STAMPS[0]]
    assert runner.next_horizon_s() == np.inf


def drive_by_arrival(
    gated: GatedIdentifier, pl: Plan, hold_s: float, tick_s: float = 0.005
) -> list[Label]:
    """Tick as id_node does now: what arrived since the last tick in two batches, held long
    enough and not yet, each admitted with its newest arrival time; then decide."""
    last = max(pl.pressure[0].max(), pl.imu[0].max(), pl.blocks[0].max())
    labels: list[Label] = []
    previous = -np.inf
    for t in np.arange(0.0, last + 1.2, tick_s):
        cut = t - hold_s
        for lo, hi in ((previous, min(cut, t)), (max(cut, previous), t)):
            arrivals, newest = {}, -np.inf
            for name, (arrival, stamps, values) in (
                ("jack_pressure", pl.pressure),
                ("imu", pl.imu),
            ):
                take = (arrival > lo) & (arrival <= hi)
                if take.any():
                    arrivals[name] = (stamps[take], values[take])
                    newest = max(newest, float(arrival[take].max()))
            take = (pl.blocks[0] > lo) & (pl.blocks[0] <= hi)
            if take.any():
                newest = max(newest, float(pl.blocks[0][take].max()))
            rebounds = [(r, a) for r, a in zip(pl.rebounds[1], pl.rebounds[0]) if lo < a <= hi]
            newest = max([newest, *(a for _, a in rebounds)])
            if newest > -np.inf:
                labels += gated.admit(
                    newest, arrivals, pl.blocks[1].select(take), [r for r, _ in rebounds]
                )
        previous = t
        labels += gated.decide(t, end_of_data=t > last + 1.0)
    return labels


@pytest.mark.parametrize(
    "delays",
    [
        {},
        {"rebound_velocity": 0.001},  # the camera's message a little behind the samples around it
        {"rebound_velocity": 0.003},  # more than the hold behind them
        {"imu": 0.15, "vibration": 0.3},
    ],
)
def test_live_labels_are_the_offline_labels_when_each_batch_is_held_from_its_arrival(
    params, chunk, gate_config, delays
):
    """The node's way of ticking (each batch held reorder_s from its own arrival, not from the
    tick) gives the offline labels too, with a rebound arriving up to 3 ms after the samples
    stamped with it and topics 0.3 s apart."""
    expected = offline(params, chunk)
    assert keys(
        drive_by_arrival(gated(params, gate_config), plan(chunk, delays), gate_config.reorder_s)
    ) == keys(expected)


def test_rebounds_ahead_of_a_lagging_reader_wait_for_the_streams(params, chunk, gate_config):
    """The continuous topics reach id_node 1.2 s of stamps behind the camera (a reader that
    lags a simulator running as fast as possible, stamps 10 x the wall clock): each rebound is
    held until the streams come within time_jump_s of it, not refused, so the live labels are
    the offline ones, every one with its rebound. A stray rebound stamped 1e6 s ahead is held,
    never released, and counted refused once the data ends: no label rests on it."""
    lag_s = 0.12  # wall s: 1.2 s of stamps at speed 10, beyond time_jump_s (1 s)
    run = plan(chunk, {"jack_pressure": lag_s, "imu": lag_s, "vibration": lag_s}, speed=10.0)
    arrival, rebounds = run.rebounds
    run.rebounds = (
        np.append(arrival, arrival[-1]),
        [*rebounds, (1e6, np.array([0.0, 0.0, 3.0]))],
    )
    runner = gated(params, gate_config)
    live = drive(runner, [run])
    identifier = StreamIdentifier(params=params["identification"], model_params=params)
    offline = replay_chunk(identifier, chunk)
    assert keys(live) == keys(offline) and len(live) == len(STAMPS)
    assert all("rebound_velocity" in label.signals for label in live)
    assert runner.count_totals()[3] == 1  # the stray one alone
