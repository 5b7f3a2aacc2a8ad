"""``tail-beam send``: hand one impact command, or a YAML list of them, to a running sim_node.

Every command is validated first, as sim_node will validate it (``Impact.from_mapping`` over the
same config files, and the same JSON reader), so bad input exits 2 with nothing sent. Then the
client waits for a simulator, lets discovery settle, publishes reliably and waits for the
acknowledgement (:mod:`tail_beam_sim.ros.client`): a command is never lost unseen, as one
published right after discovery can be. ``--wait-truth`` also waits for each command's
``impact_truth`` (printed, one JSON object per line) and reports the commands sim_node refused.

Exit status: 0 sent (and, with ``--wait-truth``, every truth received); 2 bad input, nothing
sent; 4 no simulator within ``--timeout-s``, no acknowledgement, or truths missing; 5 the
simulator refused a command; 130 interrupted.
"""

from __future__ import annotations

import argparse
import json
import secrets
import sys
from collections.abc import Mapping
from typing import Any

from tail_beam_sim.cli import EXIT_REFUSED, EXIT_TIMEOUT
from tail_beam_sim.cli.common import add_config_option
from tail_beam_sim.config import default_config_dir, load_parameters, read_yaml_file, section
from tail_beam_sim.errors import InputError, require_range, shorten
from tail_beam_sim.physics.command import parse_command
from tail_beam_sim.physics.materials import material_table
from tail_beam_sim.physics.scenario import (
    check_impacts,
    read_scenario_file,
    resolve_scenario_file,
)
from tail_beam_sim.physics.scene import Impact
from tail_beam_sim.physics.support import Support

NUMBER_FIELDS = ("radius_m", "drop_height_m", "impact_speed_mps", "position_m", "restitution")
MAX_TIMEOUT_S = 86_400.0  # a day: longer is a typo


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "send",
        help="send impact commands to a running sim_node, reliably (one, or a YAML list)",
        description=(
            "Send one impact command (the options) or a YAML list (--file) to a running "
            "sim_node: "
            "validated first, sent once the simulator is discovered and settled, acknowledged "
            "before exiting."
        ),
    )
    parser.add_argument(
        "--file",
        metavar="YAML",
        help="a list of impact_cmd objects (or impacts: [...]), e.g. config/impacts.yaml; "
        "contact_stamp_s items are ignored (the simulator schedules sent commands itself)",
    )
    parser.add_argument("--material", help="particle material from the config's material table")
    parser.add_argument("--radius-m", help="equivalent sphere radius, m")
    height = parser.add_mutually_exclusive_group()
    height.add_argument("--drop-height-m", help="free-fall height above the contact point, m")
    height.add_argument(
        "--impact-speed-mps", help="speed at first contact, m/s (instead of a height)"
    )
    parser.add_argument("--position-m", help="impact point along the plate from the hinge, m")
    parser.add_argument(
        "--restitution",
        help="particle's coefficient of restitution on steel (default: the material's)",
    )
    parser.add_argument(
        "--impact-id",
        help=(
            "the command's impact_id (default: the simulator makes one; with --wait-truth, this "
            "client does)"
        ),
    )
    parser.add_argument(
        "--namespace",
        default="/",
        help="the support's namespace, as sim_node's -r __ns:= (default /)",
    )
    parser.add_argument(
        "--timeout-s",
        help="how long to wait for a simulator, s (default send.timeout_s of config/send.yaml)",
    )
    parser.add_argument(
        "--wait-truth",
        action="store_true",
        help=(
            "wait for each command's impact_truth, print it (one JSON object per line) and "
            "report refusals"
        ),
    )
    parser.add_argument(
        "--truth-timeout-s",
        help="with --wait-truth: longest wait for the next truth or refusal, s "
        "(default send.truth_timeout_s of config/send.yaml)",
    )
    add_config_option(parser)
    parser.set_defaults(func=run)


def option_command(
    args: argparse.Namespace, materials: Mapping[str, Any], support: Support
) -> dict[str, Any]:
    """The one impact_cmd the options give, with numbers as numbers (validated)."""
    given = {
        "material": args.material,
        "radius_m": args.radius_m,
        "drop_height_m": args.drop_height_m,
        "impact_speed_mps": args.impact_speed_mps,
        "position_m": args.position_m,
        "restitution": args.restitution,
        "impact_id": args.impact_id,
    }
    given = {k: v for k, v in given.items() if v is not None}
    Impact.from_mapping(
        given, materials, support, text_numbers=True
    )  # the messages name the range
    return {k: float(v) if k in NUMBER_FIELDS else v for k, v in given.items()}


def read_commands(args: argparse.Namespace, params: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The commands to send, each validated as sim_node will validate its JSON text."""
    materials = material_table(params)
    support = Support.from_params(section(params, "support"), materials)
    options = [
        f"--{name.replace('_', '-')}"
        for name in (
            "material",
            "radius_m",
            "drop_height_m",
            "impact_speed_mps",
            "position_m",
            "restitution",
            "impact_id",
        )
        if getattr(args, name) is not None
    ]
    if args.file is not None and options:
        raise InputError(
            "--file",
            args.file,
            f"give either --file or the impact options, not both ({', '.join(options)} given)",
        )
    if args.file is not None:
        # The file checked by the suite's bounded reader first (size, encoding, nesting,
        # anchors): a hostile file is one line naming it, not a traceback or all of memory.
        read_yaml_file(resolve_scenario_file(args.file), "--file")
        commands = [
            item.command for item in read_scenario_file(args.file, field="--file", item="impacts")
        ]
        if not commands:
            raise InputError("--file", args.file, "holds no impacts")
        check_impacts(commands, materials, support, item="impacts")
    elif options:
        commands = [option_command(args, materials, support)]
    else:
        raise InputError(
            "--file",
            None,
            "give --file YAML, or the impact options (--material, --radius-m, --drop-height-m or "
            "--impact-speed-mps, --position-m)",
        )
    for index, command in enumerate(commands):
        text = json.dumps(command)  # exactly what goes out, through sim_node's own reader
        prefix = f"impacts[{index}]." if args.file is not None else ""
        Impact.from_mapping(parse_command(text), materials, support, prefix=prefix)
    return commands


def timeouts(args: argparse.Namespace, params: Mapping[str, Any]) -> tuple[float, float, float]:
    """(simulator timeout, truth timeout, settle time), s: the options, else config/send.yaml and
    sim_node.subscriber_settle_s."""
    send = section(params, "send")
    timeout = require_range(
        "--timeout-s",
        args.timeout_s if args.timeout_s is not None else send.get("timeout_s"),
        0.0,
        MAX_TIMEOUT_S,
        low_open=True,
        unit="s",
    )
    truth = require_range(
        "--truth-timeout-s",
        args.truth_timeout_s if args.truth_timeout_s is not None else send.get("truth_timeout_s"),
        0.0,
        MAX_TIMEOUT_S,
        low_open=True,
        unit="s",
    )
    settle = require_range(
        "sim_node.subscriber_settle_s",
        section(params, "sim_node").get("subscriber_settle_s"),
        0.0,
        60.0,
        unit="s",
    )
    return timeout, truth, settle


def run(args: argparse.Namespace) -> int:
    config_dir = default_config_dir()
    params = load_parameters(
        [config_dir / "sim_node.yaml", config_dir / "send.yaml", *args.config]
    )
    commands = read_commands(args, params)
    timeout_s, truth_timeout_s, settle_s = timeouts(args, params)
    if args.wait_truth:  # a truth is matched by its impact_id: give each command one
        run_tag = secrets.token_hex(3)
        commands = [
            c if "impact_id" in c else {**c, "impact_id": f"send-{run_tag}-{k + 1}"}
            for k, c in enumerate(commands)
        ]

    from tail_beam_sim.ros.client import (
        NoSimulator,
        NotAcknowledged,
        check_namespace,
        send_commands,
    )  # rclpy only once input is good

    namespace = check_namespace(args.namespace)

    def on_truth(truth: dict[str, Any]) -> None:
        print(json.dumps(truth), flush=True)

    def on_refusal(impact_id: str, line: str) -> None:
        print(
            f"tail-beam send: impact_id {shorten(impact_id)} refused by the simulator: {line}",
            file=sys.stderr,
            flush=True,
        )

    try:
        outcome = send_commands(
            commands,
            namespace=namespace,
            timeout_s=timeout_s,
            settle_s=settle_s,
            truth_timeout_s=truth_timeout_s if args.wait_truth else None,
            on_truth=on_truth,
            on_refusal=on_refusal,
        )
    except (NoSimulator, NotAcknowledged) as exc:
        print(f"tail-beam send: error: {exc}", file=sys.stderr)
        return EXIT_TIMEOUT
    where = ", ".join(outcome.simulators)
    if not args.wait_truth:
        print(
            f"tail-beam send: {len(commands)} command(s) acknowledged by {where}", file=sys.stderr
        )
        return 0
    if outcome.missing or outcome.refused:
        parts = []
        if outcome.missing:
            ids = ", ".join(shorten(i) for i in outcome.missing)
            parts.append(
                f"no impact_truth for {len(outcome.missing)} of {len(commands)} command(s) within "
                f"{truth_timeout_s:g} s "
                f"of the last answer from {where}: impact_id {ids}"
            )
        if outcome.refused:
            parts.append(
                f"{len(outcome.refused)} of {len(commands)} refused: impact_id "
                f"{', '.join(shorten(i) for i in outcome.refused)}"
            )
        print(f"tail-beam send: error: {'; '.join(parts)}", file=sys.stderr)
        return EXIT_TIMEOUT if outcome.missing else EXIT_REFUSED
    print(f"tail-beam send: {len(commands)} command(s) simulated by {where}", file=sys.stderr)
    return 0
