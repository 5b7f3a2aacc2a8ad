"""``tail-beam identify BAG``: the id_node's identification, offline on a recorded bag.

Prints one ``label`` JSON object per line, in impact_stamp order. The identifier decides from
stamps and contents only, so these are the labels id_node publishes when the same bag is
replayed into it (``latency_ms`` aside, a wall-clock figure).
"""

from __future__ import annotations

import argparse
import json
import sys

from tail_beam_id.identifier import StreamIdentifier, available_methods
from tail_beam_id.replay import replay
from tail_beam_sim.bagread import read_sensors
from tail_beam_sim.cli.common import add_config_option
from tail_beam_sim.config import load_parameters
from tail_beam_sim.sensors import ImuStream, PressureStream, Rebound


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("identify", help="label every impact of a recorded bag (one JSON object per line)")
    parser.add_argument("bag", help="rosbag2 bag directory holding jack_pressure, imu and rebound_velocity")
    parser.add_argument("--method", choices=available_methods(), help="identification method (default: identification.method)")
    add_config_option(parser)
    parser.set_defaults(func=run)


def identify_bag(bag: str, method: str | None = None, config: list[str] | None = None) -> list[dict]:
    """Labels of every impact in ``bag``, in impact_stamp order."""
    params = load_parameters(config or [])
    data = read_sensors(bag)
    identifier = StreamIdentifier(method, params=params["identification"], model_params=params)
    pressure = PressureStream(data.pressure_stamp_s, data.pressure_pa, 0.0)
    imu = ImuStream(data.imu_stamp_s, data.angular_velocity_radps, data.linear_acceleration_mps2, 0.0, 0.0)
    rebounds = [Rebound(stamp, velocity, velocity) for stamp, velocity in data.rebounds]
    labels = replay(identifier, pressure, imu, rebounds)
    return sorted(labels, key=lambda label: label["impact_stamp"])


def run(args: argparse.Namespace) -> int:
    for label in identify_bag(args.bag, args.method, args.config):
        print(json.dumps(label))
    sys.stdout.flush()
    return 0
