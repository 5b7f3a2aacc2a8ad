"""id_node's entry point: stop signals taken before the node's heavy imports
(:mod:`tail_beam_sim.ros.start`)."""

from __future__ import annotations

from tail_beam_sim.ros.start import run


def id_node() -> int:
    return run("tail_beam_id.ros.id_node")
