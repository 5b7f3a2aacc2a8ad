"""tail_beam_sim: physics core and simulator of an instrumented top-coal-caving tail beam.

The core (everything but the ``ros`` package) imports no ROS package, so it serves the ROS
nodes, the offline ``tail-beam`` command line and the benchmarks alike.

The public names below load on first use (PEP 562), so that importing a light module of the
package (an executable's entry point, :mod:`tail_beam_sim.ros.start`) does not first load
numpy and scipy.
"""

from __future__ import annotations

import importlib
from typing import Any

_HOMES = {
    "InputError": "tail_beam_sim.errors",
    "Impact": "tail_beam_sim.physics.scene",
    "Scene": "tail_beam_sim.physics.scene",
    "SimulationResult": "tail_beam_sim.physics.simulate",
    "simulate": "tail_beam_sim.physics.simulate",
}

__all__ = ["InputError", "Impact", "Scene", "SimulationResult", "simulate"]


def __getattr__(name: str) -> Any:
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module 'tail_beam_sim' has no attribute {name!r}")
