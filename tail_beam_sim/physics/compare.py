"""The last step of a checked simulation: measured differences between two simulations of one
scene (a tier and the next one up), per output the scene needs (docs/physics.md, fidelity)."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from tail_beam_sim.physics.fidelity import WAVEFORM_OUTPUTS
from tail_beam_sim.physics.result import SimulationResult
from tail_beam_sim.physics.sensors import imu_samples


def sensor_view(result: SimulationResult) -> dict[str, np.ndarray]:
    """Noise-free pressure change (Pa) and dynamic IMU readings (m/s^2, rad/s) at the streams'
    stamps, sampled as the sensors sample them (IMU averaged over its period)."""
    trajectory, start = result.trajectory, result.contact_stamp_s
    structure = trajectory.problem.structure
    state = trajectory.sample(result.pressure.stamp_s - start)
    gyro, accel = imu_samples(
        trajectory, result.imu.stamp_s - start, 1.0 / result.scene.sensors.imu_rate_hz
    )
    return {
        "pressure": structure.pressure_pa(state.q, state.qd) - structure.setting_pressure_pa,
        "imu": np.concatenate([accel[:, 0], accel[:, 2] - structure.gravity_mps2, gyro[:, 1]]),
    }


def _relative(x: float, y: float) -> float:
    return abs(x - y) / abs(y) if y else abs(x - y)


def compare(
    lower: SimulationResult, upper: SimulationResult, outputs: Iterable[str]
) -> dict[str, float]:
    """Measured relative differences of ``lower`` from ``upper``, per requested output.

    rebound: rebound speed; contact: peak contact force and duration; pressure: peak jack
    pressure change and the sampled pressure stream (relative L2); imu: the sampled IMU
    stream (relative L2). Streams are noise-free, at the sensors' stamps.
    """
    a, b = lower.summary, upper.summary
    chosen = set(outputs)
    out: dict[str, float] = {}
    if "rebound" in chosen:
        out["rebound"] = _relative(a["rebound_speed_mps"], b["rebound_speed_mps"])
    if "contact" in chosen:
        out["contact_peak_force"] = _relative(a["peak_contact_force_n"], b["peak_contact_force_n"])
        out["contact_duration"] = _relative(a["contact_duration_s"], b["contact_duration_s"])
    if chosen & set(WAVEFORM_OUTPUTS):
        view_a, view_b = sensor_view(lower), sensor_view(upper)
        if "pressure" in chosen:
            out["peak_pressure_change"] = _relative(
                a["peak_jack_pressure_change_pa"], b["peak_jack_pressure_change_pa"]
            )
        for key in chosen & set(WAVEFORM_OUTPUTS):
            norm = float(np.linalg.norm(view_b[key]))
            out[f"{key}_stream"] = (
                float(np.linalg.norm(view_a[key] - view_b[key])) / norm if norm else 0.0
            )
    return out


__all__ = ["compare", "sensor_view"]
