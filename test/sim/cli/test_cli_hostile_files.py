"""Hostile files given to `tail-beam identify --config` and `tail-beam send --file`: binary
junk, invalid UTF-8, nesting 100 000 deep, YAML anchors that expand without end (billion laughs)
or refer to themselves, integers past Python's 4300-digit limit, an endless device. Each is one
line naming the file, exit 2, in bounded time and memory; never a traceback."""

from __future__ import annotations

import resource
import subprocess
import sys
from pathlib import Path

import pytest

TAIL_BEAM = str(Path(sys.executable).parent / "tail-beam")
LAUGHS = "\n".join(
    ["a0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    + [f"a{k}: &a{k} [{', '.join([f'*a{k - 1}'] * 10)}]" for k in range(1, 10)]
    + ["'/**': {ros__parameters: {identification: *a9}}"]
)
CONTENTS = {
    "binary-junk": bytes(range(1, 32)) * 64,
    "invalid-utf8": b"'/**':\n  ros__parameters:\n    name: \xff\xfe\xfd\n",
    "deep-nesting": b"[" * 100_000,
    "billion-laughs": LAUGHS.encode(),
    "self-reference": b"'/**': &a {ros__parameters: {identification: *a}}\n",
    "recursive-anchor": b"&a [*a]\n",
    "huge-integer": b"'/**': {ros__parameters: {identification: {x: " + b"9" * 5000 + b"}}}\n",
}


def limited_memory() -> None:
    """Run the child with 2 GiB of address space: a file read without a cap fails fast."""
    resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))


def run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """`tail-beam` as a user runs it, with bounded memory and time."""
    return subprocess.run(
        [TAIL_BEAM, *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=60,
        preexec_fn=limited_memory,
    )


def assert_one_line_naming(result: subprocess.CompletedProcess, path: str) -> None:
    """Exit 2, no traceback, one line on stderr that names ``path``."""
    assert result.returncode == 2, (result.returncode, result.stderr[-2000:])
    assert "Traceback" not in result.stderr, result.stderr[-2000:]
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and path in lines[0], result.stderr[-2000:]


@pytest.mark.parametrize("name", sorted(CONTENTS))
def test_a_hostile_config_or_impact_file_is_one_line_naming_it(tmp_path, name):
    """identify --config FILE and send --file FILE on a hostile file: one line naming FILE,
    exit 2."""
    path = f"{name}.yaml"  # named as given, relative to the working directory
    (tmp_path / path).write_bytes(CONTENTS[name])
    assert_one_line_naming(run("identify", "--config", path, ".", cwd=tmp_path), path)
    assert_one_line_naming(run("send", "--file", path, cwd=tmp_path), path)


def test_an_endless_device_as_a_file_is_refused_by_size(tmp_path):
    """identify --config /dev/zero and send --file /dev/zero: refused as too large, in bounded
    memory (the whole device was read until the process was killed)."""
    for args in (
        ["identify", "--config", "/dev/zero", str(tmp_path)],
        ["send", "--file", "/dev/zero"],
    ):
        result = run(*args)
        assert_one_line_naming(result, "/dev/zero")
        assert "larger than" in result.stderr
