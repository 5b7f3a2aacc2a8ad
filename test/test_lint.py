"""The linter (ruff, configured in ruff.toml: pycodestyle, pyflakes and import order at line
length 99) runs clean over both packages and the tests, as ament_flake8 would in a ROS package."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
CHECKED = ["tail_beam_sim", "tail_beam_id", "test", "setup.py"]


def ruff(*args: str, cwd: Path = REPO) -> subprocess.CompletedProcess[str]:
    """Run ruff from this environment (the ``test`` extra installs it)."""
    command = [sys.executable, "-m", "ruff"] if shutil.which("ruff") is None else ["ruff"]
    return subprocess.run(
        [*command, *args], cwd=cwd, capture_output=True, text=True, timeout=120, check=False
    )


def test_the_packages_and_tests_pass_the_linter():
    """ruff check finds nothing in tail_beam_sim, tail_beam_id, test and setup.py."""
    result = ruff("check", "--output-format", "concise", *CHECKED)
    assert result.returncode == 0, result.stdout + result.stderr


def test_the_linter_fails_on_a_line_over_the_limit(tmp_path):
    """The check above can fail: a 100-character line and an unused import are both reported."""
    (tmp_path / "ruff.toml").write_text((REPO / "ruff.toml").read_text())
    (tmp_path / "bad.py").write_text("import os\n\nX = '" + "a" * 94 + "'\n")
    result = ruff("check", "--output-format", "concise", "bad.py", cwd=tmp_path)
    assert result.returncode != 0
    assert "E501" in result.stdout and "F401" in result.stdout
