"""Fidelity tiers: how much model a scene gets, from an impulse to bending modes and crushing.

Tiers, cheapest first:

* ``impulse``: rigid beam, each contact replaced by an instantaneous impulse (closed form);
* ``rigid``: the study's model, rigid beam on the jack, contact integrated;
* ``modal``: rigid beam plus the bending modes of ``config/modes.yaml``;
* ``brittle``: ``modal`` with the crushing contact for coal (past the study; off by default).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

from tail_beam_sim.config import load_parameters
from tail_beam_sim.errors import InputError
from tail_beam_sim.structure import BendingMode, LinearStructure, beam_with_modes, load_bending_modes, rigid_beam
from tail_beam_sim.support import Support


@dataclass(frozen=True)
class Tier:
    """One fidelity tier: its structure (with or without bending modes), solver and contact."""

    name: str
    bending_modes: bool
    default_solver: str
    brittle: bool


TIERS: dict[str, Tier] = {
    "impulse": Tier("impulse", False, "impulse", False),
    "rigid": Tier("rigid", False, "hybrid", False),
    "modal": Tier("modal", True, "hybrid", False),
    "brittle": Tier("brittle", True, "hybrid", True),
}
DEFAULT_TIER = "rigid"


def get_tier(name: str) -> Tier:
    """The tier called ``name``, or InputError listing the tiers."""
    try:
        return TIERS[name]
    except KeyError:
        raise InputError("tier", name, f"must be one of {', '.join(TIERS)}") from None


@lru_cache(maxsize=1)
def shipped_modes() -> tuple[BendingMode, ...]:
    """The bending modes of the shipped ``config/modes.yaml`` (read once)."""
    return load_bending_modes(load_parameters())


def modes_from_params(params: Mapping[str, Any] | None) -> tuple[BendingMode, ...]:
    """Bending modes of ``params`` if it holds a ``modes`` section, else the shipped ones."""
    if params is not None and "modes" in params:
        return load_bending_modes(params)
    return shipped_modes()


def structure_for(tier: Tier, support: Support, modes: Sequence[BendingMode] | None = None) -> LinearStructure:
    """The linear structure ``tier`` uses on ``support`` (``modes`` default: the shipped ones)."""
    if not tier.bending_modes:
        return rigid_beam(support)
    return beam_with_modes(support, shipped_modes() if modes is None else modes)
