"""``tail-beam``: the suite's offline command line. One module per subcommand.

Each subcommand module has ``register(subparsers)``, which adds its parser and sets
``func``. The verbs are found through the ``tail_beam.verbs`` entry-point group (setup.py), the
way ros2cli and colcon find theirs, so any installed package can contribute one.

Exit status: 0 done; 2 bad input (one line naming the field and what is allowed); 3 a solve
failed (:class:`~tail_beam_sim.physics.solvers.SolverError`: one line naming the solver and
what to change); 4 a peer did not answer in time (``send``: no simulator appeared, or it did
not acknowledge the commands or send their truths); 5 a peer refused the request (``send``:
the simulator refused a command); 74 the output could not be written (a full disk or device:
one line naming where and why); 130 interrupted; 141 the output's reader went away (a closed
pipe, ``| head``: as a tool killed by SIGPIPE reports it in a shell). Never a traceback.
"""

from __future__ import annotations

import _thread
import argparse
import errno
import os
import signal
import sys
import threading
from collections.abc import Sequence
from typing import Any

from tail_beam_sim.errors import InputError

VERB_GROUP = "tail_beam.verbs"
REDELIVER_S = 0.01  # a Ctrl-C Python could only report comes back this much later, s
# Order of ``tail-beam --help`` for the verbs it knows; any other installed verb follows, by name.
__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_SOLVER_FAILED",
    "EXIT_TIMEOUT",
    "EXIT_REFUSED",
    "EXIT_OUTPUT_FAILED",
    "EXIT_INTERRUPTED",
    "EXIT_PIPE_CLOSED",
    "OneLineParser",
    "VERB_GROUP",
    "build_parser",
    "main",
]
EXIT_BAD_INPUT = 2
EXIT_SOLVER_FAILED = 3
EXIT_TIMEOUT = 4
EXIT_REFUSED = 5
EXIT_OUTPUT_FAILED = 74  # sysexits' EX_IOERR
# What writing the output may meet that is the device's state, not the tool's fault.
OUTPUT_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO})
EXIT_INTERRUPTED = 130  # 128 + SIGINT
EXIT_PIPE_CLOSED = 141  # 128 + SIGPIPE, what a shell reports for a tool its pipe's reader left

PREFERRED_ORDER = (
    "simulate",
    "sweep",
    "send",
    "identify",
    "calibrate",
    "evaluate",
    "bag",
    "demo",
    "bench",
    "caving",
)


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line and exit 2 (no usage dump)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The ``tail-beam`` parser: with only the subcommand that ``argv`` names when it names an
    installed one (each verb's module imports what its work needs, scipy and the models among
    it: a second or more for all of them, on every run), else with every installed one (help,
    or an unknown verb: argparse lists them all)."""
    parser = OneLineParser(
        prog="tail-beam",
        description=(
            "tail_beam tools: simulate, sweep, identify, evaluate, bench offline; send "
            "impacts to a running sim_node"
        ),
    )
    sub = parser.add_subparsers(
        dest="command", required=True, parser_class=OneLineParser, metavar="COMMAND"
    )
    # imported here: importlib.metadata loads the email package, before main()'s Ctrl-C guard
    from importlib.metadata import entry_points

    verbs = {ep.name: ep for ep in entry_points(group=VERB_GROUP)}
    if not verbs:
        parser.exit(
            2,
            f"tail-beam: error: no verbs installed in entry-point group {VERB_GROUP!r}: reinstall "
            "the package (pip install -e .)\n",
        )
    named = _named_verb(sys.argv[1:] if argv is None else argv)
    if named in verbs:
        verbs[named].load()(sub)
        return parser
    rank = {name: i for i, name in enumerate(PREFERRED_ORDER)}
    for name in sorted(verbs, key=lambda n: (rank.get(n, len(rank)), n)):
        verbs[name].load()(sub)
    return parser


def _named_verb(argv: Sequence[str]) -> str | None:
    """The subcommand ``argv`` names: its first argument when that is no option (the top-level
    parser has no option but ``--help``, which takes no value)."""
    return argv[0] if argv and not argv[0].startswith("-") else None


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``tail-beam`` console script.

    The verbs' modules (numpy, scipy, rosbags, the models) are imported inside the guard, so a
    Ctrl-C while they load is ``interrupted`` (130) as it is later, not a traceback."""
    previous = _Interrupt.install()
    try:
        return _run(argv)
    finally:
        _Interrupt.restore(previous)


def _run(argv: Sequence[str] | None) -> int:
    """main() inside the Ctrl-C handler it installs."""
    command = None
    try:
        from tail_beam_sim.physics.solvers import SolverError

        args = build_parser(argv).parse_args(argv)
        command = args.command
        if _Interrupt.received:
            # a Ctrl-C during the imports that an optional import's ``except ImportError`` took
            # (an extension initialising turns it into an ImportError): honoured now
            raise KeyboardInterrupt
        try:
            status = int(args.func(args) or 0)
            if _Interrupt.received:  # taken on the way, as above: the run did not finish
                raise KeyboardInterrupt
            sys.stdout.flush()  # what is still buffered fails here, not at exit
            return status
        except InputError as exc:
            print(f"tail-beam {command}: error: {exc}", file=sys.stderr)
            return EXIT_BAD_INPUT
        except SolverError as exc:
            print(f"tail-beam {command}: solver failed: {exc}", file=sys.stderr)
            return EXIT_SOLVER_FAILED
        except BrokenPipeError:
            # The reader of stdout left (``| head``): nothing more can be said there, and Python's
            # own flush at exit must not fail on it again, so stdout goes to /dev/null from here.
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            return EXIT_PIPE_CLOSED
        except OSError as exc:
            if exc.errno not in OUTPUT_ERRNOS:
                raise
            where = exc.filename or "standard output"
            print(
                f"tail-beam {command}: error: cannot write {where}: {os.strerror(exc.errno)}",
                file=sys.stderr,
            )
            # What stdout still buffers cannot go anywhere either: Python's flush at exit must
            # not fail on it again.
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            return EXIT_OUTPUT_FAILED
    except (KeyboardInterrupt, Exception) as exc:
        # Another error is an interruption too when a Ctrl-C came: it landed inside an extension
        # module's initialisation, which turned it into one (rclpy's ImportError:
        # initialization failed).
        if not isinstance(exc, KeyboardInterrupt) and not _Interrupt.received:
            raise
        print(f"tail-beam{' ' + command if command else ''}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


class _Interrupt:
    """SIGINT as Python's own handler takes it (KeyboardInterrupt), remembered: an extension
    module initialising when it lands may turn the KeyboardInterrupt into an error of its own."""

    received = False

    _unraisable_hook: Any = None  # sys.unraisablehook while installed

    @classmethod
    def install(cls) -> Any:
        """Take SIGINT (main thread only: signal handlers belong to it); the handler it
        replaced."""
        cls.received = False
        if threading.current_thread() is threading.main_thread():
            cls._unraisable_hook = sys.unraisablehook
            sys.unraisablehook = cls._unraisable
            return signal.signal(signal.SIGINT, cls._handle)
        return None

    @classmethod
    def restore(cls, previous: Any) -> None:
        """Give SIGINT back to ``previous`` (a library caller of main() keeps its own handler)."""
        if previous is not None and threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, previous)
            sys.unraisablehook = cls._unraisable_hook or sys.__unraisablehook__

    @classmethod
    def _unraisable(cls, unraisable: Any) -> None:
        """A KeyboardInterrupt that landed where Python can only report it (a callback of the
        import machinery's module locks, while the verbs load) is delivered again to the main
        thread, where main() ends as interrupted, instead of printed as a traceback and lost."""
        if isinstance(unraisable.exc_value, KeyboardInterrupt):
            # From another thread, a moment later: raised here it would be reported again.
            timer = threading.Timer(REDELIVER_S, _thread.interrupt_main)
            timer.daemon = True
            timer.start()
            return
        (cls._unraisable_hook or sys.__unraisablehook__)(unraisable)

    @classmethod
    def _handle(cls, signum: int, frame: object) -> None:
        cls.received = True
        raise KeyboardInterrupt


if __name__ == "__main__":
    sys.exit(main())
