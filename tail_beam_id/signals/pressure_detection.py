"""Impact detection from the jack pressure alone: the fallback when the IMU has stopped.

The pressure answers an impact with the beam's slow (40 Hz) sway, so the onset is found by
fitting, at candidate onsets on a fixed grid of stamp time, the beam's response to a moment
impulse (features.fit_pressure) and keeping the local maxima whose fitted moment stands
``pressure_threshold_sigma`` standard errors above zero. Much less sensitive and less
precise in time (about a millisecond) than the IMU. Each onset found is confirmed by the same
fit with a free sway that may drift in frequency and decay (``confirm_sigma``), so that the
sway of an earlier impact is not taken for new ones.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tail_beam_id.signals.features import BeamModel, fit_pressure

GRID_S = 0.0005  # candidate onsets every this much stamp time, s


@dataclass(frozen=True)
class PressureOnset:
    """An impact found in the pressure: onset estimate (s) and its significance (sigma)."""

    onset_s: float
    significance: float


class PressureDetector:
    """Scans one pressure stream for impacts; remembers how far it got (a grid index)."""

    def __init__(
        self,
        model: BeamModel,
        threshold_sigma: float,
        pre_s: float,
        window_s: float,
        refractory_s: float,
        confirm_sigma: float,
    ) -> None:
        self.model = model
        self.threshold_sigma = threshold_sigma
        self.confirm_sigma = confirm_sigma
        self.pre_s = pre_s
        self.window_s = window_s
        self.refractory_s = refractory_s
        self.next_grid: int | None = None
        self._run: list[tuple[float, float]] = []  # (onset, significance) of the current excursion

    @property
    def scanned_s(self) -> float:
        """The next candidate onset the scan will try, s (-inf before the first scan)."""
        return -math.inf if self.next_grid is None else self.next_grid * GRID_S

    def skip_to(self, start_s: float) -> None:
        """Go on from ``start_s`` (s), leaving what lies before it unscanned: a stretch in which
        another channel found the impacts."""
        if self.next_grid is not None and self.next_grid * GRID_S < start_s:
            self.next_grid = math.ceil(start_s / GRID_S)
            self._run = []

    def scan(
        self, stamp_s: np.ndarray, pressure_pa: np.ndarray, start_s: float, final: bool = False
    ) -> list[PressureOnset]:
        """New onsets at or after ``start_s`` whose window lies inside the buffered samples."""
        if stamp_s.size < 8:
            return []
        if self.next_grid is None:
            self.next_grid = math.ceil((max(start_s, stamp_s[0] + self.pre_s)) / GRID_S)
        found: list[PressureOnset] = []
        last = stamp_s[-1] if final else stamp_s[-1] - self.window_s
        while self.next_grid * GRID_S <= last:
            onset = self.next_grid * GRID_S
            self.next_grid += 1
            fit = fit_pressure(self.model, stamp_s, pressure_pa, onset, self.pre_s, self.window_s)
            z = (
                fit.moment_impulse_nms / fit.sigma_nms
                if fit is not None and fit.sigma_nms > 0 and not fit.saturated
                else 0.0
            )
            if z > self.threshold_sigma:
                self._run.append((onset, z))
                continue
            if self._run:
                best = max(self._run, key=lambda item: item[1])
                if self._confirmed(stamp_s, pressure_pa, best[0]):
                    found.append(PressureOnset(*best))
                self._run = []
                self.next_grid = max(
                    self.next_grid, math.ceil((best[0] + self.refractory_s) / GRID_S)
                )
        if final and self._run:
            best = max(self._run, key=lambda item: item[1])
            if self._confirmed(stamp_s, pressure_pa, best[0]):
                found.append(PressureOnset(*best))
            self._run = []
        return found

    def _confirmed(self, stamp_s: np.ndarray, pressure_pa: np.ndarray, onset_s: float) -> bool:
        """The moment impulse at ``onset_s`` still stands ``confirm_sigma`` standard errors
        above zero when the free sway may drift in frequency and decay across the window. A
        beam swaying from an earlier impact at a frequency a little off the nominal one (the
        model's is the rigid beam's; a real support's differs) otherwise reads as a new impact
        every ring window, each an extra label."""
        fit = fit_pressure(
            self.model, stamp_s, pressure_pa, onset_s, self.pre_s, self.window_s, sway_drift=True
        )
        return (
            fit is not None
            and fit.sigma_nms > 0
            and fit.moment_impulse_nms >= self.confirm_sigma * fit.sigma_nms
        )
