"""id_node's, caving_node's and face_host's entry points: stop signals taken before the node's
heavy imports (:mod:`tail_beam_sim.ros.start`)."""

from __future__ import annotations

from tail_beam_sim.ros.start import run


def id_node() -> int:
    return run("tail_beam_id.ros.id_node")


def caving_node() -> int:
    return run("tail_beam_id.ros.caving_node")


def face_host() -> int:
    return run("tail_beam_id.ros.face_host")
