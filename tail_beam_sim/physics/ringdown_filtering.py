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
    eigenvalues, vectors, inverse = structure._eigen
    n = structure.size
    modal = inverse @ np.concatenate([q0, qd0])
    keep, _, _, weight = structure._half_spectrum
    lam = eigenvalues[keep]
    amplitude = vectors[:, keep] * (weight * modal[keep])  # (2n, k), complex
    angle_weight = structure.imu_slope_shape @ amplitude[:n]  # rad per unit exponential
    velocity_weight = structure.imu_shape @ amplitude[n:]  # m/s per unit exponential
    # the dense input's term: -(qd(t) - qd(t - T)) / T at the IMU, then through the filter
    gain = response(sos, np.exp(lam * dense_period_s))
    dynamic_weight = -velocity_weight * (1.0 - np.exp(-lam * dense_period_s)) / dense_period_s
    growth = np.exp(np.multiply.outer(lam, np.asarray(t_s, dtype=float) - anchor_s))
    angle = (angle_weight @ growth).real
    dynamic = ((gain * dynamic_weight) @ growth).real
    return structure.gravity_mps2 * np.cos(angle) + dynamic
