"""Which source a trained model was fitted with: the checkout's git revision, recorded in each
model's provenance so that its figures can be reproduced from the code that made them (a
network refitted on features computed by later code converges elsewhere)."""

from __future__ import annotations

import subprocess
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent.parent
GIT_TIMEOUT_S = 10.0  # a git that does not answer within this is taken as no git


def source_revision(directory: Path = PACKAGE_DIR) -> str | None:
    """``git describe --always --dirty`` of the checkout holding ``directory`` (an abbreviated
    commit, ``-dirty`` when files differ from it); None outside a git checkout or without git."""
    try:
        done = subprocess.run(
            ["git", "-C", str(directory), "describe", "--always", "--dirty", "--abbrev=12"],
            capture_output=True,
            text=True,
            timeout=GIT_TIMEOUT_S,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    revision = done.stdout.strip()
    return revision if done.returncode == 0 and revision else None
