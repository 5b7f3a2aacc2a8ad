"""``tail-beam identify BAG``: the id_node's identification, offline on a recorded bag.

Prints one ``label`` JSON object per line, in impact_stamp order. By default
(``identification.self_calibrate``) it first calibrates to the bag's own support (tail-beam
calibrate: no labels needed) and says on stderr what it measured. With ``--no-calibrate`` the
labels are the ones id_node publishes (by default uncalibrated) when the same bag is replayed
into it (``latency_ms`` aside, a wall-clock figure): the identifier decides from stamps and
contents only.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from tail_beam_id.calibration.offline import SupportProfile, with_profile
from tail_beam_id.calibration.offline import calibrate as calibrate_support
from tail_beam_id.methods import available_methods
from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.label import Label, Revisions, match_tolerance_s
from tail_beam_id.stream.replay import replay
from tail_beam_id.stream.share import GangueShare
from tail_beam_id.stream.share_reader import SharingIdentifier
from tail_beam_sim.bags.read import IDENTIFY_TOPICS, BagSensors, open_segments_note, read_runs
from tail_beam_sim.cli.common import add_config_option
from tail_beam_sim.config import load_parameters
from tail_beam_sim.errors import open_output_file, require_output_file
from tail_beam_sim.physics.sensors import ImuStream, PressureStream, Rebound


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "identify", help="label every impact of a recorded bag (one JSON object per line)"
    )
    parser.add_argument(
        "bag",
        help=(
            "rosbag2 bag directory holding the support's jack_pressure, imu, vibration and/or "
            "rebound_velocity"
        ),
    )
    parser.add_argument(
        "--method",
        choices=available_methods(),
        help="identification method (default: identification.method)",
    )
    parser.add_argument(
        "--calibrate",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="calibrate to the bag's own support first (tail-beam calibrate), then identify "
        "(default: identification.self_calibrate, on); --no-calibrate gives id_node's labels",
    )
    parser.add_argument(
        "--namespace", help="the support to identify when the bag holds several, e.g. /support_07"
    )
    parser.add_argument(
        "--shares",
        metavar="PATH",
        help="also write the flow's gangue share per sliding interval to PATH, one JSON object "
        "per line (the gangue_share messages id_node publishes; docs/gangue_share.md)",
    )
    add_config_option(parser)
    parser.set_defaults(func=run)


def identify_bag(
    bag: str,
    method: str | None = None,
    config: list[str] | None = None,
    calibrate: bool | None = None,
    namespace: str | None = None,
    shares: list[GangueShare] | None = None,
) -> list[dict]:
    """Labels of every impact in ``bag`` (of the support ``namespace`` when it holds several),
    in impact_stamp order; with ``calibrate`` (default: ``identification.self_calibrate``), on
    the bag's own support profile (labels say ``calibrated``). Any one of the sensor topics will
    do, as for id_node (the labels' ``signals`` say which were used). Gaps in the vibration's
    running index and repeated samples are reported on stderr. A bag holding several time bases
    (a restarted simulator) is identified run by run, as id_node starts afresh at each: the
    labels of each run in turn, each run in impact_stamp order. ``shares``, when given, receives
    the gangue share of every interval, as id_node publishes them."""
    params = load_parameters(config or [])
    check_settings(params, method)
    runs = read_runs(bag, required=(), namespace=namespace, any_of=IDENTIFY_TOPICS)
    report_reading(runs[0], "identify", len(runs), bag)
    if calibrate is None:
        calibrate = bool(params["identification"].get("self_calibrate", False))
    labels: list[Label] = []
    for data in runs:
        run_params = params
        if calibrate:
            try:
                profile = profile_of(data, params)
            except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
                # Self-calibration is a refinement: a recording it cannot read is still identified,
                # on the configured support, and the reason is said.
                print(
                    f"identify: {data.namespace} self-calibration failed ({type(exc).__name__}: "
                    f"{exc}); identified on the "
                    "configured support (labels say calibrated: false)",
                    file=sys.stderr,
                )
            else:
                print(f"identify: {data.namespace} {describe_profile(profile)}", file=sys.stderr)
                run_params = with_profile(params, profile)
        labels += identify_sensors(data, run_params, method, shares=shares)
    return labels


def check_settings(params: dict[str, Any], method: str | None = None) -> None:
    """Refuse bad identification settings (method, model, detection, sensor_timing, ...) by
    name before a bag is read, not after a pass over it."""
    StreamIdentifier(method, params=params.get("identification"), model_params=params)


def report_reading(data: BagSensors, verb: str, runs: int = 1, bag: str | None = None) -> None:
    """Say on stderr what reading the bag left out: segments a recorder left open (``bag``:
    its path), vibration samples missing from the running index, samples recorded twice at one
    stamp; and where a new time base begins within the bag (each run is then taken alone,
    ``runs`` of them, as id_node starts afresh there)."""
    note = open_segments_note(bag) if bag is not None else None
    if note:
        print(f"{verb}: {note}", file=sys.stderr)
    if data.vibration_gaps:
        print(
            f"{verb}: {data.namespace} vibration: {len(data.vibration_gaps)} gap(s), "
            f"{data.vibration_lost_samples} samples lost "
            f"(first missing index {data.vibration_gaps[0][0]})",
            file=sys.stderr,
        )
    for name, n in data.repeated_samples.items():
        print(
            f"{verb}: {data.namespace} {name}: {n} sample(s) at a stamp already read left out "
            "(the first kept)",
            file=sys.stderr,
        )
    for what, n in data.set_aside.items():
        print(
            f"{verb}: {data.namespace} {what}: {n} message(s) set aside, the rest read",
            file=sys.stderr,
        )
    for name, (log_s, back_s) in data.time_jumps.items():
        moved = f"go back {back_s:.3f} s" if back_s > 0 else f"jump ahead {-back_s:.3f} s"
        print(
            f"{verb}: {data.namespace} {name}: stamps {moved} at log time {log_s:.3f} s (a "
            f"restarted simulator, a looped replay or a new clock): {runs} runs, each taken "
            "alone as id_node starts afresh there",
            file=sys.stderr,
        )


def describe_profile(profile: SupportProfile) -> str:
    """One line on what self-calibration measured (or that it kept config/)."""
    if not profile.calibrated:
        return (
            "self-calibration: no clear sway of the beam in the jack pressure (too few impacts, "
            "or too short); "
            "identified on the configured support (labels say calibrated: false)"
        )
    gain = (
        f"{profile.impacts_used} impacts for the IMU gain"
        if profile.beam_inertia_about_hinge_kgm2
        else "IMU gain not measured"
    )
    return (
        f"self-calibration: sway {profile.rigid_mode_frequency_hz:.2f} Hz, oil bulk modulus "
        f"{profile.oil_bulk_modulus_pa:.3g} Pa, "
        f"{gain}, {profile.describe_modes()}, {profile.describe_camera()}, "
        f"{profile.describe_hysteresis()} (labels say calibrated: true; --no-calibrate for "
        "id_node's uncalibrated labels)"
    )


def identify_sensors(
    data: BagSensors,
    params: dict[str, Any],
    method: str | None = None,
    phase: str = "identifying",
    report: bool = True,
    shares: list[GangueShare] | None = None,
) -> list[Label]:
    """Labels of the bag's sensor data under ``params``, in impact_stamp order; on a terminal,
    a progress line on stderr (``phase``) while a long recording is worked through. With
    ``report`` the samples and rebounds left out (not finite) are said on stderr: once per bag,
    not again for self-calibration's pass over the same data. ``shares``, when given, receives
    the flow's gangue share per interval (tail_beam_id.stream.share_reader)."""
    identifier = SharingIdentifier(method, params=params["identification"], model_params=params)
    pressure = PressureStream(data.pressure_stamp_s, data.pressure_pa, 0.0)
    imu = ImuStream(
        data.imu_stamp_s, data.angular_velocity_radps, data.linear_acceleration_mps2, 0.0, 0.0
    )
    rebounds = [Rebound(stamp, velocity, velocity) for stamp, velocity in data.rebounds]
    vibration = data.vibration if data.vibration.count else None
    line = ProgressLine(sys.stderr, f"identify: {data.namespace} {phase}")
    labels = replay(identifier, pressure, imu, rebounds, vibration=vibration, progress=line.update)
    line.close()
    if shares is not None:
        shares += identifier.take_shares()
    # One impact, one label, as id_node publishes them (tail_beam_id.stream.label.Revisions).
    rule = Revisions(match_tolerance_s(params["identification"]))
    labels = [rule.admit(label) for label in labels]
    if report and rule.revisions:
        print(
            f"identify: {data.namespace} {rule.revisions} revision(s): later decisions for an "
            f'impact already labelled, printed with "revises" ({rule.changed} changed the '
            "material)",
            file=sys.stderr,
        )
    if not report:
        return sorted(labels, key=lambda label: label.impact_stamp_s)
    refused = {name: n for name, n in identifier.refused_samples.items() if n}
    for name, n in refused.items():
        print(
            f"identify: {data.namespace} {name}: {n} sample(s) with a non-finite stamp or value "
            "left out",
            file=sys.stderr,
        )
    if identifier.refused_rebounds:
        print(
            f"identify: {data.namespace} rebound_velocity: {identifier.refused_rebounds} "
            "message(s) with a non-finite "
            "stamp or velocity left out",
            file=sys.stderr,
        )
    if identifier.timing.suspect:
        print(
            f"identify: {data.namespace} sensor timing: {identifier.timing.describe()}",
            file=sys.stderr,
        )
    return sorted(labels, key=lambda label: label.impact_stamp_s)


def profile_of(data: BagSensors, params: dict[str, Any]) -> SupportProfile:
    """The support profile of a bag's sensor data (tail_beam_id.calibration.offline)."""
    accel_z = (
        data.linear_acceleration_mps2[:, 2] if data.linear_acceleration_mps2.size else np.zeros(0)
    )
    ringing = (
        (data.vibration.sample_stamps_s(), data.vibration.accel_mps2)
        if data.vibration.count
        else None
    )
    return calibrate_support(
        params,
        (data.pressure_stamp_s, data.pressure_pa),
        (data.imu_stamp_s, accel_z),
        lambda calibrated: identify_sensors(
            data, calibrated, "statistical", phase="self-calibrating", report=False
        ),
        ringing,
        [stamp for stamp, _ in data.rebounds],
    )


class ProgressLine:
    """One line on a terminal that says how far a long pass through a recording got (rewritten
    in place); nothing when the stream is no terminal (a pipe, a log, a test) or the recording
    is shorter than MIN_PROGRESS_S of stamp time."""

    MIN_PROGRESS_S = 60.0

    def __init__(self, stream: Any, what: str) -> None:
        self.stream = stream
        self.what = what
        self.shown = False
        self.enabled = bool(getattr(stream, "isatty", lambda: False)())

    def update(self, done_s: float, total_s: float) -> None:
        if not self.enabled or total_s < self.MIN_PROGRESS_S:
            return
        self.stream.write(
            f"\r{self.what}: {done_s:.0f} of {total_s:.0f} s of data "
            f"({100.0 * done_s / total_s:.0f} %)"
        )
        self.stream.flush()
        self.shown = True

    def close(self) -> None:
        if self.shown:
            self.stream.write("\n")
            self.stream.flush()


def run(args: argparse.Namespace) -> int:
    if args.shares:
        require_output_file("--shares", Path(args.shares))
    shares: list[GangueShare] = []
    for label in identify_bag(
        args.bag, args.method, args.config, args.calibrate, args.namespace, shares
    ):
        print(label.to_json())
    sys.stdout.flush()
    if args.shares:
        with open_output_file("--shares", Path(args.shares)) as handle:
            for share in shares:
                handle.write((share.to_json() + "\n").encode())
    return 0
