"""The beam as a linear structure, M q'' + C q' + K q = b(x) F, and its exact free response.

Generalised coordinates ``q``: the rigid rotation phi (rad, positive when the plate moves away
from the particle, compressing the jack) first, then any modal coordinates a richer tier adds.
Shapes map ``q`` to physical quantities:

* ``contact_shape(x)``: plate displacement away from the particle at ``x`` (m per unit q);
* ``jack_shape``: jack shortening (m per unit q);
* ``imu_shape`` / ``imu_slope_shape``: plate displacement (m) and rotation (rad) at the IMU.

Between contacts the system is linear and unforced, so it is propagated exactly with the
eigen-decomposition of its first-order matrix, for any number of times at once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from tail_beam_sim.support import Support


@dataclass(frozen=True)
class LinearStructure:
    """Mass, damping and stiffness matrices of the beam plus the shapes of its outputs."""

    mass: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray
    contact_shape_fn: Callable[[float], np.ndarray]
    jack_shape: np.ndarray
    imu_shape: np.ndarray
    imu_slope_shape: np.ndarray
    jack_stiffness_npm: float
    jack_damping_nspm: float
    piston_area_m2: float
    setting_pressure_pa: float
    imu_from_hinge_m: float
    gravity_mps2: float
    _eigen: tuple[np.ndarray, np.ndarray, np.ndarray] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        n = self.size
        inv_mass = np.linalg.inv(self.mass)
        system = np.zeros((2 * n, 2 * n))
        system[:n, n:] = np.eye(n)
        system[n:, :n] = -inv_mass @ self.stiffness
        system[n:, n:] = -inv_mass @ self.damping
        eigenvalues, vectors = np.linalg.eig(system)
        object.__setattr__(self, "_eigen", (eigenvalues, vectors, np.linalg.inv(vectors)))
        object.__setattr__(self, "inv_mass", inv_mass)

    @property
    def size(self) -> int:
        """Number of generalised coordinates."""
        return self.mass.shape[0]

    def contact_shape(self, position_m: float) -> np.ndarray:
        """Plate displacement away from the particle at ``position_m`` per unit of each q."""
        return np.asarray(self.contact_shape_fn(position_m), dtype=float)

    def natural_frequencies_hz(self) -> np.ndarray:
        """Damped natural frequencies of the structure, Hz, ascending."""
        eigenvalues = self._eigen[0]
        return np.sort(np.abs(eigenvalues.imag[eigenvalues.imag > 0])) / (2 * np.pi)

    def acceleration(self, q: np.ndarray, qd: np.ndarray, force_n: np.ndarray | float, shape: np.ndarray) -> np.ndarray:
        """q'' for states ``q``, ``qd`` (n, ...) under contact force ``force_n`` on ``shape``."""
        generalised = np.multiply.outer(shape, force_n) if np.ndim(force_n) else shape * force_n
        return self.inv_mass @ (generalised - self.damping @ qd - self.stiffness @ q)

    def propagate(self, q0: np.ndarray, qd0: np.ndarray, dt_s: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Free response after ``dt_s`` (scalar or array of times >= 0) from (q0, qd0).

        Returns q and qd with shape (n,) for a scalar time, (n, len(dt_s)) for an array.
        """
        eigenvalues, vectors, inverse = self._eigen
        modal = inverse @ np.concatenate([q0, qd0])
        times = np.asarray(dt_s, dtype=float)
        phase = np.exp(np.multiply.outer(eigenvalues, times))
        state = (vectors @ (phase * modal.reshape((-1,) + (1,) * times.ndim))).real
        n = self.size
        return state[:n], state[n:]

    def pressure_pa(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Absolute jack pressure: setting pressure + (K_Q s + c_Q s') / S, Pa."""
        shortening = self.jack_shape @ q
        rate = self.jack_shape @ qd
        return self.setting_pressure_pa + (self.jack_stiffness_npm * shortening + self.jack_damping_nspm * rate) / self.piston_area_m2


def rigid_beam(support: Support) -> LinearStructure:
    """The study's model: a rigid beam about its hinge on the jack's spring and damper."""
    lever = support.jack_lever_arm_m
    return LinearStructure(
        mass=np.array([[support.beam_inertia_about_hinge_kgm2]]),
        damping=np.array([[support.rotational_damping_nmsprad]]),
        stiffness=np.array([[support.rotational_stiffness_nmprad]]),
        contact_shape_fn=lambda x: np.array([x]),
        jack_shape=np.array([lever]),
        imu_shape=np.array([support.imu_from_hinge_m]),
        imu_slope_shape=np.array([1.0]),
        jack_stiffness_npm=support.jack_stiffness_npm,
        jack_damping_nspm=support.jack_damping_nspm,
        piston_area_m2=support.piston_area_m2,
        setting_pressure_pa=support.setting_pressure_pa,
        imu_from_hinge_m=support.imu_from_hinge_m,
        gravity_mps2=support.gravity_mps2,
    )
