"""Report figures. matplotlib is an optional extra (``pip install 'tail_beam[plot]'``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tail_beam_sim.errors import InputError, open_output_file


def pyplot() -> Any:
    """matplotlib.pyplot on the file-only Agg backend, or a clear error if it is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise InputError(
            "--plot", "matplotlib", "plots need matplotlib: pip install 'tail_beam[plot]'"
        ) from None
    return plt


def save_figure(fig: Any, path: str | Path, dpi: int, field: str = "--plot") -> Path:
    """Write ``fig`` to ``path`` (format from the suffix, PNG by default) and close it; a symbolic
    link at ``path`` is refused, never written through."""
    plt = pyplot()
    out = Path(path)
    try:
        with open_output_file(field, out) as stream:
            fig.savefig(stream, dpi=dpi, format=out.suffix.lstrip(".").lower() or "png")
    finally:
        plt.close(fig)
    return out


def plot_response(result: Any, path: str | Path) -> Path:
    """Four stacked panels against time from first contact: contact force, jack pressure,
    IMU specific force and angular velocity; noise-free lines with the sampled sensor
    readings as dots. ``result`` is a SimulationResult."""
    plt = pyplot()
    h = result.history
    t_ms = h["time_s"] * 1e3
    stamp0 = result.contact_stamp_s
    impact = result.scene.impact
    fig, axes = plt.subplots(4, 1, figsize=(8.0, 9.0), sharex=True, constrained_layout=True)
    axes[0].plot(t_ms, h["contact_force_n"] / 1e3, color="tab:red")
    axes[0].set_ylabel("contact force (kN)")
    inset = axes[0].inset_axes([0.55, 0.25, 0.4, 0.65])
    contact = h["contact_force_n"] > 0
    if contact.any():
        first, last = h["time_s"][contact][[0, -1]]
        span = (h["time_s"] >= first - 0.2 * (last - first)) & (
            h["time_s"] <= last + 0.2 * (last - first)
        )
        inset.plot(h["time_s"][span] * 1e6, h["contact_force_n"][span] / 1e3, color="tab:red")
        inset.set_xlabel("µs", fontsize=8)
        inset.tick_params(labelsize=7)
    p0 = result.scene.support.setting_pressure_pa
    axes[1].plot(t_ms, (h["jack_pressure_pa"] - p0) / 1e3, label="model")
    axes[1].plot(
        (result.pressure.stamp_s - stamp0) * 1e3,
        (result.pressure.pressure_pa - p0) / 1e3,
        ".",
        ms=2,
        alpha=0.6,
        label="transducer",
    )
    axes[1].set_ylabel(f"jack pressure − {p0 / 1e6:g} MPa (kPa)")
    axes[1].legend(loc="upper right", fontsize=8)
    g = result.scene.support.gravity_mps2
    axes[2].plot(t_ms, h["imu_specific_force_mps2"] - g, label="model (instantaneous)")
    axes[2].plot(
        (result.imu.stamp_s - stamp0) * 1e3,
        result.imu.linear_acceleration_mps2[:, 2] - g,
        ".",
        ms=2,
        alpha=0.6,
        label="IMU (sample mean)",
    )
    axes[2].set_ylabel("IMU f_z − g (m/s²)")
    axes[2].legend(loc="upper right", fontsize=8)
    axes[3].plot(t_ms, h["imu_angular_velocity_radps"] * 1e3, label="model")
    axes[3].plot(
        (result.imu.stamp_s - stamp0) * 1e3,
        result.imu.angular_velocity_radps[:, 1] * 1e3,
        ".",
        ms=2,
        alpha=0.6,
        label="gyro",
    )
    axes[3].set_ylabel("ω_y (mrad/s)")
    axes[3].set_xlabel("time from first contact (ms)")
    axes[3].legend(loc="upper right", fontsize=8)
    s = result.summary
    fig.suptitle(
        f"{impact.material.name}, R = {impact.radius_m * 1e3:g} mm, v0 = "
        f"{impact.impact_speed_mps:.2f} m/s at x = {impact.position_m:g} m: "
        f"e = {s['restitution']:.3f}, contact {s['contact_duration_s'] * 1e6:.0f} µs",
        fontsize=10,
    )
    for ax in axes:
        ax.grid(alpha=0.3)
    return save_figure(fig, path, 110)
