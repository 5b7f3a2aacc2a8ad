"""Start-up parameters from a hostile or careless user: a --params-file that is no YAML or
is missing, a trailing -p, a value of the wrong type, and a parameter name no node has. Each
ends with one line naming it (exit status 2 for what stops the node), never a traceback, and a
name the node does not know is never ignored without a word."""

from __future__ import annotations

import subprocess
import sys

import pytest
from rclpy.parameter import Parameter
from rosprobe import ros_context

from tail_beam_sim.errors import InputError

pytestmark = [pytest.mark.ros]

MAINS = {
    "sim_node": "tail_beam_sim.ros.sim_node",
    "id_node": "tail_beam_id.ros.id_node",
    "bag_recorder": "tail_beam_sim.ros.recorder_node",
    "bag_replay": "tail_beam_sim.ros.replay_node",
}


def run_main(executable: str, *ros_args: str) -> subprocess.CompletedProcess:
    """The executable's main (of this checkout, not the installed scripts) with ``--ros-args``."""
    code = f"import sys; from {MAINS[executable]} import main; sys.exit(main())"
    return subprocess.run(
        [sys.executable, "-c", code, "--ros-args", *ros_args],
        capture_output=True,
        text=True,
        timeout=60,
    )


@pytest.mark.slow
@pytest.mark.parametrize("executable", sorted(MAINS))
def test_a_params_file_that_is_no_yaml_or_missing_is_one_line_and_exit_2(tmp_path, executable):
    """A --params-file that is not YAML, one that does not exist and a trailing -p (each of
    which rclpy.init refuses with an RCLError) end every executable with exit status 2 and one
    error line naming the file or argument, no traceback."""
    broken = tmp_path / "params.yaml"
    broken.write_text("a: [b\n  c: }\n")
    for args, needle in (
        (("--params-file", str(broken)), str(broken)),
        (("--params-file", str(tmp_path / "missing.yaml")), "missing.yaml"),
        (("-p",), "-p"),
    ):
        result = run_main(executable, *args)
        assert result.returncode == 2, (args, result.stderr)
        assert "Traceback" not in result.stderr, result.stderr
        lines = [
            line for line in result.stderr.splitlines() if line.startswith(f"{executable}: error:")
        ]
        assert len(lines) == 1 and needle in lines[0], result.stderr


def test_a_storage_of_the_wrong_type_is_named(tmp_path):
    """-p recorder.storage:=[1, 2] (a list where a name goes) or a number is refused at the
    recorder's start-up with the InputError naming recorder.storage, not a TypeError; the bag
    writer refuses a storage that is no name by itself too, for its other callers."""
    from tail_beam_sim.bags.write import SegmentedBagWriter

    with pytest.raises(InputError, match=r"storage = \[1, 2\]: must be one of mcap, sqlite3"):
        SegmentedBagWriter(tmp_path / "direct", [1, 2])
    from tail_beam_sim.ros.recorder_node import RecorderNode

    with ros_context() as (context, _):
        for value in ([1, 2], 3):
            overrides = [
                Parameter("recorder.bag_path", value=str(tmp_path / "bag")),
                Parameter("recorder.storage", value=value),
            ]
            with pytest.raises(
                InputError, match=r"recorder\.storage = .*must be (text|one of mcap, sqlite3)"
            ):
                RecorderNode(context=context, parameter_overrides=overrides)


def test_a_parameter_no_node_has_is_warned_not_ignored(capfd):
    """``-p id_node.pol_period_s:=0.05`` (a typo) or a --params-file key no node declares, which
    rclpy would drop without a word, is named in one warning; a parameter of another tail_beam
    node (a ``/**`` file shared by the suite) gets an information line instead, a parameter of
    the node itself neither, and the node starts either way."""
    from tail_beam_id.ros.id_node import IdNode

    overrides = [
        Parameter("id_node.pol_period_s", value=0.05),
        Parameter("sensors.imu_rate", value=5),
        Parameter("sim_node.realtime_factor", value=0.0),
        Parameter("id_node.poll_period_s", value=0.05),
    ]
    with ros_context() as (context, _):
        IdNode(context=context, parameter_overrides=overrides).destroy_node()
    err = capfd.readouterr().err
    warned = [line for line in err.splitlines() if "WARN" in line and "not a parameter of" in line]
    assert len(warned) == 1, err
    assert (
        "id_node.pol_period_s" in warned[0]
        and "sensors.imu_rate" in warned[0]
        and "realtime_factor" not in warned[0]
    ), warned
    assert "id_node.poll_period_s" not in warned[0]
    assert any(
        "INFO" in line and "sim_node.realtime_factor" in line for line in err.splitlines()
    ), err


@pytest.mark.parametrize(
    "name, value, allowed",
    [
        ("support.plate_material", [1, 2], "must be text"),
        ("stream.tier", [1, 2], "must be text"),
        ("sensors.vibration_block_samples", float("nan"), "must be a finite number"),
        ("sensors.vibration_oversample", float("nan"), "must be a finite number"),
        ("modes.stations_m", "abc", "must be a list of finite numbers"),
        ("modes.bending_1.shape", "abc", "must be a list of finite numbers"),
        ("sim_node.publish_clock", "yes", "must be true or false"),
    ],
)
def test_a_parameter_of_the_wrong_type_is_named_at_start_up(name, value, allowed):
    """A value of the wrong type for a parameter sim_node hands its models (a list where a name
    goes, NaN where a count goes, text where an array goes, text where a flag goes) is refused
    at start-up with the InputError naming the parameter and the type its default has, not a
    TypeError or ValueError from deep inside a model."""
    from tail_beam_sim.ros.sim_node import SimNode

    with ros_context() as (context, _):
        with pytest.raises(InputError, match=rf"{name} = .*{allowed}"):
            SimNode(context=context, parameter_overrides=[Parameter(name, value=value)])


@pytest.mark.slow
def test_a_value_the_models_cannot_take_ends_start_up_with_one_line():
    """-p modes.bending_1.frequency_hz:=1e308 is a finite number of the right type on which
    the modal model's matrices overflow. Whatever a model raises from the parameters given, the
    executable ends with exit status 2 and one error line naming the parameters set on its
    command line, no traceback."""
    result = run_main(
        "sim_node",
        "-p",
        "modes.bending_1.frequency_hz:=1e308",
        "-p",
        "sim_node.realtime_factor:=0",
    )
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.startswith("sim_node: error:")]
    assert len(lines) == 1 and "modes.bending_1.frequency_hz" in lines[0], result.stderr


def test_a_start_offset_past_any_bag_is_named(tmp_path):
    """-p replay.start_offset_s:=1e308, which would overflow as nanoseconds, is refused at
    bag_replay's start-up naming replay.start_offset_s and its range: the offset has an upper
    bound because a bag's log time is int64 ns (under 9.2e9 s)."""
    from bag_helpers import records, write_segments

    from tail_beam_sim.ros.replay_node import ReplayNode

    write_segments(tmp_path / "bag", [records(20)])
    with ros_context() as (context, _):
        overrides = [
            Parameter("replay.bag_path", value=str(tmp_path / "bag")),
            Parameter("replay.start_offset_s", value=1e308),
        ]
        with pytest.raises(
            InputError, match=r"replay\.start_offset_s = 1e\+308: must be in \[0, 1e\+09\] s"
        ):
            ReplayNode(context=context, parameter_overrides=overrides)


def test_a_looping_replay_whose_bag_went_away_stops_with_one_line(tmp_path):
    """bag_replay with replay.loop reopens its bag at each pass; a bag removed (or damaged at its
    start) meanwhile stops it as a bag found damaged part-way does: one logged line and exit
    status 1, no exception out of the timer."""
    import shutil

    from bag_helpers import records, write_segments
    from rosprobe import spin_until

    from tail_beam_sim.ros.replay_node import ReplayNode

    bag = tmp_path / "bag"
    write_segments(bag, [records(20)])
    with ros_context() as (context, executor):
        overrides = [
            Parameter("replay.bag_path", value=str(bag)),
            Parameter("replay.loop", value=True),
            Parameter("replay.rate", value=100.0),
            Parameter("replay.wait_for_subscribers", value=0),
        ]
        node = ReplayNode(context=context, parameter_overrides=overrides)
        executor.add_node(node)
        assert spin_until(executor, lambda: node.loops >= 1, timeout_s=20)
        shutil.rmtree(bag)
        assert spin_until(executor, node.finished.done, timeout_s=20)
    assert node.exit_status == 1


def test_id_node_takes_a_support_profiles_calibration_section():
    """A profile written by `tail-beam calibrate` holds a `calibration` section that no config/
    default declares. id_node given it takes that section (and does not warn of it), so it
    decides as calibrated, as `tail-beam identify --config profile.yaml` does, and the support's
    hysteresis the profile read reaches the statistical method; without it, uncalibrated."""
    from tail_beam_id.ros.id_node import IdNode

    weights = [0.0, 0.9, 0.1, 0.0, 0.0, 0.0]  # one per hysteresis bin of the shipped model
    overrides = [
        Parameter("calibration.rigid_mode_frequency_hz", value=38.1),
        Parameter("calibration.impacts_used", value=16),
        Parameter("calibration.ringing_modes_hz", value=[399.6, 1268.4]),
        Parameter("calibration.hysteresis_weights", value=weights),
        Parameter("support.oil_bulk_modulus_pa", value=2.01e9),
    ]
    with ros_context() as (context, _):
        node = IdNode(context=context, parameter_overrides=overrides)
        try:
            assert node.gated.identifier.calibrated
            assert node.get_parameter("calibration.ringing_modes_hz").value == [399.6, 1268.4]
            assert node.gated.identifier.method.hysteresis_weights == weights
        finally:
            node.destroy_node()
        plain = IdNode(context=context)
        try:
            assert not plain.gated.identifier.calibrated
        finally:
            plain.destroy_node()


def test_numbers_config_reads_as_text_take_numbers_and_the_shipped_files_load():
    """config/ writes 1.95e9 and the like, which PyYAML reads as text and rcl as a number: a
    number for such a parameter (a profile's oil_bulk_modulus_pa,
    -p support.setting_pressure_pa:=2.1e7) is taken, and so is every shipped parameter file
    given as --params-file (as rcl reads it); text that is no number is refused by name."""
    from tail_beam_id.ros.id_node import IdNode
    from tail_beam_sim.config import default_config_dir
    from tail_beam_sim.ros.sim_node import SimNode

    overrides = [
        Parameter("support.oil_bulk_modulus_pa", value=2.01e9),
        Parameter("support.setting_pressure_pa", value=2.1e7),
    ]
    with ros_context() as (context, _):
        IdNode(context=context, parameter_overrides=overrides).destroy_node()
        with pytest.raises(InputError, match="support.oil_bulk_modulus_pa"):
            IdNode(
                context=context,
                parameter_overrides=[Parameter("support.oil_bulk_modulus_pa", value="stiff")],
            )
    import rclpy

    files = sorted(
        f for f in default_config_dir().glob("*.yaml") if f.name != "impacts.yaml"
    )  # impacts: a scene list, not parameters
    context = rclpy.Context()
    rclpy.init(
        args=["--ros-args", *(a for f in files for a in ("--params-file", str(f)))],
        context=context,
    )
    try:
        SimNode(context=context).destroy_node()
        IdNode(context=context).destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


@pytest.mark.parametrize(
    "name, value, allowed",
    [
        ("max_bag_duration_s", 1e-9, r"must be in \[1, 1e\+07\] s, or 0 \(never split\)"),
        ("max_bag_duration_s", 1e-10, r"must be in \[1, 1e\+07\] s, or 0 \(never split\)"),
        ("max_bag_size_bytes", 1, r"must be an integer in \[1048576, \d+\] bytes, or 0"),
        ("max_bag_size_bytes", 1000.5, r"must be an integer in \[1048576, \d+\] bytes, or 0"),
    ],
)
def test_a_bag_split_too_small_or_not_whole_is_refused(tmp_path, name, value, allowed):
    """recorder.max_bag_duration_s and max_bag_size_bytes below 1 s and 1 MiB (a file per
    message, most messages lost), a duration that rounds to 0 ns, and a fractional byte count
    are refused at start-up, naming the field and its range; 0 (never split) is taken."""
    from tail_beam_sim.ros.recorder_node import RecorderNode

    with ros_context() as (context, _):
        overrides = [
            Parameter("recorder.bag_path", value=str(tmp_path / "bag")),
            Parameter(f"recorder.{name}", value=value),
        ]
        with pytest.raises(InputError, match=rf"recorder\.{name} = {value!r}: {allowed}"):
            RecorderNode(context=context, parameter_overrides=overrides)
        node = RecorderNode(
            context=context,
            parameter_overrides=[
                Parameter("recorder.bag_path", value=str(tmp_path / "kept")),
                Parameter(f"recorder.{name}", value=0),
            ],
        )
        try:
            assert node.writer.max_duration_ns == 0 and node.writer.max_size_bytes == 0
        finally:
            node.writer.close()
            node.destroy_node()


@pytest.mark.slow
def test_a_refused_bag_split_is_one_line_at_start_up(tmp_path):
    """bag_recorder with -p recorder.max_bag_size_bytes:=1 exits with status 2 and one line
    naming the field and its range, no traceback."""
    result = run_main(
        "bag_recorder",
        "-p",
        f"recorder.bag_path:={tmp_path / 'bag'}",
        "-p",
        "recorder.max_bag_size_bytes:=1",
    )
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr, result.stderr
    lines = [
        line for line in result.stderr.splitlines() if line.startswith("bag_recorder: error:")
    ]
    assert len(lines) == 1 and "recorder.max_bag_size_bytes = 1: must be" in lines[0], lines
    assert not (tmp_path / "bag").exists()


def replay_overrides(bag, **values) -> list[Parameter]:
    """Parameters of a ReplayNode playing ``bag``, with ``replay.<name>`` values."""
    return [Parameter("replay.bag_path", value=str(bag))] + [
        Parameter(f"replay.{name}", value=value) for name, value in values.items()
    ]


def test_a_replay_rate_outside_its_range_is_refused(tmp_path):
    """-p replay.rate:=1e-300 (a replay that never advances) and 1e6 are refused naming
    replay.rate and [0.01, 100]; 0.01 is taken."""
    from bag_helpers import records, write_segments

    from tail_beam_sim.ros.replay_node import ReplayNode

    write_segments(tmp_path / "bag", [records(20)])
    with ros_context() as (context, _):
        for rate in (1e-300, 1e6):
            with pytest.raises(InputError, match=r"replay\.rate = .*: must be in \[0\.01, 100\]$"):
                ReplayNode(
                    context=context,
                    parameter_overrides=replay_overrides(tmp_path / "bag", rate=rate),
                )
        node = ReplayNode(
            context=context, parameter_overrides=replay_overrides(tmp_path / "bag", rate=0.01)
        )
        assert node.rate == 0.01
        node.destroy_node()


def test_a_loop_over_one_instant_is_refused(tmp_path):
    """replay.loop over a bag whose messages are all at one log time (one pressure and one IMU
    sample) would start each pass again at once, a busy loop: it is refused at start-up naming
    replay.loop. The same bag without loop plays."""
    from bag_helpers import records, write_segments

    from tail_beam_sim.ros.replay_node import ReplayNode

    write_segments(tmp_path / "bag", [records(1)])
    with ros_context() as (context, _):
        with pytest.raises(InputError, match=r"replay\.loop = True: needs messages .* span"):
            ReplayNode(
                context=context, parameter_overrides=replay_overrides(tmp_path / "bag", loop=True)
            )
        ReplayNode(context=context, parameter_overrides=replay_overrides(tmp_path / "bag"))


def test_a_start_offset_past_the_bags_end_names_its_duration(tmp_path):
    """replay.start_offset_s beyond the bag's last message is refused naming the offset and the
    log time the bag's messages span (not as a bag that holds no messages on replay.topics)."""
    from bag_helpers import RATE_HZ, records, write_segments

    from tail_beam_sim.ros.replay_node import ReplayNode

    write_segments(tmp_path / "bag", [records(20)])
    span = f"{19 / RATE_HZ:g}"
    with ros_context() as (context, _):
        with pytest.raises(
            InputError,
            match=rf"replay\.start_offset_s = 50\.0: is past the end of the bag: .* span {span} s",
        ):
            ReplayNode(
                context=context,
                parameter_overrides=replay_overrides(tmp_path / "bag", start_offset_s=50.0),
            )
