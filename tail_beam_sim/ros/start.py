"""The executables' entry points: a stop signal that comes while one is still starting ends it
quietly.

Importing a node's module (rclpy, numpy, scipy, the models) takes a second or more; a SIGINT
left to Python's default there would end the process in a KeyboardInterrupt traceback from
inside an import (SIGTERM: killed, status -15). This module imports nothing heavy and takes both
signals first: a signal before the node spins ends the process at once with status 0 and no
output (nothing has been opened or written yet); from :func:`tail_beam_sim.ros.spin.run_node`
on, the node stops as usual.

The handler exits with ``os._exit`` rather than raising: an exception raised where the signal
lands can be swallowed on its way out (inside an extension module's initialisation it comes
back as an ImportError, which an optional import's ``except ImportError`` takes), and the
executable then started anyway and ignored the stop.
"""

from __future__ import annotations

import importlib
import os
import signal
import sys
from typing import NoReturn

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def _exit_quietly(signum: int, frame: object) -> NoReturn:
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:  # a closed or broken stream: nothing left to keep
            pass
    os._exit(0)


def run(module: str) -> int:
    """Take the stop signals, then run ``module``'s ``main()``; its exit status."""
    for sig in STOP_SIGNALS:
        signal.signal(sig, _exit_quietly)
    return int(importlib.import_module(module).main() or 0)


def sim_node() -> int:
    return run("tail_beam_sim.ros.sim_node")


def bag_recorder() -> int:
    return run("tail_beam_sim.ros.recorder_node")


def bag_replay() -> int:
    return run("tail_beam_sim.ros.replay_node")
