"""The gangue share of a drawing opening's flow against the mass drawn: a piecewise-linear curve.

Top-coal drawing brings pure coal first; once the coal-gangue boundary reaches the opening the
gangue share of what flows rises. The face's drawing model gives that share as a function of
what has been drawn; here the curve is given (``flow.share_drawn_mass_kg`` /
``flow.share_gangue``, or by the caller), linear between its points and held beyond its ends.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tail_beam_sim.errors import InputError


@dataclass(frozen=True)
class ShareCurve:
    """Gangue share by mass (0..1) of the flow at a drawn mass (kg since the window first
    opened)."""

    drawn_mass_kg: np.ndarray
    share: np.ndarray

    @classmethod
    def of(
        cls,
        drawn_mass_kg: Sequence[float],
        share: Sequence[float],
        field: str = "flow",
    ) -> ShareCurve:
        """A checked curve; InputError naming ``<field>.share_drawn_mass_kg`` or
        ``<field>.share_gangue`` for lengths that differ, an empty curve, a share outside
        [0, 1], a drawn mass below 0 or not strictly increasing, or a value that is no number."""
        mass_field, share_field = f"{field}.share_drawn_mass_kg", f"{field}.share_gangue"
        mass = _numbers(mass_field, drawn_mass_kg)
        values = _numbers(share_field, share)
        if mass.size == 0:
            raise InputError(mass_field, list(drawn_mass_kg), "must hold at least one point")
        if mass.size != values.size:
            raise InputError(
                share_field,
                list(share),
                f"must hold one share per drawn mass: {values.size} shares for "
                f"{mass.size} masses in {mass_field}",
            )
        for k, value in enumerate(values):
            if not 0.0 <= value <= 1.0:
                raise InputError(f"{share_field}[{k}]", value, "must be a share in [0, 1]")
        for k, value in enumerate(mass):
            if value < 0.0:
                raise InputError(f"{mass_field}[{k}]", value, "must be >= 0 kg")
            if k and value <= mass[k - 1]:
                raise InputError(
                    f"{mass_field}[{k}]",
                    value,
                    f"must be > {mass[k - 1]:g} kg: the drawn masses must increase strictly",
                )
        return cls(mass, values)

    def at(self, drawn_mass_kg: float | np.ndarray) -> float | np.ndarray:
        """The gangue share by mass at ``drawn_mass_kg`` (linear between points, held
        beyond)."""
        out = np.interp(drawn_mass_kg, self.drawn_mass_kg, self.share)
        return float(out) if np.ndim(out) == 0 else out


def _numbers(field: str, values: Sequence[float]) -> np.ndarray:
    if isinstance(values, (str, bytes)) or not isinstance(values, (Sequence, np.ndarray)):
        raise InputError(field, values, "must be a list of numbers")
    out = []
    for k, value in enumerate(values):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
            raise InputError(f"{field}[{k}]", value, "must be a finite number")
        if not math.isfinite(float(value)):
            raise InputError(f"{field}[{k}]", value, "must be a finite number")
        out.append(float(value))
    return np.array(out, dtype=float)
