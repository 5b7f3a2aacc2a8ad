"""A simulated flow written as a rosbag2 bag and read back: the sensor streams, every lump's
truth and rebound, the share intervals and the window commands, as the reader exposes them."""

from __future__ import annotations

import numpy as np
import pytest

from tail_beam_sim import topics
from tail_beam_sim.bags.flow_bag import write_flow_bag
from tail_beam_sim.bags.read import read_sensors
from tail_beam_sim.config import default_config_dir, load_parameters
from tail_beam_sim.physics.flow import simulate_flow


@pytest.fixture(scope="module")
def record():
    params = load_parameters(
        [default_config_dir() / "sim_node.yaml", default_config_dir() / "flow.yaml"]
    )
    params["flow"].update(
        lumps_per_s=80.0,
        onset_delay_s=0.05,
        share_drawn_mass_kg=[0.0, 60.0, 90.0],
        share_gangue=[0.0, 0.0, 1.0],
    )
    return simulate_flow(params, 2.5, seed=4, windows=[(0.2, 2.0)])


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_flow_bag_round_trip(record, tmp_path, storage):
    """A flow's bag reads back with its samples, truths, share intervals and window commands."""
    bag = tmp_path / "flow"
    count = write_flow_bag(record, bag, storage=storage, namespace="/support_03")
    back = read_sensors(bag)
    assert back.namespace == "/support_03"
    # stamps travel as integer nanoseconds
    assert np.allclose(back.pressure_stamp_s, record.pressure.stamp_s, rtol=0, atol=1e-9)
    assert np.array_equal(back.pressure_pa, record.pressure.pressure_pa)
    assert np.array_equal(back.linear_acceleration_mps2, record.imu.linear_acceleration_mps2)
    assert np.array_equal(back.vibration.accel_mps2, record.vibration.accel_mps2)
    assert back.vibration_lost_samples == 0
    assert len(back.rebounds) == len(record.rebounds)
    assert back.json_topics[topics.IMPACT_TRUTH] == [t for _, t in record.truths]
    assert back.json_topics[topics.GANGUE_SHARE_TRUTH] == [s.to_json() for s in record.shares]
    assert back.json_topics[topics.WINDOW_CMD] == [
        {"action": "open", "stamp_s": 0.2},
        {"action": "close", "stamp_s": 2.0},
    ]
    shares = back.json_topics[topics.GANGUE_SHARE_TRUTH]
    assert shares[0]["share_by_mass"] == 0.0 and shares[-1]["share_by_mass"] > 0.0
    assert count == (
        record.pressure.stamp_s.size
        + record.imu.stamp_s.size
        + record.vibration.count
        + len(record.rebounds)
        + len(record.truths)
        + len(record.shares)
        + len(record.windows)
    )


def test_a_flow_whose_camera_reports_the_impact_point_records_one_point_per_rebound(tmp_path):
    """With sensors.camera_reports_impact_point, the offline flow keeps the camera's point of
    every lump, stamped as its rebound and within a few noise sigmas (0.01 m) of where the lump
    struck; the bag carries them on impact_point and reads them back. Without it, none."""
    params = load_parameters(
        [default_config_dir() / "sim_node.yaml", default_config_dir() / "flow.yaml"]
    )
    params["flow"].update(lumps_per_s=20.0, onset_delay_s=0.05)
    params["sensors"]["camera_reports_impact_point"] = True
    pointed = simulate_flow(params, 1.5, seed=9, windows=[(0.1, 1.5)])
    assert len(pointed.rebounds) >= 10
    assert len(pointed.points) == len(pointed.rebounds)
    rebound_at = {impact_id: r.stamp_s for impact_id, r in pointed.rebounds}
    struck_at = {t["impact_id"]: t["position_m"] for _, t in pointed.truths}
    for impact_id, point in pointed.points:
        assert point.stamp_s == rebound_at[impact_id]
        assert abs(point.point_m[0] - struck_at[impact_id]) < 0.06
        assert point.point_m[2] == 0.0
    bag = tmp_path / "pointed"
    write_flow_bag(pointed, bag)
    back = read_sensors(bag)
    assert [p[0] for p in back.points] == pytest.approx([p.stamp_s for _, p in pointed.points])
    params["sensors"]["camera_reports_impact_point"] = False
    assert simulate_flow(params, 1.5, seed=9, windows=[(0.1, 1.5)]).points == []
