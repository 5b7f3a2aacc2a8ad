"""The accelerometer's filtered output over the beam's free ring-down, in closed form.

After the particle has left the plate for the last time the beam rings freely: its velocities
are a sum of damped exponentials, ``qd(t) = Re sum_k A_k exp(lambda_k t)`` over the structure's
eigenvalues (:meth:`tail_beam_sim.physics.structure.LinearStructure.propagate`). What the
accelerometer's dense stage computes from them, the mean specific force over each dense period,
is again such a sum, and a linear filter's steady response to ``z**n`` is ``H(z) z**n``: once
the filter's own transient from the contact has died away, each output sample is that sum with
every term weighted by the anti-alias filter's response at its eigenvalue. Evaluating it only at
the output instants replaces, for most of an impact's window, the dense (oversampled)
evaluation of the trajectory and the filter run over it, which are the costliest part of
:func:`tail_beam_sim.physics.simulate.simulate`.

The gravity term ``g cos(angle)`` is taken unfiltered: the angle at the IMU is small and slow
(the beam's sway), so the filter (unit gain at DC, a cut-off in kHz) changes it by far less than
float32 resolves. A test holds the closed form to the dense path over drawn impacts.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from tail_beam_sim.physics.structure import LinearStructure

# The filter's transient is taken as gone once its slowest pole has decayed by this factor.
TRANSIENT_DECAY = 1e-12


@lru_cache(maxsize=32)
def settle_steps(sos_bytes: bytes) -> int:
    """Dense steps after which the transient of the filter (second-order sections, as bytes
    so that they can key a cache) has decayed by ``TRANSIENT_DECAY``."""
    sos = np.frombuffer(sos_bytes).reshape(-1, 6)
    radius = max(float(np.max(np.abs(np.roots(section[3:])))) for section in sos)
    if radius <= 0.0:
        return 1
    return int(math.ceil(math.log(TRANSIENT_DECAY) / math.log(radius)))


def response(sos: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The filter's transfer function H(z) at complex points ``z``."""
    inverse = 1.0 / z
    out = np.ones_like(z)
    for b0, b1, b2, a0, a1, a2 in sos:
        out = out * (b0 + inverse * (b1 + inverse * b2)) / (a0 + inverse * (a1 + inverse * a2))
    return out


def filtered_ringdown(
    structure: LinearStructure,
    anchor_s: float,
    q0: np.ndarray,
    qd0: np.ndarray,
    t_s: np.ndarray,
    dense_period_s: float,
    sos: np.ndarray,
) -> np.ndarray:
    """The anti-alias filter's steady output (m/s^2) at trajectory times ``t_s`` during a free
    ring-down whose state is (``q0``, ``qd0``) at ``anchor_s``: each dense input value the mean
    specific force along the plate normal at the IMU over the dense period before its instant
    (:func:`tail_beam_sim.physics.sensors.mean_specific_force_z`)."""
    _, vectors, inverse = structure._eigen
    n = structure.size
    modal = inverse @ np.concatenate([q0, qd0])
    keep, sigma, omega, weight = structure._half_spectrum
    amplitude = vectors[:, keep] * (weight * modal[keep])  # (2n, k), complex
    angle_weight = structure.imu_slope_shape @ amplitude[:n]  # rad per unit exponential
    velocity_weight = structure.imu_shape @ amplitude[n:]  # m/s per unit exponential
    # the dense input's term: -(qd(t) - qd(t - T)) / T at the IMU, then through the filter
    dynamic_weight = velocity_weight * _dense_gain(structure, dense_period_s, sos)
    # Re(w exp(lambda t)) = exp(sigma t) (Re w cos(omega t) - Im w sin(omega t)), in real
    # arithmetic (a complex exp costs several real ones), every mode at once
    dt = np.asarray(t_s, dtype=float) - anchor_s
    growth = np.exp(np.multiply.outer(sigma, dt))
    cos = growth * np.cos(np.multiply.outer(omega, dt))
    sin = growth * np.sin(np.multiply.outer(omega, dt))
    angle = angle_weight.real @ cos - angle_weight.imag @ sin
    dynamic = dynamic_weight.real @ cos - dynamic_weight.imag @ sin
    return structure.gravity_mps2 * np.cos(angle) + dynamic


_GAINS: dict[tuple[int, float, bytes], tuple[LinearStructure, np.ndarray]] = {}
GAIN_CACHE_SIZE = 64


def _dense_gain(structure: LinearStructure, dense_period_s: float, sos: np.ndarray) -> np.ndarray:
    """Per exponential of the structure's half spectrum: the dense stage's factor from the
    velocity's term to its specific force, -(1 - exp(-lambda T)) / T, times the filter's
    response at exp(lambda T) (1/s). Depends on the structure and the sensor setting only, so
    it is kept per (structure, dense period, filter)."""
    key = (id(structure), float(dense_period_s), sos.tobytes())
    cached = _GAINS.get(key)
    if cached is not None and cached[0] is structure:
        return cached[1]
    keep = structure._half_spectrum[0]
    lam = structure._eigen[0][keep]
    gain = response(sos, np.exp(lam * dense_period_s)) * (
        -(1.0 - np.exp(-lam * dense_period_s)) / dense_period_s
    )
    if len(_GAINS) >= GAIN_CACHE_SIZE:
        _GAINS.clear()
    _GAINS[key] = (structure, gain)  # holding it keeps its id from being reused
    return gain
