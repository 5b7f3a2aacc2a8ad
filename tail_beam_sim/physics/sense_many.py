"""Every sensor of many scenes at once, from a :class:`~tail_beam_sim.physics.contact_family.
ContactFamily`: what :func:`tail_beam_sim.physics.simulate.sense` makes of each trajectory, one
array operation per signal for the whole group.

A group is scenes that share the sample rates, the window and the accelerometer's settings
(:func:`layout_key`); each scene has its own impact (a row of the family), seed, noise levels
and ranges. Each sensor's readings are read for the whole group at once
(:meth:`ContactFamily.read`, the free response as products of the sensor grid's exponentials,
kept per setting, and each scene's); per scene remain only its seeded generators' draws (its
noise must be the one ``simulate`` gives) and the result's objects. The noise-free histories
are computed when first read (:class:`~tail_beam_sim.physics.result.LazyHistory`): the
summary's peaks are read from the same instants without them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

import numpy as np

from tail_beam_sim.physics import seeds
from tail_beam_sim.physics.contact_family import ContactFamily, Grid, _product, grid_basis
from tail_beam_sim.physics.result import LazyHistory, SimulationResult
from tail_beam_sim.physics.ringdown_filtering import _dense_gain, settle_steps
from tail_beam_sim.physics.scene import Scene, SensorSpec
from tail_beam_sim.physics.sensors import (
    SEED_CHILDREN,
    ImuStream,
    PressureStream,
    Rebound,
    SensorSuite,
    VibrationBlocks,
    _butterworth,
    _sosfilt_kernel,
)
from tail_beam_sim.physics.solvers.problem import Trajectory

HISTORY_RATE_HZ = 20000.0


def layout_key(scene: Scene, vibration: bool) -> tuple[Any, ...]:
    """What scenes of one group share: window, pre-contact time, sample rates and the
    accelerometer's settings (noise, ranges and seed may differ)."""
    spec = scene.sensors
    return (
        scene.window_s,
        scene.pre_contact_s,
        spec.pressure_rate_hz,
        spec.imu_rate_hz,
        spec.camera_frame_rate_hz,
        vibration,
        spec.vibration_rate_hz,
        spec.vibration_oversample,
        spec.vibration_antialias_order,
        spec.vibration_antialias_cutoff_fraction,
        spec.vibration_block_samples,
    )


def supported(spec: SensorSpec) -> bool:
    """Whether the group path covers these sensors (an IMU behind its own low-pass is left to
    ``sense``)."""
    return spec.imu_antialias_order == 0


def summary_figures(
    scene: Scene,
    trajectory: Trajectory,
    peak_pressure_change_pa: float,
    peak_angular_velocity_radps: float,
    peak_dynamic_accel_mps2: float,
) -> dict[str, Any]:
    """The noise-free figures of an impact (the keys of ``tail-beam simulate --json``), given
    the peaks of its histories after first contact."""
    impact = scene.impact
    rebound = trajectory.rebound_velocity_mps
    return {
        "material": impact.material.name,
        "radius_m": impact.radius_m,
        "mass_kg": impact.mass_kg,
        "position_m": impact.position_m,
        "drop_height_m": impact.drop_height_m,
        "impact_speed_mps": impact.impact_speed_mps,
        "rebound_speed_mps": max(rebound, 0.0),
        "restitution": max(rebound, 0.0) / impact.impact_speed_mps,
        "contact_duration_s": trajectory.contacts[0].duration_s,
        "peak_contact_force_n": max(c.peak_force_n for c in trajectory.contacts),
        "peak_jack_pressure_change_pa": peak_pressure_change_pa,
        "peak_beam_angular_velocity_radps": peak_angular_velocity_radps,
        "peak_imu_dynamic_accel_mps2": peak_dynamic_accel_mps2,
        "n_contacts": len(trajectory.contacts),
        "particle_at_rest": trajectory.particle_at_rest,
        "contact_model": scene.contact_model,
        "solver": trajectory.solver,
        "window_s": scene.window_s,
    }


def _grid_counts(end_s: np.ndarray, rate_hz: float) -> np.ndarray:
    """How many instants k / rate of [0, end] each scene has (``sensors.sample_grid``)."""
    return np.floor(end_s * rate_hz + 1e-9).astype(np.int64) + 1


def _stamp_grid(
    end_s: np.ndarray, rate_hz: float, contact_s: np.ndarray
) -> tuple[Grid, np.ndarray]:
    """A sensor's stamps k / rate over the group (as many as the longest scene has, s) as a
    Grid of times from each scene's contact, and each scene's own count of them."""
    counts = _grid_counts(end_s, rate_hz)
    stamps = np.arange(int(counts.max())) / rate_hz
    grid = Grid(
        stamps[None, :] - contact_s[:, None],
        stamps,
        contact_s,
        key=("stamps", rate_hz, stamps.size),
    )
    return grid, counts


# values per temporary array of the accelerometer's output stage, which works through its scenes
# in blocks of rows of about this size (128 KiB): temporaries the size of the whole group's
# output (megabytes) are fresh pages from the system at every call, whose faults cost more than
# the arithmetic on them
CHUNK_VALUES = 16384

SMALL_ANGLE_RAD = 1e-3  # below it, cos and sin by their Taylor polynomials (to float rounding)


def _cos(angle: np.ndarray) -> np.ndarray:
    """cos of small angles (the beam's sway at the IMU, 1e-4 rad) as 1 - a^2/2 + a^4/24 (the
    next term, a^6/720, is under 2e-21 there: float rounding), np.cos otherwise."""
    if angle.size and np.abs(angle).max() < SMALL_ANGLE_RAD:
        square = angle * angle
        return 1.0 - square * (0.5 - square * (1.0 / 24.0))
    return np.cos(angle)


def _small_cos_in_place(angle: np.ndarray) -> np.ndarray:
    """:func:`_cos` of angles known to be under SMALL_ANGLE_RAD, computed in ``angle``'s own
    memory (the ring-down's arrays are an impact's every output sample)."""
    square = np.multiply(angle, angle, out=angle)
    term = square * (1.0 / 24.0)
    np.subtract(0.5, term, out=term)
    term *= square
    return np.subtract(1.0, term, out=term)


def _sin(angle: np.ndarray) -> np.ndarray:
    """sin of small angles as a - a^3/6 + a^5/120 (:func:`_cos`), np.sin otherwise."""
    if angle.size and np.abs(angle).max() < SMALL_ANGLE_RAD:
        square = angle * angle
        return angle * (1.0 - square * (1.0 / 6.0 - square * (1.0 / 120.0)))
    return np.sin(angle)


def sense_group(
    family: ContactFamily,
    rows: np.ndarray,
    scenes: Sequence[Scene],
    vibration: bool,
    history_of: Callable[[Scene, Trajectory], dict[str, np.ndarray]],
) -> list[SimulationResult]:
    """The sensors of ``scenes`` (one group: :func:`layout_key`), scene i reading impact
    ``rows[i]`` of ``family`` (whose ``ok`` must hold): each scene's result as ``sense`` gives
    it, the summary without its tier and error estimate (the plan's); its histories are
    ``history_of(scene, trajectory)``, computed when first read."""
    structure = family.structure
    scene0 = scenes[0]
    spec0 = scene0.sensors
    window, pre = scene0.window_s, scene0.pre_contact_s
    count = len(scenes)
    g = structure.gravity_mps2
    seeds.children([scene.sensors.seed for scene in scenes], SEED_CHILDREN)  # in one batch
    suites = [SensorSuite(scene.sensors) for scene in scenes]
    slowest = min(spec0.pressure_rate_hz, spec0.imu_rate_hz)
    contact = np.array([pre + (0.0 + (1.0 / slowest) * suite.contact_phase()) for suite in suites])
    end = contact + window
    duration = family.duration_s[rows]

    # the summary's peaks after first contact (summarise) over the histories' instants: the
    # uniform ones from contact on and the contact's samples (the histories themselves are
    # computed when first read)
    uniform = np.arange(-pre, window + 0.5 / HISTORY_RATE_HZ, 1.0 / HISTORY_RATE_HZ)
    uniform = uniform[uniform >= 0.0]
    n = family.n
    zero_n = np.zeros(n)
    slope, imu_shape = structure.imu_slope_shape, structure.imu_shape
    area = structure.piston_area_m2
    # pressure change, pitch rate, acceleration along z at the IMU: weights of [q; q'; q'']
    jack = np.concatenate(
        [
            structure.jack_stiffness_npm * structure.jack_shape / area,
            structure.jack_damping_nspm * structure.jack_shape / area,
            zero_n,
        ]
    )
    rate_0 = np.zeros(3 * n)
    rate_0[n] = 1.0
    outputs = np.stack([jack, rate_0, np.concatenate([zero_n, zero_n, imu_shape])])
    on_grid = _grid_peaks(family, rows, uniform, outputs, ("history", pre, window))
    on_nodes = family.read_at_samples(rows, outputs)
    on_nodes[1:] = np.abs(on_nodes[1:])
    peak_change, peak_rate, peak_accel = np.maximum(on_grid, np.nanmax(on_nodes, axis=2))
    peak_pressure = structure.setting_pressure_pa + peak_change

    # pressure: point samples at k / rate
    pressure_grid, pressure_counts = _stamp_grid(end, spec0.pressure_rate_hz, contact)
    clean = structure.setting_pressure_pa + family.read(rows, pressure_grid, jack)[0]
    pressure_stamps = pressure_grid.grid
    unit = np.zeros(clean.shape)
    for rng, row, k in zip(_generators(suites, PRESSURE), unit, pressure_counts.tolist()):
        rng.standard_normal(out=row[:k])
    sigma = np.array([s.noise.pressure_pa for s in suites])[:, None]
    # clean + sigma * unit, in the draws' memory (no temporaries the size of the group's stream)
    pressure = np.add(clean, np.multiply(sigma, unit, out=unit), out=unit)
    # a saturated transducer reads its limit (SensorNoise.pressure)
    np.minimum(
        np.maximum(pressure, _per_scene(suites, 0), out=pressure),
        _per_scene(suites, 1),
        out=pressure,
    )

    # IMU: each reading the mean over the period before its stamp (sensors.imu_samples); the
    # period's start is the stamp before (the first: the beam at rest)
    imu_grid, imu_counts = _stamp_grid(end, spec0.imu_rate_hz, contact)
    imu_stamps = imu_grid.grid
    period = 1.0 / spec0.imu_rate_hz
    angle, pitch_rate, velocity = family.read(
        rows,
        imu_grid,
        np.stack(
            [
                np.concatenate([slope, zero_n, zero_n]),
                np.concatenate([zero_n, slope, zero_n]),
                np.concatenate([zero_n, imu_shape, zero_n]),
            ]
        ),
    )
    gyro = np.zeros(angle.shape + (3,))
    gyro[:, 0, 1] = angle[:, 0] / period
    gyro[:, 1:, 1] = (angle[:, 1:] - angle[:, :-1]) / period
    accel = np.zeros_like(gyro)
    accel[:, :, 0] = -structure.imu_from_hinge_m * pitch_rate**2 - g * _sin(angle)
    accel[:, :, 2] = g * _cos(angle)
    accel[:, 0, 2] -= velocity[:, 0] / period
    accel[:, 1:, 2] -= (velocity[:, 1:] - velocity[:, :-1]) / period
    gyro_unit = np.zeros_like(gyro)
    accel_unit = np.zeros_like(gyro)
    imu_rngs = _generators(suites, IMU)
    for rng, gyro_row, accel_row, k in zip(imu_rngs, gyro_unit, accel_unit, imu_counts.tolist()):
        rng.standard_normal(out=gyro_row[:k])
        rng.standard_normal(out=accel_row[:k])
    # clean + sigma * unit, in place (as the pressure's)
    gyro_sigma = np.array([s.noise.gyro_radps for s in suites])[:, None, None]
    accel_sigma = np.array([s.noise.accel_mps2 for s in suites])[:, None, None]
    np.add(gyro, np.multiply(gyro_sigma, gyro_unit, out=gyro_unit), out=gyro)
    np.add(accel, np.multiply(accel_sigma, accel_unit, out=accel_unit), out=accel)

    blocks = (
        _DenseSpan(spec0, contact, end, duration).blocks(family, rows, suites)
        if vibration
        else [VibrationBlocks.empty()] * count
    )

    rebounds = _rebounds(family, rows, suites, contact)
    out = []
    # per scene as Python numbers (the same values), read once each
    stamps_s, kps, kis = contact.tolist(), pressure_counts.tolist(), imu_counts.tolist()
    peaks = zip(peak_pressure.tolist(), peak_rate.tolist(), peak_accel.tolist())
    trajectories = family.trajectories(rows.tolist())
    for i, (scene, suite, rebound, trajectory, peak) in enumerate(
        zip(scenes, suites, rebounds, trajectories, peaks)
    ):
        stamp = stamps_s[i]
        point = suite.reported_point(scene.impact.position_m, rebound, scene.support)
        kp, ki = kps[i], kis[i]
        noise = suite.noise
        out.append(
            SimulationResult(
                scene=scene,
                trajectory=trajectory,
                contact_stamp_s=stamp,
                history=LazyHistory(partial(history_of, scene, trajectory)),
                pressure=PressureStream(
                    pressure_stamps[:kp], pressure[i, :kp], noise.pressure_pa**2
                ),
                imu=ImuStream(
                    imu_stamps[:ki],
                    gyro[i, :ki],
                    accel[i, :ki],
                    noise.gyro_radps**2,
                    noise.accel_mps2**2,
                ),
                rebound=rebound,
                summary=summary_figures(
                    scene,
                    trajectory,
                    peak[0] - scene.support.setting_pressure_pa,
                    peak[1],
                    peak[2],
                ),
                vibration=blocks[i],
                point=point,
            )
        )
    return out


# which child of a scene's seed each sensor's generator is made from (SensorSuite's)
PRESSURE, IMU, CAMERA, VIBRATION = 0, 1, 2, 4


def _generators(suites: Sequence[SensorSuite], child: int) -> list[np.random.Generator]:
    """Each suite's generator of its seed's ``child`` (the one ``SensorSuite._pressure_rng``
    and its siblings make: the same stream), made here in one pass: the group's suites are its
    own and each generator is read once, so the lazy attributes' calls per suite are spared."""
    make, bits = np.random.Generator, np.random.PCG64
    out = []
    for suite in suites:
        seed = suite._children[child]
        out.append(make(bits(seed)) if type(seed) is seeds.Child else seeds.generator(seed))
    return out


def _per_scene(suites: Sequence[SensorSuite], bound: int) -> float | np.ndarray:
    """The pressure transducer's lower (``bound`` 0) or upper (1) limit of each scene, Pa: one
    number when the scenes share it (a scalar bound costs less than a column), else (S, 1)."""
    values = [suite.noise.pressure_range_pa[bound] for suite in suites]
    return values[0] if values.count(values[0]) == len(values) else np.array(values)[:, None]


def _grid_peaks(
    family: ContactFamily,
    rows: np.ndarray,
    uniform: np.ndarray,
    outputs: np.ndarray,
    key: tuple[Any, ...],
) -> np.ndarray:
    """(3, S): the largest value over the instants ``uniform`` (s from first contact, rising,
    from 0) of each scene's readings ``outputs`` (3, 3n), the first signed, the others in
    magnitude: the maxima of :meth:`ContactFamily.read` on the whole grid.

    A structure of one mode rings after the contact as g(t) = Re(w exp(lambda (t - T))), whose
    derivative vanishes only at the instants T + (pi/2 + m pi - arg(w lambda)) / omega; g is
    monotonic between them, so its largest value (and |g|'s) over the grid is at a grid instant
    next to one of them or at the grid's end. Read are only those (two either side of each)
    and every instant through the scene's contact; a structure of more modes is read on the
    whole grid."""
    count = rows.size
    structure = family.structure
    eigenvalues = structure._eigen[0][structure._half_spectrum[0]]
    omega = float(eigenvalues[0].imag) if eigenvalues.size == 1 else 0.0
    if eigenvalues.size != 1 or not abs(omega) > 0.0 or uniform.size < 8:
        values = family.read(
            rows,
            Grid(
                np.broadcast_to(uniform, (count, uniform.size)), uniform, np.zeros(count), key=key
            ),
            outputs,
        )
        values[1:] = np.abs(values[1:])
        return values.max(axis=2)
    omega = abs(omega)
    duration = family.duration_s[rows]  # (S,)
    # the derivative's zeros after each contact, from the first at or after its end
    phase = np.angle(family.free_weights(rows, outputs)[:, :, 0] * eigenvalues[0])  # (o, S)
    if eigenvalues[0].imag < 0.0:
        phase = -phase
    first = np.ceil((phase - 0.5 * np.pi) / np.pi)
    extrema = int(math.ceil(omega * float(uniform[-1]) / np.pi)) + 2
    m = first[:, :, None] + np.arange(extrema)
    instants = duration[None, :, None] + (0.5 * np.pi + m * np.pi - phase[:, :, None]) / omega
    at = np.searchsorted(uniform, instants.transpose(1, 0, 2).reshape(count, -1))  # (S, 3E)
    near = (at[:, :, None] + np.arange(-2, 2)).reshape(count, -1)
    # every instant through each scene's contact and two after (the columns past a shorter
    # contact repeat the grid's last instant, a free one)
    through = np.searchsorted(uniform, duration, side="right") + 2  # (S,)
    columns = np.arange(int(through.max()))
    contact = np.where(columns[None, :] < through[:, None], columns[None, :], uniform.size - 1)
    index = np.concatenate([contact, near, np.full((count, 1), uniform.size - 1)], axis=1)
    index = np.clip(index, 0, uniform.size - 1)
    values = family.read(rows, Grid(uniform[index], uniform, np.zeros(count), index, key), outputs)
    values[1:] = np.abs(values[1:])
    return values.max(axis=2)


def _rebounds(
    family: ContactFamily, rows: np.ndarray, suites: Sequence[SensorSuite], contact: np.ndarray
) -> list[Rebound]:
    """Every scene's camera view of its rebound, as ``SensorSuite.rebound`` makes it (each
    scene's three draws from its own camera generator), the arithmetic for all at once: the
    particle leaves at the contact's end with the contact's separation speed."""
    true = np.zeros((rows.size, 3))
    true[:, 2] = family.end_zd_mps[rows]
    specs = [suite.spec for suite in suites]
    sigma = np.array([spec.camera_velocity_noise_mps for spec in specs]) + np.array(
        [spec.camera_velocity_noise_fraction for spec in specs]
    ) * np.abs(true[:, 2])
    draws = np.empty((rows.size, 3))
    for rng, row, scale in zip(_generators(suites, CAMERA), draws, sigma.tolist()):
        row[:] = rng.normal(0.0, scale, 3)
    measured = true + draws * np.array([1.0, 0.0, 1.0])
    rate = np.array([spec.camera_frame_rate_hz for spec in specs])
    separation = contact + family.duration_s[rows]
    stamps = (np.ceil(separation * rate - 1e-9) / rate).tolist()
    return [Rebound(stamp, measured[i], true[i]) for i, stamp in enumerate(stamps)]


class _DenseSpan:
    """The accelerometer's dense instants of every scene (``SensorSuite._dense_span``): the
    beam rests (reads g) before index ``first``, the dense response runs through the
    anti-alias filter from ``first`` to ``switch`` (padded to the longest span), the filtered
    ring-down in closed form after, to ``count``."""

    def __init__(
        self, spec: SensorSpec, contact: np.ndarray, end: np.ndarray, duration: np.ndarray
    ) -> None:
        self.spec = spec
        m = self.oversample = spec.vibration_oversample
        self.dense_rate = m * spec.vibration_rate_hz
        self.sos, self.zi_unit = _butterworth(
            spec.vibration_rate_hz,
            spec.vibration_antialias_order,
            spec.vibration_antialias_cutoff_fraction,
            m,
        )
        self.contact = contact
        count = self.count = np.floor(end * self.dense_rate + 1e-9).astype(np.int64) + 1
        free_from = np.ceil((contact + duration) * self.dense_rate - 1e-9).astype(np.int64) + 1
        steady = np.maximum(free_from, 0) + settle_steps(self.sos.tobytes())
        switch = self.switch = np.minimum(-(-steady // m) * m, count)
        moving = np.maximum(np.floor(contact * self.dense_rate).astype(np.int64) - 1, 0)
        self.first = np.minimum(moving // m * m, switch)
        self.span = int((switch - self.first).max())
        # each dense value the mean over the dense period before its instant: one instant
        # more, before the first
        low = int(self.first.min()) - 1
        self.index = self.first[:, None] - 1 - low + np.arange(self.span + 1)[None, :]
        self.grid = np.arange(low, low + int(self.index.max()) + 1) / self.dense_rate
        self.times = self.grid[self.index] - contact[:, None]

    def blocks(
        self, family: ContactFamily, rows: np.ndarray, suites: Sequence[SensorSuite]
    ) -> list[VibrationBlocks]:
        """Every scene's blocks: dense values at :attr:`times`
        (``sensors.mean_specific_force_z``), filter, ring-down, noise, clipping."""
        structure = family.structure
        n = family.n
        zero_n = np.zeros(n)
        angle, velocity = family.read(
            rows,
            Grid(self.times, self.grid, self.contact, self.index),
            np.stack(
                [
                    np.concatenate([structure.imu_slope_shape, zero_n, zero_n]),
                    np.concatenate([zero_n, structure.imu_shape, zero_n]),
                ]
            ),
        )
        g = structure.gravity_mps2
        m, dense_rate = self.oversample, self.dense_rate
        dense_period = 1.0 / dense_rate
        first, switch, count = self.first, self.switch, self.count
        angle = angle[:, 1:]
        change = velocity[:, 1:] - velocity[:, :-1]
        dense = np.ascontiguousarray(g * _cos(angle) - change / dense_period)
        if self.span:
            start = np.where(first > 0, g, dense[:, 0])
            state = np.ascontiguousarray(self.zi_unit[None, :, :] * start[:, None, None])
            dense = _sos_filter_rows(self.sos, dense, state)
        picks = dense[:, ::m]
        outputs = -(-count // m)
        j = np.arange(int(outputs.max()))
        # by blocks of scenes (CHUNK_VALUES): the ring-down everywhere (past each scene's last
        # output: unused), then, row by row, each scene's rest (g) and filtered span over it and
        # its noise (its own generator, through a buffer of one row: normal(0, sigma, k) is
        # sigma times standard_normal(k), draw by draw); then clipping and float32: as
        # SensorSuite.vibration and cut_blocks make them
        ringdown = _filtered_ringdown(
            family, rows, (j * m) / dense_rate, self.contact, dense_period, self.sos
        )
        limits = [suite.spec.vibration_range_mps2 for suite in suites]
        if limits.count(limits[0]) == len(limits):  # one range (a scalar bound is cheaper)
            limit: float | np.ndarray = limits[0]
        else:
            limit = np.array(limits)[:, None]
        sigmas = [suite.spec.vibration_noise_mps2 for suite in suites]
        scenes = list(
            zip(
                sigmas,
                _generators(suites, VIBRATION),
                picks,
                (first // m).tolist(),
                ((switch - first) // m).tolist(),
                outputs.tolist(),
            )
        )
        samples = np.empty((len(scenes), j.size), dtype=np.float32)
        noise = np.empty(j.size)
        step = max(1, CHUNK_VALUES // max(j.size, 1))
        for lo in range(0, len(scenes), step):
            hi = min(lo + step, len(scenes))
            clean = ringdown(lo, hi)
            for row, (sigma, rng, pick, rest, span, k) in zip(clean, scenes[lo:hi]):
                row[:rest] = g
                row[rest : rest + span] = pick[:span]
                draws = rng.standard_normal(out=noise[:k])
                draws *= sigma
                row[:k] += draws
            bound = limit[lo:hi] if isinstance(limit, np.ndarray) else limit
            # np.clip, as min(max(x, -limit), limit)
            np.minimum(np.maximum(clean, -bound, out=clean), bound, out=clean)
            samples[lo:hi] = clean
        size = self.spec.vibration_block_samples
        whole = outputs // size
        starts = size * np.arange(int(whole.max()), dtype=np.int64)
        stamps = starts / self.spec.vibration_rate_hz
        lengths = np.full(starts.size, size, dtype=np.int64)
        period = 1.0 / self.spec.vibration_rate_hz
        return [
            VibrationBlocks(
                starts[:b],
                lengths[:b],
                stamps[:b],
                row[: b * size],
                period,
                own_range,
                sigma**2,
            )
            for b, row, own_range, sigma in zip(whole.tolist(), samples, limits, sigmas)
        ]


def _sos_filter_rows(sos: np.ndarray, x: np.ndarray, zi: np.ndarray) -> np.ndarray:
    """Every row of ``x`` (S, T) through the second-order sections from its own state ``zi``
    (S, sections, 2): ``sensors.sos_filter`` row by row, in one call."""
    kernel = _sosfilt_kernel()
    if kernel is None:  # pragma: no cover - another scipy layout: the public function
        from scipy import signal

        return signal.sosfilt(sos, x, axis=-1, zi=zi.transpose(1, 0, 2))[0]
    out = np.array(x, dtype=float, order="C")
    kernel(np.ascontiguousarray(sos, dtype=float), out, zi)
    return out


def _filtered_ringdown(
    family: ContactFamily,
    rows: np.ndarray,
    grid_s: np.ndarray,
    contact_s: np.ndarray,
    dense_period_s: float,
    sos: np.ndarray,
) -> Callable[[int, int], np.ndarray]:
    """Rows ``lo:hi`` (of S) of the (S, T) ``ringdown_filtering.filtered_ringdown`` of impacts
    ``rows`` at the instants ``grid_s`` (absolute) of scenes whose contacts start at
    ``contact_s``, as a function of ``(lo, hi)``: the anti-alias filter's steady output over the
    free ring-down, each term's exponential split into the grid's and the scene's
    (:meth:`ContactFamily._free_on_grid`). The rows are computed when asked, a block at a time
    (CHUNK_VALUES)."""
    structure = family.structure
    n = family.n
    keep = structure._half_spectrum[0]
    eigenvalues = structure._eigen[0][keep]
    real, imag = family._free_amplitude  # (N, 2n, k)
    amplitude = real[rows] + 1j * imag[rows]
    angle_weight = np.einsum("i,sik->sk", structure.imu_slope_shape, amplitude[:, :n])
    velocity_weight = np.einsum("i,sik->sk", structure.imu_shape, amplitude[:, n:])
    dynamic_weight = velocity_weight * _dense_gain(structure, dense_period_s, sos)
    offset = contact_s + family.duration_s[rows]
    if (
        max(
            np.max(np.abs(np.multiply.outer(offset, eigenvalues.real)), initial=0.0),
            np.max(np.abs(np.multiply.outer(grid_s, eigenvalues.real)), initial=0.0),
        )
        > 300.0
    ):
        # a strongly damped mode: instant by instant
        dt = grid_s[None, :] - offset[:, None]
        angle = np.zeros(dt.shape)
        dynamic = np.zeros(dt.shape)
        for k, lam in enumerate(eigenvalues):
            growth = np.exp(lam.real * dt)
            cos, sin = growth * np.cos(lam.imag * dt), growth * np.sin(lam.imag * dt)
            a, d = angle_weight[:, k : k + 1], dynamic_weight[:, k : k + 1]
            angle = angle + (a.real * cos - a.imag * sin)
            dynamic = dynamic + (d.real * cos - d.imag * sin)
        full = structure.gravity_mps2 * np.cos(angle) + dynamic
        return lambda lo, hi: full[lo:hi]
    shifted = np.exp(-np.multiply.outer(offset, eigenvalues))  # (S, k)
    basis = grid_basis(structure, grid_s, ("outputs", dense_period_s, grid_s.size, grid_s[-1]))
    # angle and dynamic term of a block of scenes in one product: Re(w b) = [w.re, -w.im] .
    # [b.re; b.im]
    weights = np.concatenate([angle_weight * shifted, dynamic_weight * shifted])  # (2S, k)
    columns = np.concatenate([weights.real, -weights.imag], axis=1)
    stacked = np.concatenate([basis.real, basis.imag])
    count = offset.size
    # |angle| <= sum_k |weight| max|basis|: small (the polynomial), unless the bound says not
    bound = float(np.max(np.abs(weights[:count]) @ np.abs(basis).max(axis=1), initial=0.0))
    g = structure.gravity_mps2

    def block(lo: int, hi: int) -> np.ndarray:
        pair = np.concatenate([columns[lo:hi], columns[count + lo : count + hi]])
        both = _product(pair, stacked)
        angle, dynamic = both[: hi - lo], both[hi - lo :]
        cos = _small_cos_in_place(angle) if bound < SMALL_ANGLE_RAD else np.cos(angle)
        return np.add(dynamic, np.multiply(cos, g, out=cos), out=dynamic)

    return block


__all__ = ["HISTORY_RATE_HZ", "layout_key", "sense_group", "summary_figures", "supported"]
