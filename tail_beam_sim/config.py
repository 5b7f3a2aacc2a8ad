"""Loading the suite's parameters from ROS 2 parameter files in ``config/``.

A ROS 2 parameter file maps a node pattern (``/**`` or ``/ns/node``) to
``{ros__parameters: {...}}``. The physics core reads the same files as the nodes, merges the
parameters of every node pattern in file order, and lets later files override earlier ones.
"""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml

from tail_beam_sim.errors import InputError

DEFAULT_FILES = (
    "support.yaml",
    "materials.yaml",
    "sensors.yaml",
    "scene.yaml",
    "identification.yaml",
    "modes.yaml",
    "fidelity.yaml",
)
CONFIG_DIR_ENV = "TAIL_BEAM_CONFIG_DIR"
# Bounds of a YAML file the suite reads (parameter files, impact lists): a file past them is no
# such file, and reading it on would cost unbounded memory or time.
MAX_FILE_BYTES = 8 * 1024 * 1024
MAX_VALUES = 1_000_000  # values a file may expand to, an alias counted at each use
MAX_DEPTH = 100  # nesting of mappings and lists


def default_config_dir() -> Path:
    """Find the shipped ``config/`` directory.

    Looked for in order: ``$TAIL_BEAM_CONFIG_DIR``; the source tree (editable installs and
    tests); ``share/tail_beam/config`` under the Python prefix (pip install) or under the
    colcon install prefix of this package.
    """
    here = Path(__file__).resolve().parent
    candidates = []
    if os.environ.get(CONFIG_DIR_ENV):
        candidates.append(Path(os.environ[CONFIG_DIR_ENV]))
    candidates.append(here.parent / "config")
    candidates.append(Path(sys.prefix) / "share" / "tail_beam" / "config")
    # colcon: <prefix>/lib/python3.X/site-packages/tail_beam_sim -> <prefix>/share/tail_beam
    if len(here.parents) > 3:
        candidates.append(here.parents[3] / "share" / "tail_beam" / "config")
    for candidate in candidates:
        if (candidate / "support.yaml").is_file():
            return candidate
    raise InputError(
        "config_dir", str(candidates[0]), f"no support.yaml found; set {CONFIG_DIR_ENV}"
    )


def read_yaml_file(path: str | os.PathLike[str], field: str = "config") -> Any:
    """The value of the YAML file ``path``, or InputError naming it as ``field`` and saying
    why not: unreadable, larger than MAX_FILE_BYTES (read no further: ``/dev/zero`` is refused,
    not read), not UTF-8 text, not YAML, nested too deep to read, holding an integer past
    Python's digit limit, or expanding past MAX_VALUES values or MAX_DEPTH levels (anchors whose
    aliases multiply, or refer to themselves)."""
    try:
        with open(path, "rb") as stream:
            raw = stream.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise InputError(
            field, str(path), f"must be a readable file ({exc.strerror or exc})"
        ) from None
    if len(raw) > MAX_FILE_BYTES:
        raise InputError(
            field, str(path), f"is larger than {MAX_FILE_BYTES} bytes: not a YAML file to read"
        )
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(
            field, str(path), f"must be UTF-8 text (byte {exc.start} is not)"
        ) from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        first_line = str(exc).splitlines()[0] if str(exc) else "syntax error"
        raise InputError(field, str(path), f"must be valid YAML ({first_line})") from None
    except RecursionError:
        raise InputError(field, str(path), "is nested too deep to read") from None
    except ValueError as exc:  # an integer of more than 4300 digits
        raise InputError(
            field, str(path), f"holds a value that cannot be read ({str(exc)[:60]})"
        ) from None
    _check_extent(data, field, path)
    return data


def _check_extent(data: Any, field: str, path: str | os.PathLike[str]) -> None:
    """InputError when ``data`` holds more than MAX_VALUES values or nests deeper than
    MAX_DEPTH (walked without recursion; an alias is walked at each of its uses)."""
    stack = [(data, 1)]
    values = 0
    while stack:
        value, depth = stack.pop()
        values += 1
        if values > MAX_VALUES or depth > MAX_DEPTH:
            raise InputError(
                field,
                str(path),
                f"expands to more than {MAX_VALUES} values or {MAX_DEPTH} levels "
                "(YAML anchors that multiply or refer to themselves?)",
            )
        if isinstance(value, Mapping):
            stack.extend((item, depth + 1) for item in value.values())
        elif isinstance(value, list):
            stack.extend((item, depth + 1) for item in value)


def read_parameter_file(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read one ROS 2 parameter file and return its merged ``ros__parameters``."""
    data = read_yaml_file(path, "config")
    if data is None:
        return {}
    if not isinstance(data, Mapping):
        raise InputError("config", str(path), "must map node names to {ros__parameters: ...}")
    merged: dict[str, Any] = {}
    for node_pattern, body in data.items():
        if not isinstance(body, Mapping) or "ros__parameters" not in body:
            raise InputError(
                "config", f"{path}: {node_pattern}", "each entry must hold ros__parameters"
            )
        deep_merge(merged, body["ros__parameters"] or {})
    return merged


def deep_merge(base: dict[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    """Merge ``extra`` into ``base`` in place, recursing into nested mappings."""
    for key, value in extra.items():
        if isinstance(value, Mapping) and isinstance(base.get(key), dict):
            deep_merge(base[key], value)
        elif isinstance(value, Mapping):
            base[key] = deep_merge({}, value)
        else:
            base[key] = value
    return base


def load_parameters(extra_files: Iterable[str | os.PathLike[str]] = ()) -> dict[str, Any]:
    """Return the shipped defaults merged with ``extra_files`` (later files win)."""
    config_dir = default_config_dir()
    params: dict[str, Any] = {}
    for name in DEFAULT_FILES:
        deep_merge(params, read_parameter_file(config_dir / name))
    for path in extra_files:
        deep_merge(params, read_parameter_file(path))
    return params


def flatten(params: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Flatten nested parameters to ROS-style dotted names (``support.beam_length_m``)."""
    flat: dict[str, Any] = {}
    for key, value in params.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(flatten(value, name + "."))
        else:
            flat[name] = value
    return flat


def unflatten(flat: Mapping[str, Any]) -> dict[str, Any]:
    """Inverse of :func:`flatten`: dotted names back to nested mappings."""
    nested: dict[str, Any] = {}
    for name, value in flat.items():
        node = nested
        *parents, leaf = name.split(".")
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value
    return nested


def section(params: Mapping[str, Any], name: str) -> Mapping[str, Any]:
    """Return ``params[name]`` as a mapping, or raise InputError naming the section."""
    value = params.get(name)
    if not isinstance(value, Mapping):
        raise InputError(name, value, "missing parameter section in the config files")
    return value


def fingerprint(*sections: Any) -> str | None:
    """A text equal for parameter sections of equal content (canonical JSON), to key what is
    built from them once; None when a value is not plain data (numbers, text, lists,
    mappings: then build anew)."""
    try:
        return json.dumps(sections, sort_keys=True, default=_plain)
    except (TypeError, ValueError):
        return None


def _plain(value: Any) -> Any:
    """A numpy scalar as its Python number; anything else is refused (TypeError)."""
    item = getattr(value, "item", None)
    if item is not None and getattr(value, "shape", None) == ():
        return item()
    if isinstance(value, Mapping):
        return dict(value)
    raise TypeError(f"not plain data: {type(value).__name__}")
