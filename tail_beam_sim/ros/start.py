"""The executables' entry points: a stop signal that comes while one is still starting ends it
quietly.

Importing a node's module (rclpy, numpy, scipy, the models) takes a second or more; a SIGINT
left to Python's default there would end the process in a KeyboardInterrupt traceback from
inside an import (SIGTERM: killed, status -15). This module imports nothing heavy, takes both
signals first, and only then imports the node: a signal before the node spins exits with status
0 and no output; from :func:`tail_beam_sim.ros.spin.run_node` on, the node stops as usual.
"""

from __future__ import annotations

import importlib
import signal
from typing import NoReturn

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
_stop_received = False  # a stop signal came while the executable was starting


def _exit_quietly(signum: int, frame: object) -> NoReturn:
    global _stop_received
    _stop_received = True
    raise SystemExit(0)


def run(module: str) -> int:
    """Take the stop signals, then run ``module``'s ``main()``; its exit status. A stop that
    lands inside an extension module's initialisation comes back as another error (rclpy's
    ``ImportError: initialization failed``, its cause the SystemExit): still a quiet 0."""
    for sig in STOP_SIGNALS:
        signal.signal(sig, _exit_quietly)
    try:
        return int(importlib.import_module(module).main() or 0)
    except Exception:
        if _stop_received:
            return 0
        raise


def sim_node() -> int:
    return run("tail_beam_sim.ros.sim_node")


def bag_recorder() -> int:
    return run("tail_beam_sim.ros.recorder_node")


def bag_replay() -> int:
    return run("tail_beam_sim.ros.replay_node")
