"""``tail-beam``: the suite's offline command line. One module per subcommand.

Each subcommand module has ``register(subparsers)``, which adds its parser and sets
``func``. Bad input ends with exit status 2 and one line naming the field and what is
allowed, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from tail_beam_sim.errors import InputError

# Subcommands, in the order ``tail-beam --help`` lists them: name -> module.
SUBCOMMANDS = {
    "simulate": "tail_beam_sim.cli.simulate_cmd",
    "sweep": "tail_beam_sim.cli.sweep_cmd",
    "evaluate": "tail_beam_id.cli.evaluate_cmd",
    "identify": "tail_beam_id.cli.identify_cmd",
    "bag": "tail_beam_sim.cli.bag_cmd",
    "demo": "tail_beam_sim.cli.demo_cmd",
    "bench": "tail_beam_sim.cli.bench_cmd",
}


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line and exit 2 (no usage dump)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """The full ``tail-beam`` parser with every installed subcommand."""
    parser = OneLineParser(prog="tail-beam", description="tail_beam offline tools: simulate, sweep, identify, evaluate, bench")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=OneLineParser, metavar="COMMAND")
    for module_name in SUBCOMMANDS.values():
        importlib.import_module(module_name).register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``tail-beam`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except InputError as exc:
        print(f"tail-beam {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"tail-beam {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
