"""Nodes' parameters: the config/ defaults declared as ROS 2 parameters, read back nested.

Every value of the given parameter files becomes a declared parameter under its dotted name
(``sensors.imu_rate_hz``), so ``--ros-args -p`` and ``--params-file`` override any of them;
dynamic typing lets ``-p x:=2`` set a parameter shipped as ``2.0``. Parameters a node reads
only at start-up are guarded by :func:`refuse_runtime_changes`.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

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


ALL_PARAMETERS = None  # for refuse_runtime_changes: every parameter of the node


def refuse_runtime_changes(node: Node, names: Iterable[str] | None, reason: str) -> None:
    """Refuse, from now on, every set of ``names`` (None: of any parameter, ``use_sim_time``
    included) with ``reason``.

    For parameters a node reads only at start-up: a change at run time would do nothing, or,
    for ``use_sim_time``, let any participant of the domain switch the node's clock and rewrite
    its log times. Call it after the parameters are declared (declaring runs the same
    callbacks). The refusal names the parameters and the reason; the node logs it once per
    attempt and carries on unchanged.
    """
    guarded = None if names is None else set(names)

    def check(parameters: list[Parameter]) -> SetParametersResult:
        hit = [p.name for p in parameters if guarded is None or p.name in guarded]
        if not hit:
            return SetParametersResult(successful=True)
        message = f"{', '.join(sorted(hit))}: {reason}"
        node.get_logger().warning(f"parameter change refused: {message}")
        return SetParametersResult(successful=False, reason=message)

    node.add_on_set_parameters_callback(check)
