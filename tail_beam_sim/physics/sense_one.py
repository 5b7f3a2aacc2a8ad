"""Every sensor of one impact from one evaluation of its trajectory: ``simulate``'s lean path.

It makes what :func:`tail_beam_sim.physics.simulate.sense_general` makes of a trajectory (the
same noise, stamps, blocks and summary; the signals to rounding) with a fraction of the array
operations, which for one impact's few thousand instants cost more than the arithmetic:

* every instant a sensor or the summary reads (the histories' from first contact on, the
  IMU's stamps and one period before, the pressure's, the accelerometer's dense instants) is
  evaluated in one pass, and only the readings the sensors take, not the whole state: the
  beam's angle and rate, the pressure change, the pitch rate, angle, normal velocity and
  acceleration at the IMU, rows of a readout matrix kept per structure;
* the last free segment, where most instants fall, reads them in closed form over every
  instant at once (its exponentials times each reading's modal weights, as
  :meth:`~tail_beam_sim.physics.structure.LinearStructure.propagate` and
  :func:`~tail_beam_sim.physics.ringdown_filtering.filtered_ringdown` have them); the other
  segments' instants (the rest before the contact, the contact itself) are then evaluated on
  their own segment (:meth:`~tail_beam_sim.physics.solvers.Trajectory.sample_segment`) and put
  in place;
* the instants on an even grid there, the histories' uniform tail and the accelerometer's
  ring-down outputs, read each exponential as the first instant's times the grid's, kept per
  structure and spacing: no exponential, cosine or sine per instant;
* the histories are computed when first read (:func:`history`), as the group path's are: a
  data set's users read the streams and the summary, whose peaks are read at the same instants.

It covers trajectories of free segments and contacts (every solver but scipy's, whose free
flights are dense outputs) ending in a free segment, and sensors the group path covers (an IMU
behind its own low-pass is left to the general path).
"""

from __future__ import annotations

from functools import lru_cache, partial
from itertools import accumulate

import numpy as np

from tail_beam_sim.physics.result import LazyHistory, SimulationResult
from tail_beam_sim.physics.ringdown_filtering import _dense_gain
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.sense_many import (
    HISTORY_RATE_HZ,
    SMALL_ANGLE_RAD,
    _cos,
    _small_cos_in_place,
    summary_figures,
    supported,
)
from tail_beam_sim.physics.sensors import (
    AntiAliasFilter,
    ImuStream,
    PressureStream,
    SensorSuite,
    VibrationBlocks,
    cut_blocks,
    sample_grid,
)
from tail_beam_sim.physics.solvers.problem import (
    ContactSegment,
    FreeSegment,
    OdeSegment,
    Trajectory,
)
from tail_beam_sim.physics.structure import LinearStructure

# Rows of the readings: the beam's angle (rad), at the IMU the pitch rate (rad/s) and the
# velocity along the plate normal (m/s), the jack pressure's change (Pa), the beam's rate
# (rad/s), at the IMU the acceleration along the plate normal (m/s^2) and the angle (rad), the
# accelerometer's filtered ring-down's dynamic part (m/s^2, last free segment only), the
# contact force (N), the particle's position (m) and velocity (m/s). What a grid reads is a
# run of them.
ANGLE, PITCH_RATE, IMU_VELOCITY, PRESSURE, RATE, IMU_ACCEL, IMU_ANGLE, RINGDOWN = range(8)
FORCE, Z, ZD = 8, 9, 10
ROWS = 11
LINEAR = 7  # the readings linear in the state, ANGLE .. IMU_ANGLE
PEAKS = slice(PRESSURE, IMU_ACCEL + 1)  # what the summary's peaks read
RINGDOWN_ROWS = slice(IMU_ANGLE, RINGDOWN + 1)  # what the ring-down's outputs read


def covers(scene: Scene, trajectory: Trajectory) -> bool:
    """Whether the lean path covers ``scene``'s sensors and ``trajectory``'s segments."""
    segments = trajectory.segments
    return (
        supported(scene.sensors)
        and bool(segments)
        and isinstance(segments[-1], FreeSegment)
        and not any(isinstance(segment, OdeSegment) for segment in segments)
    )


def sense_one(scene: Scene, trajectory: Trajectory, vibration: bool = True) -> SimulationResult:
    """What the sensors and the summary make of ``trajectory`` (:func:`covers` must hold): the
    result of ``simulate.sense_general`` (module docstring), its histories computed when first
    read (:func:`history`), as the group path's are: the summary's peaks are read at the same
    instants without them."""
    spec = scene.sensors
    suite = SensorSuite(spec)
    structure = trajectory.problem.structure
    g = structure.gravity_mps2
    setting = structure.setting_pressure_pa
    slowest = min(spec.pressure_rate_hz, spec.imu_rate_hz)
    # phase_rng().uniform(0, 1 / slowest), which is 0 + (1 / slowest) * its first random()
    contact_stamp = scene.pre_contact_s + (0.0 + (1.0 / slowest) * suite.contact_phase())
    end = contact_stamp + scene.window_s
    imu_stamps = sample_grid(0.0, end, spec.imu_rate_hz)
    period = 1.0 / spec.imu_rate_hz
    now = imu_stamps - contact_stamp
    # the pressure's instants are the IMU's when the rates are equal (the same arithmetic)
    same_grid = spec.pressure_rate_hz == spec.imu_rate_hz
    pressure_stamps = (
        imu_stamps.copy() if same_grid else sample_grid(0.0, end, spec.pressure_rate_hz)
    )
    # Instants read directly, part after part: the histories' from first contact up to their
    # uniform tail on the last free segment (the summary's peaks: every step of each contact
    # and the uniform instants, a repeated one changing no maximum), the IMU's stamps and one
    # period before (and the pressure's, at another rate), the accelerometer's dense ones; the
    # histories' uniform tail and the accelerometer's ring-down outputs on their grids.
    uniform, after = _uniform_and_first(scene.pre_contact_s, scene.window_s)
    tail = max(after, _tail_start(uniform, trajectory.segments[-1]))
    parts = [np.concatenate([*_contact_steps(scene, trajectory), uniform[after:tail]]), now]
    parts.append(now - period)
    if not same_grid:
        parts.append(pressure_stamps - contact_stamp)
    grids = [(uniform[tail:], 1.0 / HISTORY_RATE_HZ, PEAKS)]
    gain = None
    if vibration:
        oversample = spec.vibration_oversample
        dense_rate = oversample * spec.vibration_rate_hz
        span = suite._dense_span(trajectory, end, contact_stamp)
        first, switch, count = span
        filter_ = AntiAliasFilter(
            spec.vibration_rate_hz,
            spec.vibration_antialias_order,
            spec.vibration_antialias_cutoff_fraction,
            oversample,
        )
        parts.append(np.arange(first - 1, switch) / dense_rate - contact_stamp)
        if switch < count:
            outputs = np.arange(switch, count, oversample) / dense_rate - contact_stamp
            grids.append((outputs, oversample / dense_rate, RINGDOWN_ROWS))
            gain = _dense_gain(structure, 1.0 / dense_rate, filter_.sos)
    values, on_grids = _evaluate(trajectory, np.concatenate(parts), grids, gain, flight=False)
    edges = list(accumulate(part.size for part in parts))
    read = [values[:, lo:hi] for lo, hi in zip([0, *edges[:-1]], edges)]

    # the peaks after first contact (max(setting + change) is setting + max(change): the sum
    # rounds monotonically)
    near = np.concatenate([read[0][PEAKS], on_grids[0][PEAKS]], axis=1)
    change = near[0].max()
    rate, accel_peak = np.abs(near[1:]).max(axis=1)
    summary = summary_figures(
        scene, trajectory, float((setting + change) - setting), float(rate), float(accel_peak)
    )

    noise = suite.noise
    at_now, before = read[1], read[2]
    clean = setting + (at_now if same_grid else read[3])[PRESSURE]
    pressure = PressureStream(
        pressure_stamps,
        noise.pressure(clean, suite._pressure_rng.standard_normal(pressure_stamps.size)),
        noise.pressure_pa**2,
    )
    # each IMU reading the mean over the period before its stamp (sensors.imu_samples)
    angle = at_now[IMU_ANGLE]
    gyro = np.zeros((imu_stamps.size, 3))
    gyro[:, 1] = (angle - before[IMU_ANGLE]) / period
    accel = np.zeros((imu_stamps.size, 3))
    cos, sin = _cos_sin(angle)
    accel[:, 0] = -structure.imu_from_hinge_m * at_now[PITCH_RATE] ** 2 - g * sin
    accel[:, 2] = g * cos - (at_now[IMU_VELOCITY] - before[IMU_VELOCITY]) / period
    rng = suite._imu_rng
    gyro = noise.gyro(gyro, rng.standard_normal(gyro.shape))
    accel = noise.accel(accel, rng.standard_normal(accel.shape))
    imu = ImuStream(imu_stamps, gyro, accel, noise.gyro_radps**2, noise.accel_mps2**2)

    rebound = suite.rebound(trajectory, contact_stamp)
    return SimulationResult(
        scene=scene,
        trajectory=trajectory,
        contact_stamp_s=contact_stamp,
        history=LazyHistory(partial(history, scene, trajectory)),
        pressure=pressure,
        imu=imu,
        rebound=rebound,
        summary=summary,
        vibration=_blocks(suite, filter_, g, read[-1], on_grids[1:], span)
        if vibration
        else VibrationBlocks.empty(),
        point=suite.reported_point(scene.impact.position_m, rebound, scene.support),
    )


def history(scene: Scene, trajectory: Trajectory) -> dict[str, np.ndarray]:
    """``simulate.histories`` of ``trajectory`` (:func:`covers` must hold), read as
    :func:`sense_one` reads the summary's peaks."""
    structure = trajectory.problem.structure
    g = structure.gravity_mps2
    times, head = _history_instants(scene, trajectory)
    near, (far,) = _evaluate(
        trajectory, times[:head], [(times[head:], 1.0 / HISTORY_RATE_HZ, slice(0, ROWS))], None
    )
    at = near if not far.size else far if not head else np.concatenate([near, far], axis=1)
    return {
        "time_s": times,
        "contact_force_n": at[FORCE],
        "jack_pressure_pa": structure.setting_pressure_pa + at[PRESSURE],
        "beam_angle_rad": at[ANGLE],
        "beam_angular_velocity_radps": at[RATE],
        "imu_angular_velocity_radps": at[PITCH_RATE],
        "imu_specific_force_mps2": g * _cos(at[IMU_ANGLE]) - at[IMU_ACCEL],
        "imu_dynamic_accel_mps2": -at[IMU_ACCEL],
        "particle_position_m": at[Z],
        "particle_velocity_mps": at[ZD],
    }


def _history_instants(scene: Scene, trajectory: Trajectory) -> tuple[np.ndarray, int]:
    """The histories' instants (``simulate.history_times``) and how many of them come before
    their tail on the last free segment's uniform grid (:func:`_tail_start`)."""
    times = _history_times(scene, trajectory)
    uniform = _uniform_times(scene.pre_contact_s, scene.window_s)
    return times, times.size - (uniform.size - _tail_start(uniform, trajectory.segments[-1]))


def _tail_start(uniform: np.ndarray, last: FreeSegment) -> int:
    """The first of the histories' ``uniform`` instants on free segment ``last`` (the last) and
    at or after its anchor: from it on every instant of the histories is a uniform one."""
    return int(uniform.searchsorted(max(last.start_s, last.anchor_s)))


def _cos_sin(angle: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``sense_many._cos`` and ``_sin`` of the same angles, which are small or not for both."""
    if angle.size and np.abs(angle).max() < SMALL_ANGLE_RAD:
        square = angle * angle
        return (
            1.0 - square * (0.5 - square * (1.0 / 24.0)),
            angle * (1.0 - square * (1.0 / 6.0 - square * (1.0 / 120.0))),
        )
    return np.cos(angle), np.sin(angle)


def _contact_steps(scene: Scene, trajectory: Trajectory) -> list[np.ndarray]:
    """Every step of each contact up to the window's end (s from first contact)."""
    steps = [segment.t_s for segment in trajectory.segments if hasattr(segment, "force_n")]
    if steps and steps[-1][-1] > scene.window_s:
        return [t[t <= scene.window_s] for t in steps]
    return steps


def _blocks(
    suite: SensorSuite,
    filter_: AntiAliasFilter,
    g: float,
    dense_read: np.ndarray,
    outputs_read: list[np.ndarray],
    span: tuple[int, int, int],
) -> VibrationBlocks:
    """The accelerometer's blocks (``SensorSuite.vibration``) through the fresh anti-alias
    ``filter_``, from the readings at its dense instants and, when the ring-down takes over
    (``span``: ``SensorSuite._dense_span``), at its outputs."""
    spec = suite.spec
    oversample = spec.vibration_oversample
    first, switch, _ = span
    dense_period = 1.0 / (oversample * spec.vibration_rate_hz)
    at = dense_read
    # each dense value the mean over the dense period before its instant (the instant before)
    velocity = at[IMU_VELOCITY]
    dense = g * _cos(at[IMU_ANGLE, 1:]) - (velocity[1:] - velocity[:-1]) / dense_period
    # the samples: the rest before ``first`` (the beam at rest reads g, and the filter settled
    # on it passes g), the filtered dense span, the ring-down from ``switch``
    rest, filtered = first // oversample, -(-(switch - first) // oversample)
    ringdown = outputs_read[0] if outputs_read else np.empty((ROWS, 0))
    samples = np.empty(rest + filtered + ringdown.shape[1])
    if first > 0:
        samples[:rest] = g
        filter_.settle(g)
    samples[rest : rest + filtered] = filter_(dense)[::oversample]
    if ringdown.shape[1]:
        # the ring-down's angle row is read once: its cosine computed in its own memory
        angle = ringdown[IMU_ANGLE]
        if np.abs(angle).max() < SMALL_ANGLE_RAD:
            cos = np.multiply(_small_cos_in_place(angle), g, out=angle)
        else:
            cos = g * np.cos(angle)
        np.add(cos, ringdown[RINGDOWN], out=samples[rest + filtered :])
    samples += suite._vibration_rng.normal(0.0, spec.vibration_noise_mps2, samples.size)
    limit = spec.vibration_range_mps2
    np.minimum(np.maximum(samples, -limit, out=samples), limit, out=samples)  # np.clip
    blocks, _ = cut_blocks(samples, 0, spec)
    return blocks


def _evaluate(
    trajectory: Trajectory,
    times: np.ndarray,
    grids: list[tuple[np.ndarray, float, slice]],
    gain: np.ndarray | None,
    flight: bool = True,
) -> tuple[np.ndarray, list[np.ndarray]]:
    """The readings (ROWS, T) at ``times`` (s from first contact), and (ROWS, grid size) on
    each grid (its instants, on the last free segment at or after its anchor, evenly spaced;
    their spacing, s; the rows read there, the others left unset); RINGDOWN with the
    ring-down ``gain`` per exponential (``ringdown_filtering._dense_gain``), read on the last
    segment only; FORCE, Z and ZD at ``times`` only when ``flight``."""
    segments = trajectory.segments
    structure = trajectory.problem.structure
    g = trajectory.problem.gravity_mps2
    last = segments[-1]
    weights = _free_weights(structure, last, gain)
    on_grids = []
    for instants, step_s, rows in grids:
        block = np.empty((ROWS, instants.size))
        if instants.size:
            _grid_readings(structure, last, weights, instants, step_s, rows, g, block)
        on_grids.append(block)
    out = np.empty((ROWS, times.size))
    if not times.size:
        return out, on_grids
    # the last segment's formula at every instant (each other segment's instants, replaced
    # below, read it no earlier than its own start, so that nothing overflows)
    dt = times - last.anchor_s
    if len(segments) > 1:
        np.maximum(dt, last.start_s - last.anchor_s, out=dt)
    _free_readings(structure, last, weights, dt, g, out, flight)
    if len(segments) == 1:
        return out, on_grids
    starts = np.array([segment.start_s for segment in segments])
    which = starts.searchsorted(times, side="right") - 1
    n = structure.size
    for index in range(len(segments) - 1):
        chosen = (which <= 0 if index == 0 else which == index).nonzero()[0]
        if not chosen.size:
            continue
        segment = segments[index]
        if not flight and isinstance(segment, FreeSegment) and segment.at_rest:
            out[:FORCE, chosen] = 0.0  # at rest it stays at rest
            continue
        if not flight and not isinstance(segment, FreeSegment) and segment.t_s.size > 1:
            block = np.empty((LINEAR, chosen.size))
            _contact_readings(structure, segment, times[chosen], block)
            out[:LINEAR, chosen] = block
            continue
        block = np.empty((ROWS, chosen.size))
        if isinstance(segment, FreeSegment):
            own = _free_weights(structure, segment, None)
            dt = times[chosen] - segment.anchor_s
            _free_readings(structure, segment, own, dt, g, block, flight)
        else:
            samples = trajectory.sample_segment(index, times[chosen])
            buffer = samples.q.base  # [q; qd; qdd; force; z; zd]
            np.dot(_readouts(structure)[3], buffer[: 3 * n], out=block[:LINEAR])
            block[RINGDOWN] = 0.0
            block[FORCE:] = buffer[3 * n :]
        out[:, chosen] = block
    return out, on_grids


def _contact_readings(
    structure: LinearStructure, segment: ContactSegment, times: np.ndarray, out: np.ndarray
) -> None:
    """The LINEAR rows at ``times`` within contact ``segment`` (two steps or more), into
    ``out``: q and q' by the cubic Hermite through its steps, q'' on the straight line, each
    step's polynomial in Horner form, as :meth:`~tail_beam_sim.physics.solvers.Trajectory.
    sample` evaluates them (the same arithmetic), without the particle's and the force's."""
    t = segment.t_s
    steps = t[1:] - t[:-1]
    n = structure.size
    q, qd, qdd = segment.q, segment.qd, segment.qdd
    # (4, 3n, steps): per step the coefficients of s^0 .. s^3 of [q; q'] (values and slopes at
    # the step's ends) and of q''
    coefficients = np.empty((4, 3 * n, steps.size))
    constant, linear, square, cube = coefficients
    # [q; q'; q''] at the steps: the values [q; q'] are its first rows, their slopes its last
    stack = np.concatenate([q, qd, qdd])
    values, slopes = stack[: 2 * n], stack[n:]
    v0, v1 = values[:, :-1], values[:, 1:]
    m0 = np.multiply(slopes[:, :-1], steps, out=linear[: 2 * n])
    m1 = slopes[:, 1:] * steps
    constant[:] = stack[:, :-1]
    np.subtract(qdd[:, 1:], qdd[:, :-1], out=linear[2 * n :])
    np.subtract(3.0 * (v1 - v0) - 2.0 * m0, m1, out=square[: 2 * n])
    np.add(2.0 * (v0 - v1) + m0, m1, out=cube[: 2 * n])
    coefficients[2:, 2 * n :] = 0.0
    k = np.minimum(np.maximum(t.searchsorted(times, side="right") - 1, 0), t.size - 2)
    h = steps[k]
    if steps.min() > 0:  # every step has a length (s below as np.where would give it)
        s = (times - t[k]) / h
    else:
        positive = h > 0
        s = np.where(positive, (times - t[k]) / np.where(positive, h, 1.0), 0.0)
    c = coefficients[:, :, k]  # (4, 3n, T)
    states = c[0] + s * (c[1] + s * (c[2] + s * c[3]))
    np.dot(_readouts(structure)[3], states, out=out[:LINEAR])


def _free_weights(
    structure: LinearStructure, segment: FreeSegment, gain: np.ndarray | None
) -> np.ndarray | None:
    """(RINGDOWN + 1, k) complex: each reading of free ``segment`` per exponential of the
    structure's half spectrum from its anchor (``LinearStructure.propagate``), RINGDOWN with
    the ring-down ``gain`` (zero without); None at rest."""
    if segment.at_rest:
        return None
    free_rows, modes, inverse, _, _ = _readouts(structure)
    keep, _, _, weight = structure._half_spectrum
    modal = np.dot(inverse, np.concatenate([segment.q, segment.qd]))
    amplitude = modes * (weight * modal)  # (2n, k)
    weights = np.empty((RINGDOWN + 1, keep.size), dtype=complex)
    np.dot(free_rows, amplitude, out=weights[:LINEAR])
    weights[RINGDOWN] = 0.0 if gain is None else weights[IMU_VELOCITY] * gain
    return weights


def _free_readings(
    structure: LinearStructure,
    segment: FreeSegment,
    weights: np.ndarray | None,
    dt: np.ndarray,
    gravity_mps2: float,
    out: np.ndarray,
    flight: bool = True,
) -> None:
    """Every reading of free ``segment`` at ``dt`` s from its anchor, into ``out``: the
    structure's free response through each reading's ``weights`` (:func:`_free_weights`), in
    real arithmetic, and (``flight``) the particle's flight."""
    if flight:
        out[FORCE] = 0.0
        out[Z] = segment.z_m + segment.zd_mps * dt - 0.5 * gravity_mps2 * dt * dt
        out[ZD] = segment.zd_mps - gravity_mps2 * dt
    if weights is None:
        out[:FORCE] = 0.0
        return
    _, sigma, omega, _ = structure._half_spectrum
    growth = np.exp(np.multiply.outer(sigma, dt))
    angle = np.multiply.outer(omega, dt)
    _modal_sum(weights, growth * np.cos(angle), growth * np.sin(angle), out[:FORCE])


def _grid_readings(
    structure: LinearStructure,
    segment: FreeSegment,
    weights: np.ndarray | None,
    instants: np.ndarray,
    step_s: float,
    rows: slice,
    gravity_mps2: float,
    out: np.ndarray,
) -> None:
    """The ``rows`` of :func:`_free_readings` at ``instants`` evenly ``step_s`` apart, at or
    after the anchor of ``segment``: each exponential the first instant's times the grid's
    (:func:`_grid_basis`, kept), so that no instant costs an exponential, a cosine and a
    sine."""
    if rows.stop > FORCE:
        dt = instants - segment.anchor_s
        out[FORCE] = 0.0
        out[Z] = segment.z_m + segment.zd_mps * dt - 0.5 * gravity_mps2 * dt * dt
        out[ZD] = segment.zd_mps - gravity_mps2 * dt
    linear = slice(rows.start, min(rows.stop, FORCE))
    if weights is None:
        out[linear] = 0.0
        return
    first = np.exp(_readouts(structure)[4] * (float(instants[0]) - segment.anchor_s))
    cos, sin = _grid_basis(structure, step_s, instants.size)
    _modal_sum(weights[linear] * first, cos, sin, out[linear])


_BASES: dict[tuple[int, float], tuple[LinearStructure, np.ndarray, np.ndarray]] = {}
BASIS_CACHE_SIZE = 64


def _grid_basis(
    structure: LinearStructure, step_s: float, count: int
) -> tuple[np.ndarray, np.ndarray]:
    """(k, count) each: Re and Im of exp(lambda j step_s), j = 0 .. count - 1, over the
    structure's half spectrum: kept per structure and step (a sensor's grid spacing depends on
    its settings only), extended when a longer grid asks."""
    cached = _BASES.get((id(structure), step_s))
    if cached is None or cached[0] is not structure or cached[1].shape[1] < count:
        _, sigma, omega, _ = structure._half_spectrum
        offsets = np.arange(count) * step_s
        growth = np.exp(np.multiply.outer(sigma, offsets))
        angle = np.multiply.outer(omega, offsets)
        if len(_BASES) >= BASIS_CACHE_SIZE:
            _BASES.clear()
        # holding the structure keeps its id from being reused
        cached = _BASES[(id(structure), step_s)] = (
            structure,
            growth * np.cos(angle),
            growth * np.sin(angle),
        )
    return cached[1][:, :count], cached[2][:, :count]


def _modal_sum(weights: np.ndarray, cos: np.ndarray, sin: np.ndarray, out: np.ndarray) -> None:
    """``out = Re(weights) @ cos - Im(weights) @ sin`` (weights (R, k) complex, cos and sin
    (k, T)); one exponential (the rigid beam's pair) as a plain product, which numpy's matrix
    product of an inner dimension of one takes several times longer over."""
    if weights.shape[1] == 1:
        np.multiply(weights.real, cos, out=out)
        out -= weights.imag * sin
    else:
        np.matmul(weights.real, cos, out=out)
        out -= weights.imag @ sin


Readouts = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
_READOUTS: dict[int, tuple[LinearStructure, Readouts]] = {}
READOUT_CACHE_SIZE = 64


def _readouts(structure: LinearStructure) -> Readouts:
    """The readings' rows, kept per structure: over a free state [q; q'] (LINEAR, 2n), q''
    from the structure's own forces; the eigenvectors of its half spectrum (2n, k) and the
    rows of their inverse that give its modal amplitudes (k, 2n); over [q; q'; q''] (LINEAR,
    3n), as a segment's samples give them; the half spectrum's eigenvalues (k, 1/s)."""
    cached = _READOUTS.get(id(structure))
    if cached is not None and cached[0] is structure:
        return cached[1]
    n = structure.size
    area = structure.piston_area_m2
    imu = structure.imu_shape
    state = np.zeros((LINEAR, 3 * n))
    state[ANGLE, 0] = 1.0
    state[RATE, n] = 1.0
    state[PRESSURE, :n] = structure.jack_stiffness_npm * structure.jack_shape / area
    state[PRESSURE, n : 2 * n] = structure.jack_damping_nspm * structure.jack_shape / area
    state[PITCH_RATE, n : 2 * n] = structure.imu_slope_shape
    state[IMU_VELOCITY, n : 2 * n] = imu
    state[IMU_ACCEL, 2 * n :] = imu
    state[IMU_ANGLE, :n] = structure.imu_slope_shape
    free = state[:, : 2 * n].copy()
    # q'' = -M^-1 (C q' + K q) without a contact force
    free[IMU_ACCEL] = -(imu @ structure.inv_mass) @ np.hstack(
        [structure.stiffness, structure.damping]
    )
    _, vectors, inverse = structure._eigen
    keep = structure._half_spectrum[0]
    rows = (free, vectors[:, keep], inverse[keep], state, structure._eigen[0][keep])
    if len(_READOUTS) >= READOUT_CACHE_SIZE:
        _READOUTS.clear()
    _READOUTS[id(structure)] = (structure, rows)  # holding it keeps its id from being reused
    return rows


def _history_times(scene: Scene, trajectory: Trajectory) -> np.ndarray:
    """``simulate.history_times``: the uniform instants (kept per window) and every step of each
    contact up to the window's end, sorted, each once."""
    contact = _contact_steps(scene, trajectory)
    uniform = _uniform_times(scene.pre_contact_s, scene.window_s)
    if not contact:
        return uniform.copy()
    times = np.concatenate([uniform, *contact])
    times.sort()
    keep = np.empty(times.size, dtype=bool)
    keep[0] = True
    np.not_equal(times[1:], times[:-1], out=keep[1:])
    return times[keep]


@lru_cache(maxsize=64)
def _uniform_and_first(pre_contact_s: float, window_s: float) -> tuple[np.ndarray, int]:
    """:func:`_uniform_times` and the index of its first instant at or after first contact."""
    uniform = _uniform_times(pre_contact_s, window_s)
    return uniform, int(uniform.searchsorted(0.0))


@lru_cache(maxsize=64)
def _uniform_times(pre_contact_s: float, window_s: float) -> np.ndarray:
    """HISTORY_RATE_HZ from -pre_contact_s to window_s (read only: shared)."""
    uniform = np.arange(-pre_contact_s, window_s + 0.5 / HISTORY_RATE_HZ, 1.0 / HISTORY_RATE_HZ)
    uniform.flags.writeable = False
    return uniform
