"""impact_point in bags: written and read back as recorded, identified with and without it as a
user runs `tail-beam identify`, and each hostile point refused by name while the rest of the
recording is labelled as the clean one."""

from __future__ import annotations

import copy
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
from id_helpers import stream_chunk
from rosbags.highlevel import AnyReader

from tail_beam_id.cli.identify_cmd import identify_bag
from tail_beam_sim import topics
from tail_beam_sim.bags import records as bagio
from tail_beam_sim.bags.read import read_sensors
from tail_beam_sim.config import load_parameters

BIN = Path(sys.executable).parent
COMMANDS = [
    (0.3, {"material": "coal", "radius_m": 0.05, "drop_height_m": 2.5, "position_m": 0.4}),
    (0.6, {"material": "sandstone", "radius_m": 0.04, "drop_height_m": 3.0, "position_m": 1.2}),
    (0.9, {"material": "coal", "radius_m": 0.06, "drop_height_m": 2.0, "position_m": 0.8}),
]
NOISE_M = 0.01  # sensors.impact_point_noise_m's default


def recording(points: bool):
    params = copy.deepcopy(load_parameters())
    params["sensors"]["camera_reports_impact_point"] = points
    return stream_chunk(params, COMMANDS, 1.2)


def chunk_records(chunk, extra_points=()) -> list:
    """The bag records of a simulated chunk (sensor streams, rebounds, points, truths)."""
    out = list(
        bagio.pressure_msgs(
            chunk.pressure.stamp_s, chunk.pressure.pressure_pa, chunk.pressure.variance_pa2
        )
    )
    imu = chunk.imu
    out += bagio.imu_msgs(
        imu.stamp_s,
        imu.angular_velocity_radps,
        imu.linear_acceleration_mps2,
        imu.gyro_variance,
        imu.accel_variance,
    )
    out += bagio.vibration_msgs(chunk.vibration)
    out += [bagio.rebound_msg(r.stamp_s, r.velocity_mps) for _, r in chunk.rebounds]
    out += [bagio.point_msg(p.stamp_s, p.point_m) for _, p in chunk.points]
    out += list(extra_points)
    out += [
        (topics.IMPACT_TRUTH, topics.stamp_ns(s), bagio.string_msg(t)) for s, t in chunk.truths
    ]
    return out


def test_points_round_trip_through_a_bag_and_only_when_recorded(tmp_path):
    """Points read back from a bag as written (stamp, frame, coordinates); a bag without points
    has no impact_point connection."""
    with_points, without = recording(True), recording(False)
    bagio.write_bag(tmp_path / "points", chunk_records(with_points))
    bagio.write_bag(tmp_path / "plain", chunk_records(without))
    read = read_sensors(tmp_path / "points")
    assert len(read.points) == len(COMMANDS)
    for (stamp, frame, point), (_, simulated) in zip(read.points, with_points.points):
        assert frame == topics.FRAME_PLATE
        assert abs(stamp - simulated.stamp_s) < 1e-9  # s, through integer nanoseconds
        assert point.tolist() == simulated.point_m.tolist()
    assert [p[0] for p in read.points] == [r[0] for r in read.rebounds]
    with AnyReader([tmp_path / "plain"]) as reader:
        names = {c.topic for c in reader.connections}
    assert "/impact_point" not in names and "/rebound_velocity" in names
    assert read_sensors(tmp_path / "plain").points == []


def test_identify_uses_the_point_when_present_and_labels_as_before_without(tmp_path):
    """Without the point the labels carry no impact_* feature; with it each label carries its
    impact's point (within 5 sigma of where it struck), and a method that does not read it
    (threshold) labels exactly as without; the statistical method says when it decided with
    the point."""
    with_points, without = recording(True), recording(False)
    bagio.write_bag(tmp_path / "points", chunk_records(with_points))
    bagio.write_bag(tmp_path / "plain", chunk_records(without))
    plain = identify_bag(str(tmp_path / "plain"), "threshold", calibrate=False)
    pointed = identify_bag(str(tmp_path / "points"), "threshold", calibrate=False)
    assert len(plain) == len(pointed) == len(COMMANDS)
    for a, b, (_, command) in zip(plain, pointed, COMMANDS):
        assert "impact_x_m" not in a.features and "impact_y_m" not in a.features
        assert abs(b.features["impact_x_m"] - command["position_m"]) < 5 * NOISE_M
        assert abs(b.features["impact_y_m"]) < 5 * NOISE_M
        assert (a.impact_stamp_s, a.material, a.confidence) == (
            b.impact_stamp_s,
            b.material,
            b.confidence,
        )
        rest = {k: v for k, v in b.features.items() if not k.startswith("impact_")}
        assert rest == a.features
        assert a.signals == b.signals and "impact_point" not in b.signals
    statistical = identify_bag(str(tmp_path / "points"), "statistical", calibrate=False)
    plain = identify_bag(str(tmp_path / "plain"), "statistical", calibrate=False)
    assert [lab.impact_stamp_s for lab in statistical] == [lab.impact_stamp_s for lab in plain]
    for a, b in zip(plain, statistical):
        assert "impact_point" not in a.signals
        used = b.features.get("impact_point_used") == 1.0
        assert ("impact_point" in b.signals) == used
        if used:
            assert b.features["logit_without_point"] == a.features["logit"]


def hostile_points(chunk) -> dict[str, tuple]:
    """One hostile impact_point per case, stamped as a real rebound (or at none), by the name
    the refusal must give."""
    stamp = chunk.rebounds[1][1].stamp_s
    good = [0.8, 0.0, 0.0]

    def record(s, xyz, frame=topics.FRAME_PLATE):
        topic, ns, msg = bagio.point_msg(s, np.array(xyz, dtype=float))
        msg.header.frame_id = frame
        return topic, ns, msg

    return {
        "impact_point.point.x: must be a finite number": record(stamp, [math.nan, 0.0, 0.0]),
        "impact_point.point.y: must be a finite number": record(stamp, [0.5, math.inf, 0.0]),
        "impact_point.point.x: must be in [0, 1.6] m": record(stamp, [1.9, 0.0, 0.0]),
        "impact_point.point.y: must be in [-0.75, 0.75] m": record(stamp, [0.5, 0.9, 0.0]),
        "impact_point.point.z: must be 0 m": record(stamp, [0.5, 0.0, 0.2]),
        "impact_point.header.frame_id: must be 'tail_beam_plate'": record(
            stamp, good, "tail_beam_imu"
        ),
        "no rebound at its stamp": record(stamp + 0.05, good),
    }


def test_identify_refuses_each_hostile_point_by_name_and_labels_the_rest(tmp_path):
    """`tail-beam identify` on a bag holding hostile points names each one's field on stderr,
    exits 0 and labels the impacts as on the clean bag."""
    chunk = recording(False)
    hostile = hostile_points(chunk)
    bagio.write_bag(tmp_path / "clean", chunk_records(chunk))
    bagio.write_bag(tmp_path / "hostile", chunk_records(chunk, hostile.values()))
    runs = {
        name: subprocess.run(
            [str(BIN / "tail-beam"), "identify", str(tmp_path / name), "--no-calibrate"],
            capture_output=True,
            text=True,
            timeout=180,
        )
        for name in ("clean", "hostile")
    }
    for result in runs.values():
        assert result.returncode == 0 and "Traceback" not in result.stderr, result.stderr[-3000:]
    lines = [line for line in runs["hostile"].stderr.splitlines() if "impact_point" in line]
    for needle in hostile:
        assert any(needle in line and "1 message(s) set aside" in line for line in lines), (
            needle,
            lines,
        )
    labels = {
        name: [json.loads(line) for line in result.stdout.splitlines() if line.strip()]
        for name, result in runs.items()
    }
    assert [(lab["label"], lab["confidence"]) for lab in labels["hostile"]] == [
        (lab["label"], lab["confidence"]) for lab in labels["clean"]
    ]
    assert not any("impact_x_m" in lab["features"] for lab in labels["hostile"])
