"""``tail-beam simulate``: one impact, offline; summary, bag and figure on request. With
``--flow SECONDS``: a drawing opening's flow of lumps instead (config/flow.yaml, docs/flow.md);
summary per share interval, bag on request."""

from __future__ import annotations

import argparse
import json
import math
import sys

from tail_beam_sim.bags import records as bagio
from tail_beam_sim.bags.flow_bag import write_flow_bag
from tail_beam_sim.cli.common import (
    add_fidelity_options,
    add_impact_options,
    fidelity_from_args,
    scene_from_args,
)
from tail_beam_sim.config import default_config_dir, load_parameters
from tail_beam_sim.errors import InputError, require_new_path, require_output_file, require_range
from tail_beam_sim.physics.flow import simulate_flow
from tail_beam_sim.physics.simulate import simulate


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("simulate", help="simulate one impact and report what the sensors see")
    add_impact_options(parser)
    add_fidelity_options(parser)
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object of noise-free results"
    )
    parser.add_argument(
        "--bag",
        metavar="PATH",
        help="write the sensor streams, rebound and truth as a rosbag2 bag",
    )
    parser.add_argument(
        "--storage",
        choices=sorted(bagio.STORAGES),
        default="mcap",
        help="bag storage (default mcap)",
    )
    parser.add_argument(
        "--compression",
        choices=bagio.COMPRESSIONS,
        default="zstd",
        help="mcap chunk compression (default zstd; sqlite3 files are not compressed)",
    )
    parser.add_argument("--plot", metavar="PNG", help="write a figure of the response")
    parser.add_argument(
        "--flow",
        metavar="SECONDS",
        type=str,
        help="simulate a drawing opening's flow for SECONDS of simulation time instead of one "
        "impact (section flow of config/flow.yaml, overridden by --config; --seed sets the "
        "lumps' seed; the window opens at flow.open_at_s, 0 if -1)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # Output paths first, before any work: a link there is refused, never written through.
    if args.bag:
        require_new_path("--bag", args.bag)
    if args.flow is not None:
        return run_flow(args)
    if args.plot:
        require_output_file("--plot", args.plot)
    scene = scene_from_args(args)
    tier, needs, settings = fidelity_from_args(args)
    result = simulate(
        scene, args.solver, tier=tier, needs=needs, settings=settings, check=args.check
    )
    summary = result.summary
    if args.bag:
        command = {
            "material": scene.impact.material.name,
            "radius_m": scene.impact.radius_m,
            "position_m": scene.impact.position_m,
            "impact_id": scene.impact.impact_id or "simulate-0",
        }
        if scene.impact.drop_height_m is not None:
            command["drop_height_m"] = scene.impact.drop_height_m
        else:
            command["impact_speed_mps"] = scene.impact.impact_speed_mps
        if not scene.impact.impact_id:
            scene = scene.with_impact(impact_id="simulate-0")
            result.scene = scene
        count = bagio.write_bag(
            args.bag, bagio.result_records(result, command), args.storage, args.compression
        )
        print(f"wrote {count} messages to {args.bag} ({args.storage})", file=sys.stderr)
    if args.plot:
        from tail_beam_sim.plotting import plot_response

        print(f"wrote {plot_response(result, args.plot)}", file=sys.stderr)
    if args.json:
        print(
            json.dumps(
                {
                    k: None if isinstance(v, float) and math.isnan(v) else v
                    for k, v in summary.items()
                }
            )
        )
    else:
        print(format_summary(summary))
    return 0


def format_summary(s: dict) -> str:
    """A short human-readable report of one impact."""
    height = f"dropped {s['drop_height_m']:g} m, " if s["drop_height_m"] is not None else ""
    lines = [
        f"{s['material']} sphere R = {s['radius_m'] * 1e3:g} mm ({s['mass_kg'] * 1e3:.1f} g), "
        f"{height}"
        f"impact {s['impact_speed_mps']:.3f} m/s at {s['position_m']:g} m from the hinge "
        f"({s['contact_model']} contact, {s['solver']} solver)",
        f"  rebound              {s['rebound_speed_mps']:.3f} m/s   (restitution "
        f"{s['restitution']:.4f})",
        f"  contact              {s['contact_duration_s'] * 1e6:.1f} µs, peak force "
        f"{s['peak_contact_force_n'] / 1e3:.2f} kN, {s['n_contacts']} contact(s)",
        f"  jack pressure swing  {s['peak_jack_pressure_change_pa'] / 1e3:.2f} kPa above setting",
        f"  beam rate            {s['peak_beam_angular_velocity_radps'] * 1e3:.3f} mrad/s peak",
        f"  IMU dynamic accel    {s['peak_imu_dynamic_accel_mps2']:.2f} m/s^2 peak "
        "(instantaneous)",
        f"  fidelity             {s['tier']} tier, {s['solver']} solver, estimated relative error "
        f"{s['error_estimate']:.2g}",
    ]
    if "check" in s:
        check = s["check"]
        lines.append(
            f"  check vs {check['against']:<11} "
            + ", ".join(f"{k} {v:.2g}" for k, v in check.items() if k != "against")
        )
    return "\n".join(lines)


# Options of one impact that a flow does not take (its lumps come from the flow section).
_NOT_WITH_FLOW = (
    "material",
    "radius_m",
    "drop_height_m",
    "impact_speed_mps",
    "position_m",
    "restitution",
    "plot",
    "check",
    "solver",
    "outputs",
    "tolerance",
)


def run_flow(args: argparse.Namespace) -> int:
    """``--flow SECONDS``: simulate the flow, print one line per share interval (or one JSON
    object), write the bag on request."""
    duration = require_range("--flow", args.flow, 0.0, 3600.0, low_open=True, unit="s")
    for name in _NOT_WITH_FLOW:
        if getattr(args, name, None) not in (None, False):
            option = "--" + name.replace("_", "-")
            raise InputError(option, getattr(args, name), "is not taken with --flow")
    config = default_config_dir()
    params = load_parameters([config / "sim_node.yaml", config / "flow.yaml", *args.config])
    if args.tier:
        params["stream"]["tier"] = args.tier
    for name, value in (("contact_model", args.contact_model), ("window_s", args.window_s)):
        if value is not None:
            params["scene"][name] = value
    record = simulate_flow(params, duration, seed=args.seed)
    if args.bag:
        count = write_flow_bag(record, args.bag, args.storage, args.compression)
        print(f"wrote {count} messages to {args.bag} ({args.storage})", file=sys.stderr)
    lumps = record.lumps
    mass = sum(lump.mass_kg for lump in lumps)
    summary = {
        "duration_s": record.duration_s,
        "lumps": len(lumps),
        "lumps_per_s": record.lumps_per_s,
        "mass_kg": mass,
        "gangue_lumps": sum(lump.is_gangue for lump in lumps),
        "windows": [{"stamp_s": stamp, "action": action} for stamp, action in record.windows],
        "shares": [share.to_json() for share in record.shares],
    }
    if args.json:
        print(json.dumps(summary))
        return 0
    print(
        f"flow of {len(lumps)} lumps over {record.duration_s:g} s ({record.lumps_per_s:.1f} "
        f"lumps/s, {mass:.1f} kg, {summary['gangue_lumps']} gangue)"
    )
    print("  interval s        lumps  mass kg  gangue by mass  by count")
    for share in record.shares:
        by_mass = "-" if share.share_by_mass is None else f"{share.share_by_mass:.3f}"
        by_count = "-" if share.share_by_count is None else f"{share.share_by_count:.3f}"
        print(
            f"  {share.start_stamp_s:7.2f}-{share.end_stamp_s:<7.2f} {share.lumps:6d} "
            f"{share.mass_kg:8.1f}  {by_mass:>14}  {by_count:>8}"
        )
    return 0
