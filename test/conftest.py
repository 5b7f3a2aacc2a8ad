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


def pytest_collection_modifyitems(config, items) -> None:
    """Spread the modules holding slow tests (marked ``slow``) evenly among the others, each
    module's tests kept together (its module fixtures built once). pytest-xdist deals tests out
    in consecutive chunks, then tops each worker up from the front: left at the end (test/sim/ros
    sorts late), a worker still holding two slow tests kept the other one idle; spread out, the
    last tests are short ones that even the two workers out. The order is the same on every
    worker (xdist requires it)."""
    modules: dict[str, list] = {}
    for item in items:
        modules.setdefault(item.nodeid.split("::")[0], []).append(item)
    slow = [m for m, its in modules.items() if any(i.get_closest_marker("slow") for i in its)]
    fast = [m for m in modules if m not in slow]
    slow.reverse()  # test/sim/ros's process tests, the longest, first
    spacing = len(fast) / max(len(slow), 1)  # in modules: a module's count of tests says little
    ordered: list = []
    placed = 0  # slow modules placed so far
    for done, module in enumerate(fast):
        while slow and done >= spacing * placed:
            ordered.extend(modules[slow.pop(0)])
            placed += 1
        ordered.extend(modules[module])
    for module in slow:
        ordered.extend(modules[module])
    items[:] = ordered
