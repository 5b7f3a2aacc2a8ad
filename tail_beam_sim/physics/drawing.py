"""Top-coal drawing as a stochastic medium: a void that climbs from the drawing opening.

The model is Litwiniszyn's stochastic medium in its discrete, void-diffusion form (J.
Litwiniszyn, "The theories and model research of movements of ground masses", 1956; the void
model of gravity flow: H. Caram and D. C. Hong, Phys. Rev. Lett. 67, 828, 1991): the broken
top coal and the caved gangue above it are a grid of equal cells across the face (columns)
and up the seam (rows). Drawing one cell at an opening leaves a void in the bottom row; the
void climbs one row at a time, stepping one column sideways with probability
``lateral_step_probability`` (half to each side) or straight up, and the cell it leaves
falls into the cell below. Fresh gangue enters the top row where the void leaves the grid.

What one opening leaves in place, its neighbours may draw: every opening works on the same
grid, so the coal-gangue boundary that one window pulls down is the boundary the next one
meets, and the order of the windows changes what is recovered. The draw body of one opening
is a parabola whose half-width at height ``z`` grows as ``sqrt(z * q * cell)``, the
Bergmark-Roos ellipsoid's shape in two dimensions; ``q`` sets it.

Materials are cell codes: :data:`COAL` (top coal, there before drawing) and :data:`GANGUE`.
Cells are equal volumes; their masses come from the densities (:mod:`tail_beam_sim.physics.face`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tail_beam_sim.errors import InputError

__all__ = ["COAL", "GANGUE", "VoidGrid"]

COAL = 0
GANGUE = 1


@dataclass
class VoidGrid:
    """The cells of a face's cross-section, ``cells[row][column]``, row 0 at the openings.

    ``coal_rows`` rows of top coal lie under ``gangue_rows`` rows of gangue (one is enough:
    the gangue above is all alike); ``lateral_step_probability`` is the void's chance per row
    of stepping sideways (0: it climbs straight, a column drawn alone; 1: it always steps).
    Sideways steps at the grid's sides reflect.
    """

    columns: int
    coal_rows: int
    gangue_rows: int = 1
    lateral_step_probability: float = 2.0 / 3.0

    def __post_init__(self) -> None:
        if self.columns < 1:
            raise InputError("face.columns", self.columns, "must be >= 1 cell")
        if self.coal_rows < 1:
            raise InputError("face.coal_rows", self.coal_rows, "must be >= 1 cell")
        if self.gangue_rows < 1:
            raise InputError("face.gangue_rows", self.gangue_rows, "must be >= 1 cell")
        if not 0.0 <= self.lateral_step_probability <= 1.0:
            raise InputError(
                "face.lateral_step_probability", self.lateral_step_probability, "must be in [0, 1]"
            )
        rows = self.coal_rows + self.gangue_rows
        self.cells: list[list[int]] = [
            [COAL if r < self.coal_rows else GANGUE] * self.columns for r in range(rows)
        ]
        self._coal_in_row = [self.columns if r < self.coal_rows else 0 for r in range(rows)]
        self._top_coal_row = self.coal_rows - 1  # highest row that still holds coal (-1: none)
        self.gangue_entered = 0  # cells of fresh gangue that came in at the top

    @property
    def rows(self) -> int:
        return self.coal_rows + self.gangue_rows

    def as_array(self) -> np.ndarray:
        """The cells as an array (rows x columns), row 0 at the openings."""
        return np.array(self.cells, dtype=np.int8)

    def coal_cells(self) -> int:
        """Coal cells still in the grid."""
        return sum(self._coal_in_row)

    def draw(self, column: int, uniforms: np.ndarray) -> int:
        """Draw the bottom cell of ``column`` and let the void climb; the drawn cell's material.

        ``uniforms`` holds one uniform draw in [0, 1) per row (the void's steps), so that a
        caller drawing many cells makes one call to its generator for all of them.
        """
        if not 0 <= column < self.columns:
            raise InputError("column", column, f"must be in [0, {self.columns - 1}]")
        cells = self.cells
        drawn = cells[0][column]
        coal_in_row = self._coal_in_row
        if drawn == COAL:
            coal_in_row[0] -= 1
        q = self.lateral_step_probability
        half = 0.5 * q
        last = self.columns - 1
        col = column
        row = 0
        # Above the highest row holding coal all is gangue, and shifting gangue among gangue
        # changes nothing: the climb ends there, the top refilled with gangue.
        stop = min(self._top_coal_row, self.rows - 1)
        for u in uniforms[: max(stop, 0)].tolist():
            above = col
            if u < half:
                above = col - 1 if col > 0 else col + 1 if last > 0 else col
            elif u < q:
                above = col + 1 if col < last else col - 1 if last > 0 else col
            material = cells[row + 1][above]
            cells[row][col] = material
            if material == COAL:
                coal_in_row[row] += 1
                coal_in_row[row + 1] -= 1
            col = above
            row += 1
        # The void at (row, col) fills with gangue (fresh from above, or gangue shifted down).
        cells[row][col] = GANGUE
        self.gangue_entered += 1
        while self._top_coal_row >= 0 and coal_in_row[self._top_coal_row] == 0:
            self._top_coal_row -= 1
        return drawn
