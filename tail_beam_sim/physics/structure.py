"""The beam as a linear structure, M q'' + C q' + K q = b(x) F, and its exact free response.

Generalised coordinates ``q``: the rigid rotation phi (rad, positive when the plate moves away
from the particle, compressing the jack) first, then any modal coordinates a richer tier adds.
Shapes map ``q`` to physical quantities:

* ``contact_shape(x)``: plate displacement away from the particle at ``x`` (m per unit q);
* ``jack_shape``: jack shortening (m per unit q);
* ``imu_shape`` / ``imu_slope_shape``: plate displacement (m) and rotation (rad) at the IMU.

Between contacts the system is linear and unforced, so it is propagated exactly with the
eigen-decomposition of its first-order matrix, for any number of times at once.

Two structures are built here: :func:`rigid_beam` (the study's model, q = [phi]) and
:func:`beam_with_modes` (q = [phi, eta_1 .. eta_N]: the rigid rotation plus N bending modes of
the beam held at its hinge and jack pin, read from ``config/modes.yaml``). The bending modes'
numbers come from :func:`euler_bernoulli_modes`, a finite-element Euler-Bernoulli model of the
beam's box section (see the comments in ``config/modes.yaml``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
from scipy.linalg import eigh

from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.support import Support
from tail_beam_sim.spec import BENDING_MODE, MODES


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
    # contact_shape_fn of many positions at once, (positions, size); None: one by one
    contact_shapes_fn: Callable[[np.ndarray], np.ndarray] | None = field(
        default=None, repr=False, compare=False
    )
    _eigen: tuple[np.ndarray, np.ndarray, np.ndarray] = field(
        init=False, repr=False, compare=False
    )

    def __post_init__(self) -> None:
        n = self.size
        inv_mass = np.linalg.inv(self.mass)
        system = np.zeros((2 * n, 2 * n))
        system[:n, n:] = np.eye(n)
        system[n:, :n] = -inv_mass @ self.stiffness
        system[n:, n:] = -inv_mass @ self.damping
        eigenvalues, vectors = np.linalg.eig(system)
        inverse = np.linalg.inv(vectors)
        object.__setattr__(self, "_eigen", (eigenvalues, vectors, inverse))
        object.__setattr__(self, "inv_mass", inv_mass)
        # The system is real, so its eigenvalues are real or come in conjugate pairs whose
        # terms of a real state are conjugates: one of each pair, counted twice, gives the
        # state with half the exponentials (:meth:`propagate`).
        upper = eigenvalues.imag >= 0.0
        object.__setattr__(
            self,
            "_half_spectrum",
            (
                np.flatnonzero(upper),
                eigenvalues[upper].real.copy(),
                eigenvalues[upper].imag.copy(),
                np.where(eigenvalues[upper].imag > 0.0, 2.0, 1.0),
            ),
        )
        # Per-structure products the solvers need for every impact (modal coordinates xi, x = V
        # xi):
        # xi gained per unit generalised force, and q'' from the structure's own forces per unit
        # xi.
        object.__setattr__(self, "modal_input", inverse[:, n:] @ inv_mass)
        object.__setattr__(
            self,
            "modal_internal",
            inv_mass @ (self.stiffness @ vectors[:n] + self.damping @ vectors[n:]),
        )

    @property
    def size(self) -> int:
        """Number of generalised coordinates."""
        return self.mass.shape[0]

    def contact_shape(self, position_m: float) -> np.ndarray:
        """Plate displacement away from the particle at ``position_m`` per unit of each q."""
        return np.asarray(self.contact_shape_fn(position_m), dtype=float)

    def contact_shapes(self, positions_m: Sequence[float]) -> np.ndarray:
        """:meth:`contact_shape` of each position, (positions, size): the same values."""
        if self.contact_shapes_fn is None:
            return np.array([self.contact_shape(x) for x in positions_m], dtype=float)
        return np.asarray(
            self.contact_shapes_fn(np.asarray(positions_m, dtype=float)), dtype=float
        )

    def contact_compliance(self, shape: np.ndarray) -> float:
        """b^T M^-1 b: the contact point's velocity change per unit impulse, 1/kg.

        The inverse of the structure's effective mass at the contact point; 0 where the point
        cannot move (over the hinge: the plate is then a rigid wall, docs/physics.md).
        """
        return float(shape @ self.inv_mass @ shape)

    def natural_frequencies_hz(self) -> np.ndarray:
        """Damped natural frequencies of the structure, Hz, ascending."""
        eigenvalues = self._eigen[0]
        return np.sort(np.abs(eigenvalues.imag[eigenvalues.imag > 0])) / (2 * np.pi)

    @cached_property
    def fastest_frequency_hz(self) -> float:
        """The highest damped natural frequency, Hz (0 for a structure without oscillating
        modes)."""
        frequencies = self.natural_frequencies_hz()
        return float(frequencies.max()) if frequencies.size else 0.0

    def acceleration(
        self, q: np.ndarray, qd: np.ndarray, force_n: np.ndarray | float, shape: np.ndarray
    ) -> np.ndarray:
        """q'' for states ``q``, ``qd`` (n, ...) under contact force ``force_n`` on ``shape``."""
        generalised = np.multiply.outer(shape, force_n) if np.ndim(force_n) else shape * force_n
        return self.inv_mass @ (generalised - self.damping @ qd - self.stiffness @ q)

    def propagate(
        self, q0: np.ndarray, qd0: np.ndarray, dt_s: np.ndarray | float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Free response after ``dt_s`` (scalar or array of times >= 0) from (q0, qd0).

        Returns q and qd with shape (n,) for a scalar time, (n, len(dt_s)) for an array.
        """
        return self.propagate_amplitude(self.free_amplitude(q0, qd0), dt_s)

    def free_amplitude(self, q0: np.ndarray, qd0: np.ndarray) -> np.ndarray | None:
        """The free response from (q0, qd0) as the complex amplitude of each exponential
        (one of each conjugate pair, weighted; :meth:`propagate_amplitude`), None at rest: a
        state propagated many times is decomposed once."""
        _, vectors, inverse = self._eigen
        modal = inverse @ np.concatenate([q0, qd0])
        if not np.any(modal):
            return None
        keep, _, _, weight = self._half_spectrum
        return vectors[:, keep] * (weight * modal[keep])

    def propagate_amplitude(
        self, amplitude: np.ndarray | None, dt_s: np.ndarray | float
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`propagate` of the state whose :meth:`free_amplitude` is ``amplitude``."""
        times = np.asarray(dt_s, dtype=float)
        if amplitude is None:
            # At rest it stays at rest, also backwards in time (samples before the first contact):
            # exp(lambda t) of a strongly damped mode overflows there, and inf * 0 is NaN.
            rest = np.zeros((self.size,) + times.shape)
            return rest, rest.copy()
        # x(t) = Re sum_k V_k c_k exp(lambda_k t), over one eigenvalue of each conjugate pair
        # (weight 2) and the real ones (weight 1), in real arithmetic: with
        # lambda = sigma + i omega and w V c = a + i b, each term is
        # exp(sigma t) (a cos(omega t) - b sin(omega t)). Real exp, cos and sin cost a fraction
        # of a complex exp.
        keep, sigma, omega, _ = self._half_spectrum
        growth = np.multiply.outer(sigma, times)
        np.exp(growth, out=growth)
        angle = np.multiply.outer(omega, times)
        # exp(sigma t) cos(omega t) and exp(sigma t) sin(omega t), written over their inputs
        cosine = np.cos(angle)
        np.multiply(growth, cosine, out=cosine)
        sine = np.sin(angle, out=angle)
        np.multiply(growth, sine, out=sine)
        # einsum, not a BLAS product: each time's state then does not depend on how many times
        # are asked for at once (BLAS kernels round the tail of a block differently), so a stream
        # sampled in chunks is bit-identical to one sampled whole.
        if keep.size == 1 and times.ndim == 1:
            # one exponential (the rigid beam's pair): a plain product, the same floats
            state = amplitude.real * cosine - amplitude.imag * sine
        else:
            state = np.einsum("ik,k...->i...", amplitude.real, cosine)
            state -= np.einsum("ik,k...->i...", amplitude.imag, sine)
        n = self.size
        return state[:n], state[n:]

    def pressure_pa(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Absolute jack pressure: setting pressure + (K_Q s + c_Q s') / S, Pa."""
        shortening = self.jack_shape @ q
        rate = self.jack_shape @ qd
        return (
            self.setting_pressure_pa
            + (self.jack_stiffness_npm * shortening + self.jack_damping_nspm * rate)
            / self.piston_area_m2
        )


def reduced_mass_kg(
    particle_mass_kg: float | np.ndarray, compliance_per_kg: float | np.ndarray
) -> float | np.ndarray:
    """m M / (m + M) written with the structure's compliance 1/M, kg: finite on a rigid wall
    (compliance 0, where it is the particle's own mass)."""
    return particle_mass_kg / (1.0 + particle_mass_kg * compliance_per_kg)


def rigid_beam(support: Support) -> LinearStructure:
    """The study's model: a rigid beam about its hinge on the jack's spring and damper."""
    lever = support.jack_lever_arm_m
    return LinearStructure(
        mass=np.array([[support.beam_inertia_about_hinge_kgm2]]),
        damping=np.array([[support.rotational_damping_nmsprad]]),
        stiffness=np.array([[support.rotational_stiffness_nmprad]]),
        contact_shape_fn=lambda x: np.array([x]),
        contact_shapes_fn=lambda xs: xs[:, None].copy(),
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


@dataclass(frozen=True)
class BendingMode:
    """One bending mode of the beam held at its hinge and jack pin.

    Its coordinate eta is the mode's largest plate displacement, m (the shape is normalised to
    a peak of 1). ``shape`` (m/m) and ``slope_radpm`` (rad/m) are tabulated at ``stations_m``
    (m from the hinge) and interpolated by cubic Hermite, which reproduces the finite-element
    shape exactly when the stations are its nodes. ``rigid_coupling_kgm`` = integral of
    rho A x psi dx, the mass coupling between the mode and the rigid rotation, kg m.
    """

    name: str
    frequency_hz: float
    damping_ratio: float
    modal_mass_kg: float
    rigid_coupling_kgm: float
    stations_m: np.ndarray
    shape: np.ndarray
    slope_radpm: np.ndarray

    def _locate(self, x_m: float) -> tuple[int, float, float]:
        stations = self.stations_m
        if not stations[0] - 1e-9 <= x_m <= stations[-1] + 1e-9:
            raise InputError(
                f"modes.{self.name}",
                x_m,
                f"position must be in [{stations[0]:g}, {stations[-1]:g}] m",
            )
        k = min(max(int(stations.searchsorted(x_m, side="right")) - 1, 0), stations.size - 2)
        h = float(stations[k + 1] - stations[k])
        return k, h, (x_m - float(stations[k])) / h

    def shape_at(self, x_m: float) -> float:
        """Plate displacement per unit eta at ``x_m`` (m/m)."""
        k, h, s = self._locate(x_m)
        # Python floats: the same double arithmetic as numpy's scalars, a fraction of the cost
        w0, w1 = self.shape[k : k + 2].tolist()
        t0, t1 = self.slope_radpm[k : k + 2].tolist()
        return float(
            (2 * s**3 - 3 * s**2 + 1) * w0
            + (s**3 - 2 * s**2 + s) * h * t0
            + (-2 * s**3 + 3 * s**2) * w1
            + (s**3 - s**2) * h * t1
        )

    def shapes_at(self, x_m: np.ndarray) -> np.ndarray:
        """:meth:`shape_at` of each position (one search of the stations for all; the
        polynomial in Python floats, as there: the same values)."""
        stations = self.stations_m
        inside = (stations[0] - 1e-9 <= x_m) & (x_m <= stations[-1] + 1e-9)
        if not inside.all():
            self._locate(float(x_m[~inside][0]))  # raises, naming the position
        k = np.clip(stations.searchsorted(x_m, side="right") - 1, 0, stations.size - 2)
        widths = stations[k + 1] - stations[k]
        out = []
        for s, h, w0, w1, t0, t1 in zip(
            ((x_m - stations[k]) / widths).tolist(),
            widths.tolist(),
            self.shape[k].tolist(),
            self.shape[k + 1].tolist(),
            self.slope_radpm[k].tolist(),
            self.slope_radpm[k + 1].tolist(),
        ):
            out.append(
                (2 * s**3 - 3 * s**2 + 1) * w0
                + (s**3 - 2 * s**2 + s) * h * t0
                + (-2 * s**3 + 3 * s**2) * w1
                + (s**3 - s**2) * h * t1
            )
        return np.array(out)

    def slope_at(self, x_m: float) -> float:
        """Plate rotation per unit eta at ``x_m`` (rad/m)."""
        k, h, s = self._locate(x_m)
        w0, w1 = self.shape[k : k + 2].tolist()
        t0, t1 = self.slope_radpm[k : k + 2].tolist()
        return float(
            (6 * s**2 - 6 * s) / h * w0
            + (3 * s**2 - 4 * s + 1) * t0
            + (-6 * s**2 + 6 * s) / h * w1
            + (3 * s**2 - 2 * s) * t1
        )


MODE_FIELDS = ("frequency_hz", "damping_ratio", "modal_mass_kg", "rigid_coupling_kgm")  # numbers


def load_bending_modes(params: Mapping[str, Any]) -> tuple[BendingMode, ...]:
    """The first ``modes.count`` bending modes of the ``modes`` parameter section."""
    section = params.get("modes")
    if not isinstance(section, Mapping):
        raise InputError("modes", section, "missing parameter section (config/modes.yaml)")
    names = sorted(
        (k for k in section if k.startswith("bending_")), key=lambda k: int(k.split("_")[1])
    )
    count = MODES.check(
        {"count": section.get("count", len(names))},
        only=("count",),
        context={"bending_modes": len(names)},
    )["count"]
    stations = np.asarray(section.get("stations_m", []), dtype=float)
    if stations.ndim != 1 or stations.size < 2 or np.any(np.diff(stations) <= 0):
        raise InputError(
            "modes.stations_m", section.get("stations_m"), "must be >= 2 increasing positions, m"
        )
    modes = []
    for name in names[:count]:
        body = section[name]
        field_ = f"modes.{name}"
        shape = np.asarray(body.get("shape", []), dtype=float)
        slope = np.asarray(body.get("slope_radpm", []), dtype=float)
        if shape.shape != stations.shape or slope.shape != stations.shape:
            raise InputError(
                f"{field_}.shape",
                shape.size,
                f"shape and slope_radpm need {stations.size} values (one per station)",
            )
        modes.append(
            BendingMode(
                name=name,
                **BENDING_MODE.check(body, where=field_, only=MODE_FIELDS),
                stations_m=stations,
                shape=shape,
                slope_radpm=slope,
            )
        )
    return tuple(modes)


def beam_with_modes(support: Support, modes: Sequence[BendingMode]) -> LinearStructure:
    """Rigid beam on the jack plus bending modes: q = [phi, eta_1, .., eta_N] (Rayleigh-Ritz).

    Displacement away from the particle: w(x) = x phi + sum psi_k(x) eta_k. Mass: I_C, the
    modal masses and their couplings with phi; stiffness and damping: the modes' own plus the
    jack's along ``jack_shape`` (zero for a mode held at the jack pin, as the shipped ones are).
    """
    if not modes:
        return rigid_beam(support)
    n = 1 + len(modes)
    sin_jack = math.sin(math.radians(support.jack_angle_to_beam_deg))
    jack = np.array(
        [support.jack_lever_arm_m]
        + [m.shape_at(support.jack_pin_from_hinge_m) * sin_jack for m in modes]
    )
    mass = np.zeros((n, n))
    mass[0, 0] = support.beam_inertia_about_hinge_kgm2
    own_stiffness = np.zeros(n)
    own_damping = np.zeros(n)
    for k, mode in enumerate(modes, start=1):
        omega = 2 * math.pi * mode.frequency_hz
        mass[k, k] = mode.modal_mass_kg
        mass[0, k] = mass[k, 0] = mode.rigid_coupling_kgm
        own_stiffness[k] = mode.modal_mass_kg * omega**2
        own_damping[k] = 2 * mode.damping_ratio * omega * mode.modal_mass_kg
    if np.linalg.eigvalsh(mass).min() <= 0.0:
        raise InputError(
            "modes",
            [m.name for m in modes],
            "rigid_coupling_kgm too large for the beam's inertia: mass matrix not positive",
        )
    x_imu = support.imu_from_hinge_m
    return LinearStructure(
        mass=mass,
        damping=np.diag(own_damping) + support.jack_damping_nspm * np.outer(jack, jack),
        stiffness=np.diag(own_stiffness) + support.jack_stiffness_npm * np.outer(jack, jack),
        contact_shape_fn=lambda x: np.array([x] + [m.shape_at(x) for m in modes]),
        contact_shapes_fn=lambda xs: np.column_stack([xs] + [m.shapes_at(xs) for m in modes]),
        jack_shape=jack,
        imu_shape=np.array([x_imu] + [m.shape_at(x_imu) for m in modes]),
        imu_slope_shape=np.array([1.0] + [m.slope_at(x_imu) for m in modes]),
        jack_stiffness_npm=support.jack_stiffness_npm,
        jack_damping_nspm=support.jack_damping_nspm,
        piston_area_m2=support.piston_area_m2,
        setting_pressure_pa=support.setting_pressure_pa,
        imu_from_hinge_m=x_imu,
        gravity_mps2=support.gravity_mps2,
    )


def euler_bernoulli_modes(
    length_m: float,
    held_at_m: Sequence[float],
    bending_stiffness_nm2: float,
    mass_per_length_kgpm: float,
    count: int,
    elements: int,
    element_stiffness_scale: Sequence[float] | None = None,
    element_mass_scale: Sequence[float] | None = None,
    tip_mass_kg: float = 0.0,
) -> list[dict[str, Any]]:
    """Bending modes of an Euler-Bernoulli beam held (w = 0) at ``held_at_m``, free elsewhere:
    uniform, or with each element's bending stiffness and mass per length scaled by
    ``element_stiffness_scale`` and ``element_mass_scale`` (one factor per element: a beam of
    other sections along it, ribs, a wear plate) and a point mass ``tip_mass_kg`` (kg) at the
    free end.

    Finite elements with cubic Hermite shapes and consistent mass. Returns, per mode,
    frequency_hz, modal_mass_kg, rigid_coupling_kgm and shape / slope_radpm at the nodes
    (``stations_m``), the shape normalised to a peak displacement of +1. Every held point
    must fall on a node.
    """
    stiffness_scale = (
        np.ones(elements)
        if element_stiffness_scale is None
        else np.asarray(element_stiffness_scale, dtype=float)
    )
    mass_scale = (
        np.ones(elements)
        if element_mass_scale is None
        else np.asarray(element_mass_scale, dtype=float)
    )
    for name, scale in (
        ("modes.element_stiffness_scale", stiffness_scale),
        ("modes.element_mass_scale", mass_scale),
    ):
        if scale.shape != (elements,) or not np.all(scale > 0.0):
            raise InputError(name, scale.size, f"must be {elements} factors > 0 (one per element)")
    if not tip_mass_kg >= 0.0:
        raise InputError("modes.tip_mass_kg", tip_mass_kg, "must be >= 0 kg")
    h = length_m / elements
    stations = np.linspace(0.0, length_m, elements + 1)
    ndof = 2 * (elements + 1)
    k_el = (
        bending_stiffness_nm2
        / h**3
        * np.array(
            [
                [12, 6 * h, -12, 6 * h],
                [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                [-12, -6 * h, 12, -6 * h],
                [6 * h, 2 * h * h, -6 * h, 4 * h * h],
            ]
        )
    )
    m_el = (
        mass_per_length_kgpm
        * h
        / 420.0
        * np.array(
            [
                [156, 22 * h, 54, -13 * h],
                [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                [54, 13 * h, 156, -22 * h],
                [-13 * h, -3 * h * h, -22 * h, 4 * h * h],
            ]
        )
    )
    stiffness = np.zeros((ndof, ndof))
    mass = np.zeros((ndof, ndof))
    for e in range(elements):
        dofs = slice(2 * e, 2 * e + 4)
        stiffness[dofs, dofs] += stiffness_scale[e] * k_el
        mass[dofs, dofs] += mass_scale[e] * m_el
    mass[2 * elements, 2 * elements] += tip_mass_kg
    held = []
    for x in held_at_m:
        node = int(round(x / h))
        if abs(node * h - x) > 1e-9 * length_m:
            raise InputError("modes.held_at_m", x, f"must fall on a node (multiples of {h:g} m)")
        held.append(2 * node)
    free = np.setdiff1d(np.arange(ndof), held)
    eigenvalues, vectors = eigh(stiffness[np.ix_(free, free)], mass[np.ix_(free, free)])
    rigid = np.zeros(ndof)
    rigid[0::2], rigid[1::2] = stations, 1.0
    modes = []
    for k in range(count):
        full = np.zeros(ndof)
        full[free] = vectors[:, k]
        peak = full[0::2][np.argmax(np.abs(full[0::2]))]
        full /= peak
        modes.append(
            {
                "frequency_hz": math.sqrt(eigenvalues[k]) / (2 * math.pi),
                "modal_mass_kg": float(full @ mass @ full),
                "rigid_coupling_kgm": float(full @ mass @ rigid),
                "stations_m": stations,
                "shape": full[0::2].copy(),
                "slope_radpm": full[1::2].copy(),
            }
        )
    return modes
