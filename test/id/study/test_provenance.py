"""The git revision a model records in its provenance."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from tail_beam_id.study.provenance import source_revision

pytestmark = pytest.mark.skipif(shutil.which("git") is None, reason="no git on this machine")


def _git(directory: Path, *args: str) -> str:
    return subprocess.run(
        ["git", "-C", str(directory), *args], capture_output=True, text=True, check=True
    ).stdout.strip()


def test_revision_names_the_commit_and_a_changed_tree(tmp_path: Path) -> None:
    """A fresh repository's revision is its commit's abbreviated hash; a tracked file changed
    after it adds -dirty, which a model fitted on uncommitted code must say."""
    _git(tmp_path, "init", "-q")
    (tmp_path / "a.txt").write_text("one\n")
    _git(tmp_path, "add", "a.txt")
    _git(
        tmp_path, "-c", "user.name=t", "-c", "user.email=t@example.org", "commit", "-q", "-m", "c"
    )
    commit = _git(tmp_path, "rev-parse", "HEAD")
    clean = source_revision(tmp_path)
    assert clean is not None and re.fullmatch(r"[0-9a-f]{12}", clean) and commit.startswith(clean)
    (tmp_path / "a.txt").write_text("two\n")
    assert source_revision(tmp_path) == f"{clean}-dirty"


def test_no_checkout_gives_none(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Outside any git checkout (an installed wheel) there is no revision to record, not an
    error."""
    outside = tmp_path / "not_a_repo"
    outside.mkdir()
    monkeypatch.setenv("GIT_CEILING_DIRECTORIES", str(tmp_path))
    assert source_revision(outside) is None
