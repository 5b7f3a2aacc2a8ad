"""``tail-beam calibrate BAG``: a support profile from the support's own recording, no labels.

Writes a ROS 2 parameter file (``--out``, default: printed) that ``tail-beam identify --config``
and ``id_node --ros-args --params-file`` load; see tail_beam_id.calibration.offline for what it
measures and how.
"""

from __future__ import annotations

import argparse
import sys

import yaml

from tail_beam_id.cli.identify_cmd import check_settings, profile_of, report_reading
from tail_beam_sim import topics
from tail_beam_sim.bags.read import read_runs
from tail_beam_sim.cli.common import add_config_option
from tail_beam_sim.config import load_parameters
from tail_beam_sim.errors import InputError, open_output_file, require_output_file


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "calibrate",
        help=(
            "learn a support profile (jack gain, IMU gain and mounting, ringing, noise) from a bag"
        ),
    )
    parser.add_argument(
        "bag", help="rosbag2 bag of the support: jack_pressure and imu, with some impacts"
    )
    parser.add_argument(
        "--out", help="write the profile here (a ROS 2 parameter file); default: print it"
    )
    parser.add_argument(
        "--namespace", help="the support to calibrate when the bag holds several, e.g. /support_07"
    )
    add_config_option(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    params = load_parameters(args.config)
    out = (
        require_output_file("--out", args.out) if args.out else None
    )  # before the work, not after
    check_settings(params)
    # What calibration reads: the jack pressure (the sway) and the IMU (mounting, gain); either
    # will do (tail_beam_id.calibration.offline.calibrate), the camera is not needed.
    runs = read_runs(
        args.bag, required=(), namespace=args.namespace, any_of=(topics.JACK_PRESSURE, topics.IMU)
    )
    report_reading(runs[0], "calibrate", len(runs), args.bag)
    # Several time bases (a restarted simulator): the longest run is the support's recording.
    data = max(runs, key=lambda run: run.pressure_stamp_s.size + run.imu_stamp_s.size)
    if len(runs) > 1:
        print(
            f"calibrate: {data.namespace} calibrated on run {runs.index(data) + 1} of "
            f"{len(runs)}, the longest",
            file=sys.stderr,
        )
    profile = profile_of(data, params)
    text = yaml.safe_dump(profile.parameters(), sort_keys=False)
    if out is not None:
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(
                "--out", str(out), f"its folder cannot be made ({exc.strerror or exc})"
            ) from None
        try:
            with open_output_file("--out", out) as stream:
                stream.write(text.encode("utf-8"))
        except OSError as exc:  # a full disk or device: tail-beam says it, naming the file
            raise OSError(exc.errno, exc.strerror, str(out)) from None
        print(f"wrote {out}", file=sys.stderr)
    else:
        sys.stdout.write(text)
    c = profile
    if not c.calibrated:
        print(
            "calibrate: no clear sway of the beam in the jack pressure (too few impacts, or too "
            "short): "
            f"the profile holds the noise, mounting and camera frame only ({c.describe_camera()})",
            file=sys.stderr,
        )
    else:
        print(
            f"calibrate: sway {c.rigid_mode_frequency_hz:.2f} Hz, {c.impacts_used} impacts for "
            "the IMU gain, "
            f"mount sign {c.imu_mount_sign}, {c.describe_modes()}, {c.describe_camera()}, "
            f"{c.describe_hysteresis()}, {c.describe_predictor()}",
            file=sys.stderr,
        )
    return 0
