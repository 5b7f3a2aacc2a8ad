"""`tail-beam simulate` as a user runs it: JSON summary, rosbag2 output, figure, and bad input."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from tail_beam_sim.cli import main

REQUIRED_KEYS = {
    "material",
    "radius_m",
    "position_m",
    "impact_speed_mps",
    "rebound_speed_mps",
    "restitution",
    "contact_duration_s",
    "peak_contact_force_n",
    "peak_jack_pressure_change_pa",
    "peak_beam_angular_velocity_radps",
    "peak_imu_dynamic_accel_mps2",
    "n_contacts",
}
CONTRACT_TYPES = {
    "impact_cmd": "std_msgs/msg/String",
    "jack_pressure": "sensor_msgs/msg/FluidPressure",
    "imu": "sensor_msgs/msg/Imu",
    "rebound_velocity": "geometry_msgs/msg/TwistStamped",
    "impact_truth": "std_msgs/msg/String",
}


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    """Run `tail-beam` in-process; argparse's own errors exit through SystemExit."""
    try:
        code = main(list(argv))
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def test_json_summary_has_the_documented_keys(capsys):
    """`simulate --json` prints one object with every documented key, and its restitution is
    rebound over impact speed."""
    code, out, _ = run_cli(
        capsys,
        "simulate",
        "--material",
        "coal",
        "--radius-m",
        "0.025",
        "--drop-height-m",
        "3.5",
        "--position-m",
        "1.0",
        "--json",
    )
    assert code == 0
    summary = json.loads(out)
    assert REQUIRED_KEYS <= set(summary)
    assert summary["material"] == "coal" and summary["n_contacts"] >= 1
    assert summary["restitution"] == pytest.approx(
        summary["rebound_speed_mps"] / summary["impact_speed_mps"]
    )


def test_impact_speed_option_reproduces_the_study_speed(capsys):
    """The study's 3.5 m case used 8.368 m/s, which no height gives: the speed can be commanded."""
    code, out, _ = run_cli(capsys, "simulate", "--impact-speed-mps", "8.368", "--json")
    assert code == 0
    summary = json.loads(out)
    assert summary["impact_speed_mps"] == 8.368 and summary["drop_height_m"] is None


def _read_bag(path: Path) -> dict[str, list]:
    store = get_typestore(Stores.ROS2_KILTED)
    messages: dict[str, list] = {}
    with AnyReader([path], default_typestore=store) as reader:
        assert all(
            c.topic.startswith("/") for c in reader.connections
        )  # fully qualified, as rosbag2 stores them
        types = {c.topic[1:]: c.msgtype for c in reader.connections}
        for connection, log_ns, raw in reader.messages():
            messages.setdefault(connection.topic[1:], []).append(
                (log_ns, reader.deserialize(raw, connection.msgtype))
            )
    messages["_types"] = types  # type: ignore[assignment]
    return messages


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_bag_reads_back_with_contract_topics_types_units_and_stamps(tmp_path, capsys, storage):
    """A simulated bag reads back with the contract's topics and types, pressure in Pa at 2 kHz
    stamps, IMU per REP 145, one rebound and a truth agreeing with the summary."""
    bag = tmp_path / "impact"
    code, out, _ = run_cli(
        capsys,
        "simulate",
        "--material",
        "sandstone",
        "--bag",
        str(bag),
        "--storage",
        storage,
        "--json",
    )
    assert code == 0
    summary = json.loads(out)
    messages = _read_bag(bag)
    types = messages.pop("_types")
    for topic, msgtype in CONTRACT_TYPES.items():
        assert types[topic] == msgtype

    pressure = messages["jack_pressure"]
    stamps = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for _, m in pressure])
    values = np.array([m.fluid_pressure for _, m in pressure])
    # Units: absolute pressure in Pa around the 20 MPa setting; stamps at the configured 2 kHz.
    assert np.all(np.abs(values - 20e6) < 1e6)
    assert np.allclose(np.diff(stamps), 1 / 2000.0, atol=2e-9)
    assert all(
        m.header.frame_id == "tail_beam_jack" and m.variance == pytest.approx(1e8)
        for _, m in pressure
    )
    assert [t for t, _ in pressure] == [int(round(s * 1e9)) for s in stamps]

    imu = [m for _, m in messages["imu"]]
    accel_z = np.array([m.linear_acceleration.z for m in imu])
    # REP 145: a plate at rest reads +g along its upward axis; no orientation estimate.
    assert np.median(accel_z) == pytest.approx(9.81, abs=0.1)
    assert all(
        m.orientation_covariance[0] == -1 and m.header.frame_id == "tail_beam_imu" for m in imu
    )

    ((_, rebound),) = messages["rebound_velocity"]
    truth = json.loads(messages["impact_truth"][0][1].data)
    rebound_stamp = rebound.header.stamp.sec + rebound.header.stamp.nanosec * 1e-9
    # The camera stamps the end of contact to within its frame period (5 kHz).
    assert 0 <= rebound_stamp - truth["final_separation_stamp"] <= 1 / 5000.0 + 1e-9
    assert rebound.header.frame_id == "tail_beam_plate"
    assert rebound.twist.linear.z == pytest.approx(summary["rebound_speed_mps"], abs=0.5)
    assert truth["material"] == "sandstone" and truth["label"] == "gangue"
    assert truth["contact_start_stamp"] < truth["contact_end_stamp"] <= rebound_stamp
    command = json.loads(messages["impact_cmd"][0][1].data)
    assert command["material"] == "sandstone" and command["drop_height_m"] == 3.5


def test_bag_decodes_with_an_independent_mcap_reader(tmp_path, capsys):
    """Not only rosbags: the mcap project's own ROS 2 decoder reads the same bag."""
    mcap_reader = pytest.importorskip("mcap.reader")
    decoder = pytest.importorskip("mcap_ros2.decoder")
    bag = tmp_path / "impact"
    assert run_cli(capsys, "simulate", "--bag", str(bag))[0] == 0
    (mcap_file,) = bag.glob("*.mcap")
    counts: dict[str, int] = {}
    with mcap_file.open("rb") as stream:
        reader = mcap_reader.make_reader(stream, decoder_factories=[decoder.DecoderFactory()])
        for _, channel, _, msg in reader.iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "/jack_pressure":
                assert 19e6 < msg.fluid_pressure < 21e6
    assert (
        counts["/jack_pressure"] > 100
        and counts["/rebound_velocity"] == 1
        and counts["/vibration"] > 5
    )


def test_plot_writes_a_png(tmp_path, capsys):
    """`simulate --plot` writes a real PNG file (signature and non-trivial size)."""
    png = tmp_path / "response.png"
    assert run_cli(capsys, "simulate", "--plot", str(png))[0] == 0
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000


BAD_INPUT = [
    (["--radius-m", "-0.01"], "radius_m", "[0.001, 0.5]"),
    (["--radius-m", "nan"], "radius_m", "[0.001, 0.5] m (a finite number)"),
    (["--material", "granite"], "material", "coal"),
    (["--position-m", "1.7"], "position_m", "[0, 1.6]"),
    (["--drop-height-m", "0"], "drop_height_m", "[0.001, 50]"),
    (["--drop-height-m", "2", "--impact-speed-mps", "6"], "impact-speed-mps", "not allowed"),
    (["--config", "/nonexistent/params.yaml"], "config", "readable"),
]


@pytest.mark.parametrize(("argv", "field", "allowed"), BAD_INPUT)
def test_bad_input_exits_2_with_one_line_naming_field_and_range(capsys, argv, field, allowed):
    """Each bad option exits 2 with one stderr line naming the field and its allowed range, no
    traceback."""
    code, _, err = run_cli(capsys, "simulate", *argv)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and field in lines[0] and allowed in lines[0], err
    assert "Traceback" not in err


def test_missing_height_and_speed_is_an_error(tmp_path, capsys):
    """A config whose scene gives neither drop_height_m nor impact_speed_mps: exactly one is
    required."""
    config = tmp_path / "no_height.yaml"
    config.write_text("/**:\n  ros__parameters:\n    scene:\n      drop_height_m: null\n")
    code, _, err = run_cli(capsys, "simulate", "--config", str(config))
    assert code == 2 and "exactly one" in err


def test_unreadable_yaml_config_is_reported(tmp_path, capsys):
    """A --config file that is not valid YAML exits 2 with one line saying so."""
    config = tmp_path / "broken.yaml"
    config.write_text("/**: [unclosed\n")
    code, _, err = run_cli(capsys, "simulate", "--config", str(config))
    assert code == 2 and "valid YAML" in err and len(err.strip().splitlines()) == 1


def test_installed_console_script_reports_bad_input_without_traceback():
    """The real `tail-beam` executable, as a user runs it."""
    exe = Path(sys.executable).parent / "tail-beam"
    proc = subprocess.run(
        [str(exe), "simulate", "--radius-m", "-1"], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 2
    assert (
        proc.stderr.strip()
        == "tail-beam simulate: error: radius_m = '-1': must be in [0.001, 0.5] m"
    )
