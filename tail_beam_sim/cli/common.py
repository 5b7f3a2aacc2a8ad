"""Options shared by several subcommands: config files and the impact's description."""

from __future__ import annotations

import argparse
from typing import Any

from tail_beam_sim.config import load_parameters
from tail_beam_sim.physics.contact import CONTACT_LAWS
from tail_beam_sim.physics.fidelity import OUTPUTS, TIER_CHOICES, FidelitySettings, Needs
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.solvers import SOLVERS


def add_config_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--config",
        action="append",
        default=[],
        metavar="YAML",
        help=(
            "ROS 2 parameter file overriding the shipped config/ defaults (repeatable; later wins)"
        ),
    )


def add_impact_options(parser: argparse.ArgumentParser) -> None:
    """--material, --radius-m, --drop-height-m | --impact-speed-mps, --position-m, ..."""
    parser.add_argument(
        "--material", help="particle material from the config's material table (default: coal)"
    )
    parser.add_argument("--radius-m", type=str, help="equivalent sphere radius, m (default 0.025)")
    height = parser.add_mutually_exclusive_group()
    height.add_argument(
        "--drop-height-m",
        type=str,
        help="free-fall height above the contact point, m (default 3.5)",
    )
    height.add_argument(
        "--impact-speed-mps", type=str, help="speed at first contact, m/s (instead of a height)"
    )
    parser.add_argument(
        "--position-m",
        type=str,
        help="impact point along the plate from the hinge, m (default 1.0)",
    )
    parser.add_argument(
        "--restitution",
        type=str,
        help="particle's coefficient of restitution on steel (default: the material's)",
    )
    parser.add_argument(
        "--contact-model", choices=CONTACT_LAWS, help="contact law (default: calibrated)"
    )
    parser.add_argument(
        "--window-s", type=str, help="simulated time after first contact, s (default 0.05)"
    )
    parser.add_argument("--seed", type=int, help="sensor noise seed (default from config)")
    add_config_option(parser)


def scene_from_args(args: argparse.Namespace) -> Scene:
    """Build and validate the scene that the options describe."""
    params = load_parameters(args.config)
    overrides: dict[str, Any] = {
        "material": args.material,
        "radius_m": args.radius_m,
        "drop_height_m": args.drop_height_m,
        "impact_speed_mps": args.impact_speed_mps,
        "position_m": args.position_m,
        "restitution": args.restitution,
        "contact_model": args.contact_model,
        "window_s": args.window_s,
        "seed": args.seed,
    }
    return Scene.from_params(params, overrides)


def add_fidelity_options(parser: argparse.ArgumentParser, check: bool = True) -> None:
    """--tier, --solver, --outputs, --tolerance and, when ``check``, --check (defaults from
    config/fidelity.yaml). ``simulate`` and ``sweep`` share them, so that a sweep's row and the
    single simulation of the same settings use the same model."""
    parser.add_argument(
        "--tier",
        choices=TIER_CHOICES,
        help="model fidelity (default from config: auto, the cheapest that meets the needs)",
    )
    parser.add_argument(
        "--solver",
        choices=sorted(SOLVERS),
        help="solver (default: the tier's; hybrid for rigid/modal/brittle)",
    )
    parser.add_argument(
        "--outputs",
        nargs="+",
        choices=OUTPUTS,
        help="what the scene needs, for --tier auto (default: all)",
    )
    parser.add_argument(
        "--tolerance",
        type=str,
        help="relative error the scene accepts, for --tier auto (default 0.01)",
    )
    if check:
        parser.add_argument(
            "--check",
            action="store_true",
            help="also simulate the next tier up and report the measured differences",
        )


def fidelity_from_args(args: argparse.Namespace) -> tuple[str, Needs, FidelitySettings]:
    """The tier, needs and settings that the options and config files give."""
    settings = FidelitySettings.from_params(load_parameters(args.config))
    needs = Needs.of(
        args.outputs or settings.needs.outputs,
        settings.needs.tolerance if args.tolerance is None else args.tolerance,
    )
    return args.tier or settings.tier, needs, settings
