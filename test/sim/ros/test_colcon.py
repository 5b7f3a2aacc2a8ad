"""A colcon build of the package into a temporary workspace, and its executables found through
the ament index, the way ``ros2 run tail_beam <exe>`` finds them (ros-notes.md)."""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = [pytest.mark.slow, pytest.mark.ros]
REPO = Path(__file__).resolve().parents[3]
VENV_BIN = Path(sys.executable).parent


def in_workspace(
    install: Path, script: str, timeout_s: float = 120
) -> subprocess.CompletedProcess:
    """Run ``script`` in a clean bash that sourced the workspace's setup.bash (as a user would)."""
    env = {
        "HOME": os.environ.get("HOME", "/tmp"),
        "PATH": f"{VENV_BIN}:/usr/bin:/bin",
        "ROS_DOMAIN_ID": os.environ["ROS_DOMAIN_ID"],
    }
    command = f". {shlex.quote(str(install / 'setup.bash'))} && {script}"
    # Run outside the source tree, so that nothing is imported from it by accident.
    return subprocess.run(
        ["bash", "-c", command],
        env=env,
        cwd=install.parent,
        capture_output=True,
        text=True,
        timeout=timeout_s,
    )


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    if shutil.which("colcon", path=str(VENV_BIN)) is None:
        pytest.fail("colcon is not installed (pip install -e '.[colcon]')")
    root = tmp_path_factory.mktemp("ws")
    result = subprocess.run(
        [
            str(VENV_BIN / "colcon"),
            "--log-base",
            str(root / "log"),
            "build",
            "--base-paths",
            str(REPO),
            "--build-base",
            str(root / "build"),
            "--install-base",
            str(root / "install"),
        ],
        cwd=root,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    return root / "install"


PREFIX = (
    "$(python -c 'from ament_index_python import get_package_prefix; "
    'print(get_package_prefix("tail_beam"))\')'
)


def test_ament_index_finds_the_package_and_its_executables(workspace):
    """The colcon-built workspace registers tail_beam in the ament index with the four
    executables and tail-beam under lib/tail_beam."""
    result = in_workspace(workspace, f"echo {PREFIX}; ls {PREFIX}/lib/tail_beam")
    assert result.returncode == 0, result.stderr
    prefix, *executables = result.stdout.split()
    assert Path(prefix) == workspace / "tail_beam"
    assert {"sim_node", "id_node", "bag_recorder", "bag_replay", "tail-beam"} <= set(executables)


def test_the_installed_package_runs_with_its_installed_config(workspace):
    """In the workspace, the package imports from its install space and reads config/ from
    share/tail_beam/config."""
    probe = (
        "import tail_beam_sim, tail_beam_sim.config as c; "
        "print(tail_beam_sim.__file__); print(c.default_config_dir())"
    )
    result = in_workspace(workspace, f"python -c {shlex.quote(probe)}")
    assert result.returncode == 0, result.stderr
    module, config = result.stdout.split()
    assert (
        Path(module).is_relative_to(workspace)
        and Path(config) == workspace / "tail_beam" / "share" / "tail_beam" / "config"
    )


def test_sim_node_found_through_the_index_runs_and_exits_cleanly(workspace):
    """sim_node run from the installed lib/tail_beam simulates a generated impact and exits 0
    when idle."""
    run = (
        f"{PREFIX}/lib/tail_beam/sim_node --ros-args -p sim_node.realtime_factor:=0.0 "
        "-p sim_node.exit_after_idle_s:=0.2 -p scenario.source:=generated -p scenario.count:=1"
    )
    result = in_workspace(workspace, run)
    assert result.returncode == 0, result.stderr
    assert "impact caving-0000" in result.stderr and "done" in result.stderr


def test_installed_cli_reports_bad_input_in_one_line(workspace):
    """The installed tail-beam exits 2 with exactly one line for a bag that does not exist."""
    result = in_workspace(workspace, f"{PREFIX}/lib/tail_beam/tail-beam identify /nonexistent/bag")
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        "tail-beam identify: error: bag = '/nonexistent/bag': does not exist"
    ]
