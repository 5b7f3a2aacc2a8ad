"""Nodes' parameters: the config/ defaults declared as ROS 2 parameters, read back nested.

Every value of the given parameter files becomes a declared parameter under its dotted name
(``sensors.imu_rate_hz``), so ``--ros-args -p`` and ``--params-file`` override any of them;
dynamic typing lets ``-p x:=2`` set a parameter shipped as ``2.0``.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

from tail_beam_sim.config import deep_merge, default_config_dir, flatten, load_parameters, read_parameter_file, unflatten


def config_defaults(files: Iterable[str], with_physics: bool) -> dict[str, Any]:
    """Merged parameters of ``files`` in config/ (after the physics defaults if asked)."""
    paths = [default_config_dir() / name for name in files]
    if with_physics:
        return load_parameters(paths)
    merged: dict[str, Any] = {}
    for path in paths:
        deep_merge(merged, read_parameter_file(Path(path)))
    return merged


def declare_and_read(node: Node, defaults: dict[str, Any]) -> dict[str, Any]:
    """Declare every default as a parameter of ``node``; return the values in effect, nested."""
    dynamic = ParameterDescriptor(dynamic_typing=True)
    names = flatten(defaults)
    node.declare_parameters("", [(name, value, dynamic) for name, value in names.items()])
    return unflatten({name: node.get_parameter(name).value for name in names})
