"""Nodes' parameters: the config/ defaults declared as ROS 2 parameters, read back nested.

Every value of the given parameter files becomes a declared parameter under its dotted name
(``sensors.imu_rate_hz``), so ``--ros-args -p`` and ``--params-file`` override any of them;
dynamic typing lets ``-p x:=2`` set a parameter shipped as ``2.0``. Parameters a node reads
only at start-up are guarded by :func:`refuse_runtime_changes`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from tail_beam_sim.config import (
    deep_merge,
    default_config_dir,
    flatten,
    load_parameters,
    read_parameter_file,
    unflatten,
)
from tail_beam_sim.errors import InputError, shorten


def config_defaults(files: Iterable[str], with_physics: bool) -> dict[str, Any]:
    """Merged parameters of ``files`` in config/ (after the physics defaults if asked)."""
    paths = [default_config_dir() / name for name in files]
    if with_physics:
        return load_parameters(paths)
    merged: dict[str, Any] = {}
    for path in paths:
        deep_merge(merged, read_parameter_file(Path(path)))
    return merged


def declare_and_read(
    node: Node, defaults: dict[str, Any], open_sections: Iterable[str] = ()
) -> dict[str, Any]:
    """Declare every default as a parameter of ``node``, and every override (``-p``,
    ``--params-file``) under one of ``open_sections`` (sections with no defaults, whose keys a
    file brings: a support profile's ``calibration``); return the values in effect, nested."""
    dynamic = ParameterDescriptor(dynamic_typing=True)
    names = flatten(defaults)
    node.declare_parameters("", [(name, value, dynamic) for name, value in names.items()])
    overrides = (
        getattr(node, "_parameter_overrides", None) or {}
    )  # rclpy keeps them there, no public accessor
    opened = sorted(
        name
        for name in overrides
        if name not in names and any(name.startswith(f"{s}.") for s in open_sections)
    )
    node.declare_parameters("", [(name, overrides[name].value, dynamic) for name in opened])
    guard_parameter_services(node)
    say_unused_overrides(node)
    values = {name: node.get_parameter(name).value for name in [*names, *opened]}
    for name in names:
        require_kind(name, values[name], names[name])
    return unflatten(values)


PARAMETER_TYPES = frozenset(
    int(t) for t in Parameter.Type
)  # the value types rcl_interfaces defines (0-9)


def guard_parameter_services(node: Node) -> None:
    """Refuse, naming the parameter, a ``set_parameters`` or ``set_parameters_atomically``
    request that holds a value of no parameter type (``ParameterValue.type`` outside 0-9,
    which only a hand-made request holds) or a name the node has no parameter for, before
    rclpy's parameter service sees it: its ``Parameter.from_parameter_msg`` raised ValueError
    out of the executor, so any participant of the domain ended the node with one service
    call; and its refusal of an undeclared name named none (``undeclared parameter(s): []``)."""
    for service in node.services:
        name = service.srv_name.rsplit("/", 1)[-1]
        if name not in ("set_parameters", "set_parameters_atomically"):
            continue

        def guarded(
            request, response, _inner=service.callback, _atomic=name == "set_parameters_atomically"
        ):
            def refusal(p) -> str | None:
                if p.value.type not in PARAMETER_TYPES:
                    return (
                        f"{shorten(p.name, 60)}: value type {p.value.type} is no parameter type "
                        "(must be one of "
                        f"{min(PARAMETER_TYPES)}-{max(PARAMETER_TYPES)}, "
                        "rcl_interfaces/ParameterType)"
                    )
                if not node.has_parameter(p.name):
                    return f"{shorten(p.name, 60)}: {node.get_name()} has no such parameter"
                return None

            reasons = [refusal(p) for p in request.parameters]
            bad = [r for r in reasons if r is not None]
            if not bad:
                return _inner(request, response)
            node.get_logger().warning(f"parameter change refused: {'; '.join(bad)}")
            if _atomic:  # all or none
                response.result = SetParametersResult(successful=False, reason="; ".join(bad))
                return response
            # One result per parameter: the others go to rclpy's service as they would have.
            valid = [p for p, r in zip(request.parameters, reasons) if r is None]
            answered = iter(
                _inner(type(request)(parameters=valid), type(response)()).results if valid else []
            )
            response.results = [
                next(answered) if r is None else SetParametersResult(successful=False, reason=r)
                for r in reasons
            ]
            return response

        service.callback = guarded


def _finite_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _numeric_text(value: object) -> bool:
    """Text that reads as a finite number ('1.95e9')."""
    if not isinstance(value, str):
        return False
    try:
        return math.isfinite(float(value))
    except ValueError:
        return False


def require_kind(name: str, value: Any, default: Any) -> None:
    """InputError unless ``value`` is of the kind of its shipped ``default``: a finite number for
    a number (an integer or a float: dynamic typing), text, true or false, a list of finite
    numbers or of text. The ranges are checked where each value is used; this keeps a list
    where a name goes, or NaN where a count goes, from reaching a model as a traceback."""
    if isinstance(default, bool):
        ok, kind = isinstance(value, bool), "must be true or false"
    elif isinstance(default, (int, float)) or _numeric_text(default):
        # A default such as 1.95e9 reads as text from config/ (YAML 1.1 wants 1.95e+9) but is a
        # number to the models, and rcl reads it as one from a --params-file: either will do.
        ok, kind = _finite_number(value) or _numeric_text(value), "must be a finite number"
    elif isinstance(default, str):
        ok, kind = isinstance(value, str), "must be text"
    elif (
        isinstance(default, (list, tuple)) and default and all(isinstance(x, str) for x in default)
    ):
        ok, kind = (
            isinstance(value, (list, tuple)) and all(isinstance(x, str) for x in value),
            "must be a list of text",
        )
    elif isinstance(default, (list, tuple)):
        ok, kind = (
            isinstance(value, (list, tuple)) and all(_finite_number(x) for x in value),
            "must be a list of finite numbers",
        )
    else:
        return
    if not ok:
        raise InputError(name, value, f"{kind} (its default: {shorten(default, 40)})")


NODE_CONFIG_FILES = (
    "sim_node.yaml",
    "id_node.yaml",
    "recorder.yaml",
    "replay.yaml",
    "caving_node.yaml",
    "face.yaml",
    "face_host.yaml",
)
MAX_NAMED = 10  # most unused parameter names one log line lists


def say_unused_overrides(node: Node) -> None:
    """Name the overrides (``-p``, ``--params-file``) ``node`` has no parameter for: rclpy drops
    them without a word, and a typo would pass for a setting. A warning for names no node of the
    suite has; an information line for another node's (a ``/**`` file shared by the suite)."""
    overrides = (
        getattr(node, "_parameter_overrides", None) or {}
    )  # rclpy keeps them there, no public accessor
    unused = sorted(name for name in overrides if not node.has_parameter(name))
    if not unused:
        return
    suite = set(flatten(config_defaults(NODE_CONFIG_FILES, with_physics=True)))
    others = [n for n in unused if n in suite]
    unknown = [n for n in unused if n not in suite]

    def listed(names: list[str]) -> str:
        return ", ".join(names[:MAX_NAMED]) + (
            f" and {len(names) - MAX_NAMED} more" if len(names) > MAX_NAMED else ""
        )

    if unknown:
        node.get_logger().warning(
            f"ignored, not a parameter of {node.get_name()} nor of any tail_beam node (a typo?): "
            f"{listed(unknown)}"
        )
    if others:
        node.get_logger().info(f"ignored, parameters of other tail_beam nodes: {listed(others)}")


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
