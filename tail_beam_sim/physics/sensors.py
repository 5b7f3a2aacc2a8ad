"""What the support's sensors report, from a trajectory: noise-free signals and sampled streams.

* Jack pressure: the piston chamber's absolute pressure, point-sampled, clipped to the
  transducer's range (a saturated transducer reads its limit).
* IMU on the beam: angular velocity about y and specific force (acceleration minus gravity,
  so a plate at rest reads +g along z). Each sample is the mean over its sample period, as an
  integrating, alias-free accelerometer gives: a pulse shorter than a sample shows as its
  impulse, not as a spike caught by chance.
* Camera: the particle's velocity as it last leaves the plate, stamped at the first frame
  at or after separation.
* Camera, impact point (when the camera reports it): where the particle struck, on the plate
  (x from the hinge, y across from the beam's axis, z 0), m, with Gaussian noise per
  coordinate, stamped as the same impact's rebound. The beam is modelled as a line, so a
  particle strikes on its axis: the true y is 0.
* Tail-beam accelerometer (``vibration``): specific force along the plate normal at the IMU's
  place, m/s^2, sampled at 1-100 kHz behind an anti-alias filter: the beam's response is
  computed ``oversample`` times per sample (each dense value the exact mean over its dense
  period, from the velocity change), low-passed by a Butterworth filter
  (:class:`AntiAliasFilter`, its state carried from chunk to chunk) and decimated; then white
  noise of the sensor's density over the filter's band, and clipping to the measuring range
  (a saturated sample reads its limit and is flagged). Samples travel in blocks
  (:class:`VibrationBlocks`) numbered by the running index of their first sample, so that a
  consumer detects a lost or late block from the index (:class:`BlockSequencer`).

Noise is Gaussian. :class:`SensorNoise` is the one sampling path from a clean signal to a
reading (noise level, clipping) for every producer: the offline suite here (a generator per
sensor, so changing one rate leaves the others' noise alone), the stream (noise indexed by
sample number, so chunking never changes it) and the batch (float32 draws). They differ only in
where their unit normal draws come from.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.random.bit_generator import ISeedSequence

from tail_beam_sim.physics import seeds
from tail_beam_sim.physics.ringdown_filtering import filtered_ringdown, settle_steps
from tail_beam_sim.physics.scene import SensorSpec
from tail_beam_sim.physics.solvers.lazy import lazy
from tail_beam_sim.physics.solvers.problem import FreeSegment, Samples, Trajectory
from tail_beam_sim.physics.support import Support


@dataclass
class PressureStream:
    """Jack pressure samples: stamps (s, simulation time) and absolute pressure (Pa)."""

    stamp_s: np.ndarray
    pressure_pa: np.ndarray
    variance_pa2: float


@dataclass
class ImuStream:
    """IMU samples: stamps (s), angular velocity (rad/s, T x 3), specific force (m/s^2, T x 3)."""

    stamp_s: np.ndarray
    angular_velocity_radps: np.ndarray
    linear_acceleration_mps2: np.ndarray
    gyro_variance: float
    accel_variance: float


@dataclass
class Rebound:
    """The camera's rebound measurement: stamp (s) and velocity in the plate frame (m/s)."""

    stamp_s: float
    velocity_mps: np.ndarray  # (x along the beam, y, z along the outward normal)
    true_velocity_mps: np.ndarray


@dataclass
class ImpactPoint:
    """The camera's view of where the particle struck: stamp (s, its rebound's) and the point on
    the plate (x from the hinge, y across from the beam's axis, z 0), m."""

    stamp_s: float
    point_m: np.ndarray  # (x, y, z), measured
    true_point_m: np.ndarray


@dataclass(frozen=True)
class SensorNoise:
    """The sensors' noise levels (1 sigma) and how a reading is made of a clean signal and unit
    normal draws: pressure (Pa, clipped to the transducer's range), gyro (rad/s) and
    accelerometer (m/s^2), both scaled by the IMU's rate (``imu_noise_scale``)."""

    pressure_pa: float
    gyro_radps: float
    accel_mps2: float
    pressure_range_pa: tuple[float, float]

    @classmethod
    def of(cls, spec: SensorSpec) -> SensorNoise:
        """The noise of ``spec``'s settings (one object per setting: it is frozen, and made
        for every simulated impact)."""
        return _noise_of(
            spec.pressure_noise_pa,
            spec.imu_gyro_noise_radps,
            spec.imu_accel_noise_mps2,
            spec.imu_noise_scale,
            spec.pressure_range_min_pa,
            spec.pressure_range_max_pa,
        )

    def pressure(self, clean_pa: np.ndarray, unit: np.ndarray) -> np.ndarray:
        """Pressure readings, Pa: a saturated transducer reads its limit."""
        low, high = self.pressure_range_pa
        return np.minimum(np.maximum(clean_pa + self.pressure_pa * unit, low), high)  # np.clip

    def gyro(self, clean_radps: np.ndarray, unit: np.ndarray) -> np.ndarray:
        """Angular velocity readings, rad/s."""
        return clean_radps + self.gyro_radps * unit

    def accel(self, clean_mps2: np.ndarray, unit: np.ndarray) -> np.ndarray:
        """Specific force readings, m/s^2."""
        return clean_mps2 + self.accel_mps2 * unit


@lru_cache(maxsize=256, typed=True)
def _noise_of(
    pressure_pa: float,
    gyro_radps: float,
    accel_mps2: float,
    imu_scale: float,
    pressure_min_pa: float,
    pressure_max_pa: float,
) -> SensorNoise:
    """:meth:`SensorNoise.of` of these settings (noise levels 1 sigma, the IMU's scale on
    both of its, the transducer's range in Pa)."""
    return SensorNoise(
        pressure_pa=pressure_pa,
        gyro_radps=gyro_radps * imu_scale,
        accel_mps2=accel_mps2 * imu_scale,
        pressure_range_pa=(pressure_min_pa, pressure_max_pa),
    )


def specific_force_z(trajectory: Trajectory, samples: Samples) -> np.ndarray:
    """Noise-free, instantaneous specific force along the plate normal at the IMU, m/s^2."""
    structure = trajectory.problem.structure
    angle = structure.imu_slope_shape @ samples.q
    return structure.gravity_mps2 * np.cos(angle) - structure.imu_shape @ samples.qdd


def imu_samples(
    trajectory: Trajectory,
    t_s: np.ndarray,
    period_s: float,
    states: tuple[Samples, Samples] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free IMU readings averaged over (t - period, t]: gyro (T x 3), accel (T x 3).

    ``states``: the trajectory already sampled at ``t_s`` and ``t_s - period_s`` (one pass
    for every sensor, :meth:`Trajectory.sample_many`); sampled here when None."""
    structure = trajectory.problem.structure
    now, before = states or trajectory.sample_many([t_s, t_s - period_s])
    slope, imu = structure.imu_slope_shape, structure.imu_shape
    angle = slope @ now.q
    gyro = np.zeros((t_s.size, 3))
    gyro[:, 1] = slope @ (now.q - before.q) / period_s
    accel = np.zeros((t_s.size, 3))
    rate = slope @ now.qd
    g = structure.gravity_mps2
    accel[:, 0] = -structure.imu_from_hinge_m * rate**2 - g * np.sin(angle)
    accel[:, 2] = g * np.cos(angle) - imu @ (now.qd - before.qd) / period_s
    return gyro, accel


class ImuLowPass:
    """An IMU behind a digital low-pass filter (``sensors.imu_antialias_order`` >= 1): its
    specific force along z and its pitch rate, computed ``imu_oversample`` times per sample,
    each through a Butterworth filter whose state is carried between calls, read at the sample
    instants. Calls must come in order, each starting where the last one ended (the stream's
    chunks); the first starts settled at its first sample (the beam at rest)."""

    def __init__(self, spec: SensorSpec) -> None:
        self.rate_hz = spec.imu_rate_hz
        self.oversample = spec.imu_oversample
        self._filters = [
            AntiAliasFilter(
                spec.imu_rate_hz,
                spec.imu_antialias_order,
                spec.imu_antialias_cutoff_fraction,
                spec.imu_oversample,
            )
            for _ in range(2)
        ]
        self._next_dense: int | None = None

    def __call__(
        self,
        sample_index: np.ndarray,
        response: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    ) -> tuple[np.ndarray, np.ndarray]:
        """Filtered (specific force z m/s^2, pitch rate rad/s) at samples ``sample_index``
        (stamps index / rate); ``response(stamps_s)`` gives the beam's noise-free (specific
        force z averaged over the dense period, pitch rate) at absolute stamps."""
        if sample_index.size == 0:
            return np.empty(0), np.empty(0)
        m = self.oversample
        first = self._next_dense if self._next_dense is not None else int(sample_index[0]) * m
        dense_index = np.arange(first, int(sample_index[-1]) * m + 1)
        self._next_dense = int(dense_index[-1]) + 1
        accel, rate = response(dense_index / (m * self.rate_hz))
        pick = sample_index * m - first
        return self._filters[0](accel)[pick], self._filters[1](rate)[pick]


def dense_imu_response(
    trajectory: Trajectory, t_s: np.ndarray, dense_period_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """What :class:`ImuLowPass` filters: specific force along z at the IMU averaged over the
    dense period centred on each instant (so the mean does not lag it; m/s^2) and the pitch rate
    (rad/s), at ``t_s`` in the trajectory's time."""
    rate = trajectory.problem.structure.imu_slope_shape @ trajectory.sample(t_s).qd
    return mean_specific_force_z(trajectory, t_s + 0.5 * dense_period_s, dense_period_s), rate


SEED_CHILDREN = 6  # a suite's children of its seed (SensorSuite.__init__)
_ALONG_X_AND_Z = np.array([1.0, 0.0, 1.0])  # the camera's noise mask (rebound: no y)
_ALONG_X_AND_Z.flags.writeable = False


def _seed_children(seed: int) -> tuple[ISeedSequence, ...]:
    """The six children of ``seed``, ``np.random.SeedSequence(seed).spawn(6)``'s (spawning
    costs more than a short stream's noise; a child is only read, never spawned from, so one
    set serves every suite of that seed: :func:`tail_beam_sim.physics.seeds.children`)."""
    return seeds.children_of(seed, SEED_CHILDREN)


@lru_cache(maxsize=1024)
def _first_uniform(child: ISeedSequence) -> float:
    """The first ``random()`` of a generator made from ``child``."""
    return float(seeds.generator(child).random())


def sample_grid(start_s: float, end_s: float, rate_hz: float) -> np.ndarray:
    """Sample instants k / rate_hz of the absolute clock that fall in [start_s, end_s]."""
    first = math.ceil(start_s * rate_hz - 1e-9)
    last = math.floor(end_s * rate_hz + 1e-9)
    return np.arange(first, last + 1) / rate_hz


class SensorSuite:
    """Samples a trajectory the way the support's sensors would, with seeded noise."""

    def __init__(self, spec: SensorSpec, seed: int | None = None) -> None:
        self.spec = spec
        self.noise = SensorNoise.of(spec)
        # Children of the seed: pressure, IMU, camera, contact phase, vibration, impact point
        # (the point's own, so that turning it on changes no other sensor's readings). Each
        # generator is made from its child when first used.
        self._children = _seed_children(spec.seed if seed is None else seed)

    @lazy
    def _pressure_rng(self) -> np.random.Generator:
        return seeds.generator(self._children[0])

    @lazy
    def _imu_rng(self) -> np.random.Generator:
        return seeds.generator(self._children[1])

    @lazy
    def _camera_rng(self) -> np.random.Generator:
        return seeds.generator(self._children[2])

    @lazy
    def _vibration_rng(self) -> np.random.Generator:
        return seeds.generator(self._children[4])

    @lazy
    def _point_rng(self) -> np.random.Generator:
        return seeds.generator(self._children[5])

    def phase_rng(self) -> np.random.Generator:
        """The generator of simulate()'s contact phase (the seed's fourth child, which no
        sensor's noise uses)."""
        return seeds.generator(self._children[3])

    def contact_phase(self) -> float:
        """The first uniform draw in [0, 1) of :meth:`phase_rng` (what simulate() scales to
        its contact's phase), kept per seed."""
        return _first_uniform(self._children[3])

    def pressure(
        self,
        trajectory: Trajectory,
        stamp_s: np.ndarray,
        contact_stamp_s: float,
        state: Samples | None = None,
    ) -> PressureStream:
        """Pressure samples at absolute stamps; the trajectory's t = 0 is ``contact_stamp_s``
        (``state``: the trajectory already sampled at ``stamp_s - contact_stamp_s``)."""
        noise = self.noise
        if state is None:
            state = trajectory.sample(stamp_s - contact_stamp_s)
        clean = trajectory.problem.structure.pressure_pa(state.q, state.qd)
        noisy = noise.pressure(clean, self._pressure_rng.standard_normal(stamp_s.size))
        return PressureStream(stamp_s, noisy, noise.pressure_pa**2)

    def imu(
        self,
        trajectory: Trajectory,
        stamp_s: np.ndarray,
        contact_stamp_s: float,
        states: tuple[Samples, Samples] | None = None,
    ) -> ImuStream:
        """IMU samples at absolute stamps (on the rate's grid), each averaged over its sample
        period, or behind the IMU's low-pass filter (``imu_antialias_order`` >= 1).
        ``states``: the trajectory already sampled at the stamps and one period before them
        (:meth:`imu_times`)."""
        noise = self.noise
        spec = self.spec
        gyro, accel = imu_samples(
            trajectory, stamp_s - contact_stamp_s, 1.0 / spec.imu_rate_hz, states
        )
        if spec.imu_antialias_order > 0:
            dense_period = 1.0 / (spec.imu_oversample * spec.imu_rate_hz)
            index = np.rint(stamp_s * spec.imu_rate_hz).astype(np.int64)
            accel[:, 2], gyro[:, 1] = ImuLowPass(spec)(
                index, lambda t: dense_imu_response(trajectory, t - contact_stamp_s, dense_period)
            )
        gyro = noise.gyro(gyro, self._imu_rng.standard_normal(gyro.shape))
        accel = noise.accel(accel, self._imu_rng.standard_normal(accel.shape))
        return ImuStream(stamp_s, gyro, accel, noise.gyro_radps**2, noise.accel_mps2**2)

    def imu_times(self, stamp_s: np.ndarray, contact_stamp_s: float) -> list[np.ndarray]:
        """The trajectory's times :meth:`imu` reads at stamps ``stamp_s`` (s): the stamps and
        one sample period before them (each reading is the mean over that period)."""
        now = stamp_s - contact_stamp_s
        return [now, now - 1.0 / self.spec.imu_rate_hz]

    def vibration_times(
        self, end_s: float, contact_stamp_s: float, trajectory: Trajectory | None = None
    ) -> np.ndarray:
        """The trajectory's times :meth:`vibration` reads (s): the accelerometer's dense
        (oversampled) instants from stamp 0, and one dense period before the first. Each dense
        value is the mean over the period before its instant, which the instant before bounds:
        one evaluation per instant serves as both ends. They run to ``end_s``, or, given the
        ``trajectory``, only until its filtered ring-down takes over (:meth:`_ringdown_start`)."""
        dense_rate = self.spec.vibration_oversample * self.spec.vibration_rate_hz
        first, switch, _ = self._dense_span(trajectory, end_s, contact_stamp_s)
        return np.arange(first - 1, switch) / dense_rate - contact_stamp_s

    def _dense_span(
        self, trajectory: Trajectory | None, end_s: float, contact_stamp_s: float
    ) -> tuple[int, int, int]:
        """(first, switch, count): the accelerometer's dense indices run 0 .. count - 1 (to
        ``end_s``); only ``first`` .. ``switch - 1`` are evaluated densely and filtered. Before
        ``first`` (an output sample's index) the beam has not moved yet (the ``trajectory``
        starts at rest: every dense value is g, which the filter, settled on it, passes
        unchanged); from ``switch`` on the filtered ring-down takes over
        (:meth:`_ringdown_start`). Without a trajectory: (0, count, count)."""
        spec = self.spec
        oversample = spec.vibration_oversample
        dense_rate = oversample * spec.vibration_rate_hz
        count = math.floor(end_s * dense_rate + 1e-9) + 1
        if trajectory is None:
            return 0, count, count
        switch = self._ringdown_start(trajectory, contact_stamp_s, count)
        head = trajectory.segments[0] if trajectory.segments else None
        if not isinstance(head, FreeSegment) or not head.at_rest:
            return 0, switch, count
        # dense value i spans (instant i - 1, instant i]: at rest while instant i is at or
        # before the rest's end (one more value is taken as moving, against rounding)
        rest_end = contact_stamp_s + head.end_s
        moving = (
            max(math.floor(rest_end * dense_rate) - 1, 0) if math.isfinite(rest_end) else count
        )
        first = min(moving // oversample * oversample, switch)
        return first, switch, count

    def _ringdown_start(self, trajectory: Trajectory, contact_stamp_s: float, count: int) -> int:
        """The first dense index (an output sample's) from which the accelerometer reads the
        trajectory's last free segment through the filter's steady response
        (:mod:`tail_beam_sim.physics.ringdown_filtering`), or ``count`` when none of the
        ``count`` dense instants does (the last segment is not a free one, or starts too late)."""
        last = trajectory.segments[-1] if trajectory.segments else None
        if not isinstance(last, FreeSegment) or not math.isfinite(last.start_s):
            return count
        spec = self.spec
        dense_rate = spec.vibration_oversample * spec.vibration_rate_hz
        settle = _settle_steps(
            spec.vibration_rate_hz,
            spec.vibration_antialias_order,
            spec.vibration_antialias_cutoff_fraction,
            spec.vibration_oversample,
        )
        # each dense value spans (instant - period, instant]: free from this index on
        free_from = math.ceil((contact_stamp_s + last.start_s) * dense_rate - 1e-9) + 1
        steady = max(free_from, 0) + settle
        first = -(-steady // spec.vibration_oversample) * spec.vibration_oversample
        return min(first, count)

    def vibration(
        self,
        trajectory: Trajectory,
        end_s: float,
        contact_stamp_s: float,
        dense_states: Samples | None = None,
    ) -> VibrationBlocks:
        """The accelerometer's complete blocks from stamp 0 to ``end_s`` (the trajectory's t = 0
        is ``contact_stamp_s``): dense response, anti-alias filter, noise, clipping.
        ``dense_states``: the trajectory already sampled at :meth:`vibration_times`."""
        spec = self.spec
        oversample = spec.vibration_oversample
        dense_rate = oversample * spec.vibration_rate_hz
        first, switch, count = self._dense_span(trajectory, end_s, contact_stamp_s)
        if dense_states is None:
            dense_states = trajectory.sample(
                self.vibration_times(end_s, contact_stamp_s, trajectory)
            )
        dense = mean_specific_force_z(
            trajectory,
            dense_states.t_s[1:],
            1.0 / dense_rate,
            (dense_states.take(slice(1, None)), dense_states.take(slice(None, -1))),
        )
        aa = AntiAliasFilter(
            spec.vibration_rate_hz,
            spec.vibration_antialias_order,
            spec.vibration_antialias_cutoff_fraction,
            oversample,
        )
        pieces = []
        if first > 0:  # the beam at rest reads g, and the filter settled on it passes g
            rest = trajectory.problem.structure.gravity_mps2
            pieces.append(np.full(first // oversample, rest))
            aa.settle(rest)
        pieces.append(aa(dense)[::oversample])
        if switch < count:
            last = trajectory.segments[-1]
            outputs = np.arange(switch, count, oversample) / dense_rate
            pieces.append(
                filtered_ringdown(
                    trajectory.problem.structure,
                    last.anchor_s,
                    last.q,
                    last.qd,
                    outputs - contact_stamp_s,
                    1.0 / dense_rate,
                    aa.sos,
                )
            )
        clean = np.concatenate(pieces) if len(pieces) > 1 else pieces[0]
        noisy = clean + self._vibration_rng.normal(0.0, spec.vibration_noise_mps2, clean.size)
        blocks, _ = cut_blocks(
            np.clip(noisy, -spec.vibration_range_mps2, spec.vibration_range_mps2), 0, spec
        )
        return blocks

    def rebound(self, trajectory: Trajectory, contact_stamp_s: float) -> Rebound:
        """The camera's view of the particle leaving the plate for the last time."""
        spec = self.spec
        true = np.array([0.0, 0.0, trajectory.rebound_velocity_mps])
        sigma = spec.camera_velocity_noise_mps + spec.camera_velocity_noise_fraction * abs(true[2])
        measured = true + self._camera_rng.normal(0.0, sigma, 3) * _ALONG_X_AND_Z
        separation = contact_stamp_s + trajectory.final_separation_s
        stamp = (
            math.ceil(separation * spec.camera_frame_rate_hz - 1e-9) / spec.camera_frame_rate_hz
        )
        return Rebound(stamp, measured, true)

    def reported_point(
        self, position_m: float, rebound: Rebound, support: Support
    ) -> ImpactPoint | None:
        """:meth:`impact_point` on ``support``'s plate (its ``beam_length_m`` by
        ``plate_width_m``) when the camera reports impact points (the spec's
        ``camera_reports_impact_point``), else None."""
        if not self.spec.camera_reports_impact_point:
            return None
        return self.impact_point(position_m, rebound, support.beam_length_m, support.plate_width_m)

    def impact_point(
        self, position_m: float, rebound: Rebound, length_m: float, width_m: float
    ) -> ImpactPoint:
        """The camera's view of where the particle struck ``position_m`` (m from the hinge, on
        the beam's axis), stamped as its ``rebound``: a point on the plate of ``length_m`` by
        ``width_m`` (the camera sees the plate, so a reading is never off it)."""
        true = np.array([float(position_m), 0.0, 0.0])
        sigma = self.spec.impact_point_noise_m
        noisy = true + self._point_rng.normal(0.0, sigma, 3) * np.array([1.0, 1.0, 0.0])
        half = 0.5 * width_m
        measured = np.array(
            [min(max(noisy[0], 0.0), length_m), min(max(noisy[1], -half), half), 0.0]
        )
        return ImpactPoint(rebound.stamp_s, measured, true)


def mean_specific_force_z(
    trajectory: Trajectory,
    t_s: np.ndarray,
    period_s: float,
    states: tuple[Samples, Samples] | None = None,
) -> np.ndarray:
    """Noise-free specific force along the plate normal at the IMU's place, each value the exact
    mean over (t - period, t] (from the velocity change), m/s^2; ``t_s`` in the trajectory's
    time. ``states``: the trajectory already sampled at ``t_s`` and at the period's starts."""
    structure = trajectory.problem.structure
    now, before = states or trajectory.sample_many([t_s, t_s - period_s])
    angle = structure.imu_slope_shape @ now.q
    return (
        structure.gravity_mps2 * np.cos(angle)
        - structure.imu_shape @ (now.qd - before.qd) / period_s
    )


class AntiAliasFilter:
    """The accelerometer's anti-alias low-pass: a Butterworth filter (``order``, cut-off
    ``cutoff_fraction`` x ``rate_hz``) run on the densely computed response (``oversample`` x
    ``rate_hz``), then every ``oversample``-th value kept. The state is carried between calls,
    so the output is the same however the dense signal is split."""

    def __init__(
        self, rate_hz: float, order: int, cutoff_fraction: float, oversample: int
    ) -> None:
        self.oversample = oversample
        self._sos, self._zi_unit = _butterworth(rate_hz, order, cutoff_fraction, oversample)
        self.sos = self._sos
        self._zi: np.ndarray | None = None

    def settle(self, value: float) -> None:
        """Start (or restart) settled on a constant input ``value``, as after a long rest."""
        self._zi = self._zi_unit * value

    def __call__(self, dense: np.ndarray) -> np.ndarray:
        """Filter dense values (in order, continuing the previous call); returns them all
        filtered."""
        if dense.size == 0:
            return dense.copy()
        if self._zi is None:  # start settled on the first value (the beam at rest reads +g)
            self._zi = self._zi_unit * dense[0]
        out, self._zi = sos_filter(self._sos, dense, self._zi)
        return out


@lru_cache(maxsize=1)
def _sosfilt_kernel() -> Callable[..., None] | None:
    """scipy's compiled second-order-sections kernel behind ``scipy.signal.sosfilt``; None in
    another scipy layout. Imported on first use, as scipy.signal is here: importing it takes
    a second or two, which a process that filters nothing (the command line's other verbs,
    the bag tools) need not pay."""
    try:
        from scipy.signal._sosfilt import _sosfilt
    except ImportError:  # pragma: no cover - another scipy layout: the public function
        return None
    return _sosfilt


def sos_filter(sos: np.ndarray, x: np.ndarray, zi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``scipy.signal.sosfilt(sos, x, zi=zi)`` of a 1-D signal: (output, final state), through
    scipy's compiled kernel directly when it is there (the same arithmetic; the public
    function's argument handling costs ten times the filtering of an impact's few hundred
    samples)."""
    kernel = _sosfilt_kernel()
    if kernel is None:
        from scipy import signal

        return signal.sosfilt(sos, x, zi=zi)
    out = np.array(x, dtype=float, order="C").reshape(1, -1)
    state = np.array(zi, dtype=float, order="C").reshape(1, -1, 2)
    kernel(np.ascontiguousarray(sos, dtype=float), out, state)
    return out[0], state[0]


@lru_cache(maxsize=32)
def _butterworth(
    rate_hz: float, order: int, cutoff_fraction: float, oversample: int
) -> tuple[np.ndarray, np.ndarray]:
    """The low-pass's second-order sections and their settled state for a unit input, designed
    once per setting: the design costs more than filtering one impact's samples. Shared between
    filters, which only read them."""
    from scipy import signal

    sos = signal.butter(
        order, cutoff_fraction * rate_hz, btype="low", fs=oversample * rate_hz, output="sos"
    )
    return sos, signal.sosfilt_zi(sos)


@lru_cache(maxsize=32)
def _settle_steps(rate_hz: float, order: int, cutoff_fraction: float, oversample: int) -> int:
    """``settle_steps`` of the low-pass :func:`_butterworth` designs for this setting."""
    return settle_steps(_butterworth(rate_hz, order, cutoff_fraction, oversample)[0].tobytes())


@dataclass
class VibrationBlocks:
    """Blocks of accelerometer samples (topic ``vibration``; docs/interface.md).

    Block ``b`` holds samples ``first_index[b] .. first_index[b] + lengths[b] - 1`` of the
    sensor's running sample count; ``accel_mps2`` holds all samples of all blocks, block after
    block (float32, specific force along z, m/s^2). ``stamp_s[b]`` is the stamp of the block's
    first sample and ``period_s`` the sample period, so sample ``j`` of block ``b`` is at
    ``stamp_s[b] + j * period_s``. A sample at +-``range_mps2`` is saturated (clipped).
    """

    first_index: np.ndarray  # (B,) int64
    lengths: np.ndarray  # (B,) int64
    stamp_s: np.ndarray  # (B,) s
    accel_mps2: np.ndarray  # (sum of lengths,) float32
    period_s: float
    range_mps2: float
    noise_variance: float = 0.0  # (m/s^2)^2 per sample

    @classmethod
    def empty(cls, period_s: float = 0.0, range_mps2: float = math.inf) -> VibrationBlocks:
        none = np.empty(0, dtype=np.int64)
        return cls(
            none, none.copy(), np.empty(0), np.empty(0, dtype=np.float32), period_s, range_mps2
        )

    @property
    def count(self) -> int:
        """Number of blocks."""
        return int(self.first_index.size)

    @property
    def sample_count(self) -> int:
        return int(self.accel_mps2.size)

    def offsets(self) -> np.ndarray:
        """Where each block starts in ``accel_mps2`` (B + 1 edges)."""
        return np.concatenate([[0], np.cumsum(self.lengths)]).astype(np.int64)

    def block(self, b: int) -> tuple[int, float, np.ndarray]:
        """(first index, stamp s, samples) of block ``b``."""
        edges = self.offsets()
        return (
            int(self.first_index[b]),
            float(self.stamp_s[b]),
            self.accel_mps2[edges[b] : edges[b + 1]],
        )

    def sample_stamps_s(self) -> np.ndarray:
        """The stamp of every sample, s: each block's stamp plus j sample periods."""
        within = np.arange(self.sample_count) - np.repeat(self.offsets()[:-1], self.lengths)
        return np.repeat(self.stamp_s, self.lengths) + within * self.period_s

    def saturated(self) -> np.ndarray:
        """Whether each sample reads the measuring range's limit (clipped)."""
        return np.abs(self.accel_mps2) >= np.float32(self.range_mps2)

    def select(self, keep: np.ndarray) -> VibrationBlocks:
        """The blocks where ``keep`` (B,) is true, in their order."""
        keep = np.asarray(keep, dtype=bool)
        sample_keep = np.repeat(keep, self.lengths)
        return VibrationBlocks(
            self.first_index[keep],
            self.lengths[keep],
            self.stamp_s[keep],
            self.accel_mps2[sample_keep],
            self.period_s,
            self.range_mps2,
            self.noise_variance,
        )

    def sorted(self) -> VibrationBlocks:
        """The same blocks in running-index order, each index once (a repeated block dropped)."""
        if not self.count:
            return self
        order = np.argsort(self.first_index, kind="stable")
        _, first = np.unique(self.first_index[order], return_index=True)
        return self.take(order[first])

    def index_conflict(self) -> tuple[int, int] | None:
        """The first two blocks (positions, in index order) whose running indices overlap while
        their stamps are further apart than the indices say (by more than half the first block's
        duration): a publisher whose ``angle_min``/``angle_max`` do not count the samples (every
        block index 0, or a block count). None when index and stamps agree; an exact repeat
        (same index, same stamp: a topic recorded twice) agrees."""
        if self.count < 2:
            return None
        order = np.lexsort((self.stamp_s, self.first_index))
        first, length, stamp = self.first_index[order], self.lengths[order], self.stamp_s[order]
        overlap = first[1:] < first[:-1] + length[:-1]
        off = (
            np.abs(np.diff(stamp) - np.diff(first) * self.period_s)
            > 0.5 * length[:-1] * self.period_s
        )
        bad = np.flatnonzero(overlap & off)
        return None if not bad.size else (int(order[bad[0]]), int(order[bad[0] + 1]))

    def take(self, order: np.ndarray) -> VibrationBlocks:
        """The blocks at positions ``order``, in that order."""
        edges = self.offsets()
        pieces = [self.accel_mps2[edges[b] : edges[b + 1]] for b in order]
        samples = np.concatenate(pieces) if pieces else np.empty(0, dtype=np.float32)
        return VibrationBlocks(
            self.first_index[order],
            self.lengths[order],
            self.stamp_s[order],
            samples,
            self.period_s,
            self.range_mps2,
            self.noise_variance,
        )

    @staticmethod
    def concatenate(parts: list[VibrationBlocks]) -> VibrationBlocks:
        """The blocks of ``parts`` one after another (period and range of the first non-empty
        part)."""
        parts = [p for p in parts if p.count]
        if not parts:
            return VibrationBlocks.empty()
        head = parts[0]
        return VibrationBlocks(
            np.concatenate([p.first_index for p in parts]),
            np.concatenate([p.lengths for p in parts]),
            np.concatenate([p.stamp_s for p in parts]),
            np.concatenate([p.accel_mps2 for p in parts]),
            head.period_s,
            head.range_mps2,
            head.noise_variance,
        )


def cut_blocks(
    samples: np.ndarray, first_index: int, spec: SensorSpec
) -> tuple[VibrationBlocks, np.ndarray]:
    """Samples ``first_index ..`` (clipped, m/s^2) cut into the sensor's blocks: block b holds
    indices b*N .. b*N+N-1 (N = ``vibration_block_samples``). Returns the complete blocks and
    the samples left over (the start of the next block). ``first_index`` is a block's start."""
    n = spec.vibration_block_samples
    whole = samples.size // n * n
    starts, lengths, stamps = _block_layout(first_index, whole // n, n, spec.vibration_rate_hz)
    blocks = VibrationBlocks(
        starts,
        lengths,
        stamps,
        np.asarray(samples[:whole], dtype=np.float32),
        1.0 / spec.vibration_rate_hz,
        spec.vibration_range_mps2,
        spec.vibration_noise_mps2**2,
    )
    return blocks, np.asarray(samples[whole:], dtype=np.float32)


@lru_cache(maxsize=256)
def _block_layout(
    first_index: int, count: int, block_samples: int, rate_hz: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``count`` blocks of ``block_samples`` from ``first_index`` at ``rate_hz``: their first
    indices, lengths and stamps (s), kept per layout and read only (every impact of a setting
    has the same few)."""
    starts = first_index + block_samples * np.arange(count, dtype=np.int64)
    layout = (starts, np.full(starts.size, block_samples, dtype=np.int64), starts / rate_hz)
    for array in layout:
        array.flags.writeable = False
    return layout


@dataclass
class SequenceReport:
    """What :class:`BlockSequencer` found in the blocks it was given."""

    accepted: VibrationBlocks  # the blocks to use, in index order
    gaps: list[tuple[int, int]]  # (first missing index, missing sample count), in order
    late: int  # blocks refused: they came after a later block was accepted (or repeated one)
    # blocks refused whose index is behind the stream's while their stamp is not: the index does
    # not count samples
    misindexed: int = 0


class BlockSequencer:
    """Keeps a block stream in running-index order and counts what is missing.

    Each call takes the blocks that arrived since the last one; it sorts them by index (a block
    late within one call is put back in order), accepts those that continue the stream, reports
    every jump in the index as a gap (samples lost), and refuses a block whose index is behind
    what was already accepted (late past a later block, or a repeat) with a count, counted apart
    (``misindexed``) when its stamp is not where its index puts it. Totals are kept in
    ``lost_samples``, ``gap_count`` (gaps), ``late_blocks`` and ``misindexed_blocks``.
    """

    def __init__(self) -> None:
        self.next_index: int | None = None
        self.next_stamp_s: float | None = None  # the stamp the sample at next_index has, s
        self.lost_samples = 0
        self.gap_count = 0
        self.late_blocks = 0
        self.misindexed_blocks = 0
        self.accepted_samples = 0

    def restart(self) -> None:
        """The source started its running index again (a restarted simulator): the next block
        begins the stream anew; the totals are kept."""
        self.next_index = None
        self.next_stamp_s = None

    def push(self, blocks: VibrationBlocks) -> SequenceReport:
        order = np.lexsort(
            (blocks.stamp_s, blocks.first_index)
        )  # repeats kept: refused below like late blocks
        keep = np.zeros(blocks.count, dtype=bool)
        gaps: list[tuple[int, int]] = []
        expected, expected_stamp = self.next_index, self.next_stamp_s
        misindexed = 0
        for k, b in enumerate(order):
            first, length, stamp = (
                int(blocks.first_index[b]),
                int(blocks.lengths[b]),
                float(blocks.stamp_s[b]),
            )
            if expected is not None and first < expected:
                # Behind the stream: late or repeated when its stamp is where its index puts it,
                # else its index does not count the samples (a publisher breaking the contract).
                implied = (
                    None
                    if expected_stamp is None
                    else expected_stamp - (expected - first) * blocks.period_s
                )
                misindexed += int(
                    implied is not None and abs(stamp - implied) > 0.5 * length * blocks.period_s
                )
                continue
            if expected is not None and first > expected:
                gaps.append((expected, first - expected))
            keep[k] = True
            expected, expected_stamp = first + length, stamp + length * blocks.period_s
        refused = int((~keep).sum())
        accepted = blocks.take(order[keep])
        self.next_index, self.next_stamp_s = expected, expected_stamp
        self.lost_samples += sum(n for _, n in gaps)
        self.gap_count += len(gaps)
        self.late_blocks += refused - misindexed
        self.misindexed_blocks += misindexed
        self.accepted_samples += accepted.sample_count
        return SequenceReport(accepted, gaps, refused - misindexed, misindexed)


class IndexSpan:
    """Counts the samples missing from a block stream whatever the order blocks come in: the
    span from the lowest first index to the highest end, less the samples received (a recorder
    writes every block it gets, late ones included, so only a block never received is lost)."""

    def __init__(self) -> None:
        self.first: int | None = None
        self.end: int | None = None
        self.samples = 0
        self.blocks = 0

    def add(self, first_index: int, length: int) -> None:
        self.first = first_index if self.first is None else min(self.first, first_index)
        self.end = (
            first_index + length if self.end is None else max(self.end, first_index + length)
        )
        self.samples += length
        self.blocks += 1

    @property
    def lost_samples(self) -> int:
        return (
            0
            if self.first is None or self.end is None
            else max(self.end - self.first - self.samples, 0)
        )
