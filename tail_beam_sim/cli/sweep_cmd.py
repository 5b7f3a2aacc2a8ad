"""``tail-beam sweep``: one impact parameter varied, a table of noise-free results (the
study's figures: restitution against height, response against position and material).

The model is chosen as ``tail-beam simulate`` chooses it (``--tier``, default from
config/fidelity.yaml), so a row equals the single simulation of the same settings; the table
says which tier each row used.
"""

from __future__ import annotations

import argparse
import json

from tail_beam_sim.cli.common import (
    add_fidelity_options,
    add_impact_options,
    fidelity_from_args,
    scene_from_args,
)
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.scene import Impact
from tail_beam_sim.physics.simulate import simulate

SWEEPABLE = (
    "drop_height_m",
    "impact_speed_mps",
    "position_m",
    "radius_m",
    "material",
    "restitution",
)
COLUMNS = (
    "impact_speed_mps",
    "rebound_speed_mps",
    "restitution",
    "contact_duration_s",
    "peak_contact_force_n",
    "peak_jack_pressure_change_pa",
    "peak_beam_angular_velocity_radps",
    "peak_imu_dynamic_accel_mps2",
    "n_contacts",
)


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("sweep", help="vary one impact parameter and tabulate the results")
    parser.add_argument("parameter", choices=SWEEPABLE, help="the impact field to vary")
    parser.add_argument("values", nargs="+", help="its values (numbers, or material names)")
    add_impact_options(parser)
    add_fidelity_options(parser, check=False)
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object per value instead of a table"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    base = scene_from_args(args)
    tier, needs, settings = fidelity_from_args(args)
    rows = []
    for value in args.values:
        fields = {
            "material": base.impact.material.name,
            "radius_m": base.impact.radius_m,
            "position_m": base.impact.position_m,
        }
        if base.impact.drop_height_m is not None:
            fields["drop_height_m"] = base.impact.drop_height_m
        else:
            fields["impact_speed_mps"] = base.impact.impact_speed_mps
        if args.restitution is not None:  # else the material's own, for each material swept
            fields["restitution"] = base.impact.restitution
        if args.parameter in ("drop_height_m", "impact_speed_mps"):
            fields.pop("drop_height_m", None)
            fields.pop("impact_speed_mps", None)
        fields[args.parameter] = value
        try:
            impact = Impact.from_mapping(fields, base.materials, base.support, text_numbers=True)
        except InputError as exc:
            raise InputError(f"values ({args.parameter})", value, exc.allowed) from None
        summary = simulate(
            base.with_impact(**impact.__dict__),
            args.solver,
            tier=tier,
            needs=needs,
            settings=settings,
        ).summary
        swept = (
            value if args.parameter == "material" else float(value)
        )  # a number in --json, as the field is in impact_cmd
        rows.append(
            {args.parameter: swept, "tier": summary["tier"], **{c: summary[c] for c in COLUMNS}}
        )
    if args.json:
        for row in rows:
            print(json.dumps(row))
        return 0
    tiers = sorted({r["tier"] for r in rows})
    one_tier = len(tiers) == 1
    print(f"# {'tier ' + tiers[0] if one_tier else 'tiers per row'} (--tier {tier}), noise-free")
    header = (
        f"{args.parameter:>16} {'v0 m/s':>8} {'v1 m/s':>8} {'e':>7} {'t_c us':>7} "
        f"{'F kN':>8} {'dp kPa':>8} {'w mrad/s':>9} {'a m/s2':>8} {'n':>3}"
    )
    print(header + ("" if one_tier else f" {'tier':>8}"))
    for r in rows:
        print(
            f"{r[args.parameter]!s:>16} {r['impact_speed_mps']:8.3f} "
            f"{r['rebound_speed_mps']:8.3f} {r['restitution']:7.4f} "
            f"{r['contact_duration_s'] * 1e6:7.1f} {r['peak_contact_force_n'] / 1e3:8.2f} "
            f"{r['peak_jack_pressure_change_pa'] / 1e3:8.2f} "
            f"{r['peak_beam_angular_velocity_radps'] * 1e3:9.4f} "
            f"{r['peak_imu_dynamic_accel_mps2']:8.2f} {r['n_contacts']:3d}"
            + ("" if one_tier else f" {r['tier']:>8}")
        )
    return 0
