"""Shared fixtures. Every test run, and every xdist worker in it, gets its own ROS_DOMAIN_ID
before rclpy is imported, so concurrent runs and workers never see each other's messages."""

from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
# Tests live in one folder per layer (test/sim/physics, test/sim/bags, test/sim/ros,
# test/sim/cli, test/id); their shared helpers (rosprobe, id_helpers) sit here and the
# benchmark and soak scripts in test/bench.
for _helpers in (Path(__file__).resolve().parent, Path(__file__).resolve().parent / "bench"):
    if str(_helpers) not in sys.path:
        sys.path.insert(0, str(_helpers))


def _domain_id() -> int:
    """A per-run base plus the worker index: ``$TAIL_BEAM_TEST_DOMAIN_BASE`` (for runs side by
    side on one machine that must never meet), else 1..48 from xdist's run id or this process."""
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID") or f"{os.getpid()}"
    base = int(
        os.environ.get("TAIL_BEAM_TEST_DOMAIN_BASE")
        or int(hashlib.sha256(run.encode()).hexdigest(), 16) % 12 * 4 + 1
    )
    worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0")
    return base + int(worker.removeprefix("gw") or 0) % 4


if "TAIL_BEAM_TEST_DOMAIN_ID" in os.environ:
    os.environ["ROS_DOMAIN_ID"] = os.environ["TAIL_BEAM_TEST_DOMAIN_ID"]
else:
    os.environ["ROS_DOMAIN_ID"] = str(_domain_id())
os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")


@pytest.fixture(scope="session")
def params() -> dict:
    """The shipped default parameters (config/*.yaml), merged."""
    from tail_beam_sim.config import load_parameters

    return load_parameters()


@pytest.fixture(scope="session")
def default_scene(params):
    """The default scene: 25 mm coal, 3.5 m drop, 1.0 m from the hinge."""
    from tail_beam_sim.physics.scene import Scene

    return Scene.from_params(params)
