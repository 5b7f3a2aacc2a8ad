"""``-h`` of the node executables: what the node does, its parameters from its config file
(name, default and the file's own comment) and examples. Printed without starting ROS."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from tail_beam_sim.config import default_config_dir

HELP_FLAGS = ("-h", "--help")


@dataclass(frozen=True)
class NodeUsage:
    """What ``<executable> -h`` says: a summary, the parameters of ``config_files`` (in config/)
    and example command lines."""

    executable: str
    summary: str
    config_files: Sequence[str] = ()
    examples: Sequence[str] = ()

    def text(self) -> str:
        lines = [
            f"usage: {self.executable} [-h] [--ros-args [-p NAME:=VALUE]... [--params-file YAML] "
            "[-r __ns:=/NAMESPACE]]",
            "",
            self.summary,
            "",
            "Parameters (set with -p NAME:=VALUE or --params-file; every value of config/*.yaml "
            "is one):",
        ]
        for name in self.config_files:
            for parameter, value, comment in parameter_comments(default_config_dir() / name):
                lines.append(f"  {parameter} = {value}")
                lines.extend(f"      {line}" for line in comment)
        if self.examples:
            lines += ["", "Examples:", *(f"  {example}" for example in self.examples)]
        return "\n".join(lines)


def asks_for_help(argv: Sequence[str]) -> bool:
    """Whether the non-ROS arguments hold -h or --help (``--ros-args ... --`` is skipped)."""
    inside_ros = False
    for arg in argv:
        if arg == "--ros-args":
            inside_ros = True
        elif arg == "--":
            inside_ros = False
        elif not inside_ros and arg in HELP_FLAGS:
            return True
    return False


def parameter_comments(path: Path) -> list[tuple[str, str, list[str]]]:
    """(dotted name, default as written, comment lines above it) of each value of a ROS 2
    parameter file, read from the text so that the file's own comments document the parameters."""
    found: list[tuple[str, str, list[str]]] = []
    stack: list[tuple[int, str]] = []  # (indent, key) of the open sections
    comment: list[str] = []
    for raw in path.read_text(encoding="utf-8").splitlines():
        stripped = raw.strip()
        if not stripped:
            continue
        indent = len(raw) - len(raw.lstrip())
        if stripped.startswith("#"):
            comment.append(stripped.lstrip("#").strip())
            continue
        key, colon, value = stripped.partition(":")
        if not colon:
            comment = []
            continue
        while stack and stack[-1][0] >= indent:
            stack.pop()
        value = value.strip()
        if value:
            path_keys = [k for _, k in stack if k not in ("/**", "ros__parameters")]
            found.append(
                (".".join([*path_keys, key.strip()]), value, comment if path_keys else [])
            )
        else:
            stack.append((indent, key.strip()))
        comment = []
    return found
