"""The physics core: materials, contact, support, solvers, sensors and streams (numpy/scipy, no
ROS)."""

__all__ = [
    "materials",
    "contact",
    "support",
    "structure",
    "scene",
    "solvers",
    "simulate",
    "fidelity",
    "batch",
    "stream",
    "scenario",
    "sensors",
    "benchmark",
]
