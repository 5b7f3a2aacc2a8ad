"""The floor plan (docs/architecture.md): imports go downward only, no module imports itself
back through others, and only the ROS rooms touch rclpy."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
ROS_PACKAGES = {
    "rclpy",
    "rcl_interfaces",
    "std_msgs",
    "sensor_msgs",
    "geometry_msgs",
    "rosgraph_msgs",
    "builtin_interfaces",
}
# Layers of tail_beam_sim, lowest first: a module may import its own layer and those below.
SIM_LAYERS = ["base", "physics", "bags", "ros", "cli"]
BASE_MODULES = {"errors", "config", "topics", "plotting", "spec"}


def modules(package: str) -> dict[str, Path]:
    """Every module of ``package`` by dotted name."""
    root = REPO / package
    found = {}
    for path in sorted(root.rglob("*.py")):
        parts = list(path.relative_to(REPO).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


def imported(path: Path) -> set[str]:
    """Absolute module names ``path`` imports, at any depth (lazy imports count)."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return names


def sim_layer(module: str) -> str:
    parts = module.split(".")
    if len(parts) == 1 or parts[1] in BASE_MODULES:
        return "base"
    return parts[1]


SIM = modules("tail_beam_sim")
ID = modules("tail_beam_id")
# Floors of tail_beam_id, lowest first (the package's own __init__ is its description only).
ID_FLOORS = ["signals", "methods", "stream", "calibration", "caving", "ros", "study", "cli"]


def id_floor(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def import_graph(found: dict[str, Path]) -> dict[str, set[str]]:
    """module -> the package's modules it imports (lazy and type-checking imports count)."""
    return {
        module: {name for name in imported(path) if name in found and name != module}
        for module, path in found.items()
    }


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected groups of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    groups: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in graph[node]:
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            group = []
            while True:
                top = stack.pop()
                group.append(top)
                if top == node:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return groups


def test_every_sim_module_has_a_known_layer():
    """A new module of tail_beam_sim goes in a room of the plan, not loose in the hall."""
    loose = [m for m in SIM if sim_layer(m) not in SIM_LAYERS]
    assert not loose, f"modules outside the layout's rooms: {loose}"


@pytest.mark.parametrize("module", sorted(set(SIM) - {"tail_beam_sim"}))
def test_sim_imports_go_downward(module):
    """physics <- bags <- ros <- cli: no module imports a layer above its own (the package's own
    ``__init__`` is its public face and re-exports the core)."""
    rank = SIM_LAYERS.index(sim_layer(module))
    upward = [
        name
        for name in imported(SIM[module])
        if name.startswith("tail_beam_sim.") and SIM_LAYERS.index(sim_layer(name)) > rank
    ]
    assert not upward, f"{module} ({sim_layer(module)}) imports upward: {upward}"


def test_every_id_module_has_a_floor():
    """A new module of tail_beam_id goes on a floor of the plan, not loose in the hall."""
    loose = [m for m in ID if m != "tail_beam_id" and id_floor(m) not in ID_FLOORS]
    assert not loose, f"modules outside the floors: {loose}"


@pytest.mark.parametrize("module", sorted(set(ID) - {"tail_beam_id"}))
def test_id_imports_go_downward(module):
    """signals <- methods <- stream <- calibration <- caving <- ros <- study <- cli."""
    rank = ID_FLOORS.index(id_floor(module))
    upward = [
        name
        for name in imported(ID[module])
        if name.startswith("tail_beam_id.") and ID_FLOORS.index(id_floor(name)) > rank
    ]
    assert not upward, f"{module} ({id_floor(module)}) imports upward: {upward}"


@pytest.mark.parametrize("found", [SIM, ID], ids=["tail_beam_sim", "tail_beam_id"])
def test_no_import_circles(found):
    """No module reaches itself again through what it imports, even lazily."""
    assert circles(import_graph(found)) == []


def test_the_circle_finder_finds_circles():
    """The check above can fail: a two-module and a three-module circle are both found."""
    graph = {"a": {"b"}, "b": {"a"}, "c": {"d"}, "d": {"e"}, "e": {"c"}, "f": {"a"}}
    assert sorted(circles(graph)) == [["a", "b"], ["c", "d", "e"]]


@pytest.mark.parametrize("module", sorted(SIM))
def test_simulator_never_names_the_identifier(module):
    """tail_beam_sim <- tail_beam_id: the simulator does not know of the identifier, not even in
    a string."""
    assert "tail_beam_id" not in SIM[module].read_text()


@pytest.mark.parametrize("module", sorted({**SIM, **ID}))
def test_only_ros_rooms_import_ros(module):
    """rclpy and ROS message packages are imported only by tail_beam_sim.ros and
    tail_beam_id.ros's nodes (id_node, caving_node, face_host)."""
    path = SIM.get(module) or ID[module]
    ros = {name for name in imported(path) if name.split(".")[0] in ROS_PACKAGES}
    allowed = module.startswith("tail_beam_sim.ros") or module in (
        "tail_beam_id.ros.id_node",
        "tail_beam_id.ros.caving_node",
        "tail_beam_id.ros.face_host",
    )
    assert allowed or not ros, f"{module} imports {sorted(ros)}"
    assert "_rclpy_pybind11" not in path.read_text(), (
        f"{module} reaches into rclpy's private binding"
    )


def test_physics_imports_no_ros_and_no_bags():
    """The physics core is pure numpy/scipy: importing it loads neither rclpy nor rosbags."""
    heavy = {
        name
        for module, path in SIM.items()
        if sim_layer(module) == "physics"
        for name in imported(path)
        if name.split(".")[0] in ROS_PACKAGES | {"rosbags", "mcap"}
    }
    assert not heavy


def test_verbs_come_from_the_entry_point_group():
    """tail-beam finds identify and evaluate through setup.py's entry points, not by name in the
    simulator."""
    from importlib.metadata import entry_points

    verbs = {ep.name: ep.value for ep in entry_points(group="tail_beam.verbs")}
    assert {"simulate", "identify", "evaluate", "demo", "bag"} <= set(verbs)
    assert verbs["identify"].startswith("tail_beam_id.")


@pytest.mark.parametrize(
    "package", sorted(m for m, p in {**SIM, **ID}.items() if p.name == "__init__.py")
)
def test_every_package_declares_its_public_names(package):
    """Each package says what it exports (``__all__``), so a star import or a reader knows the
    API."""
    path = SIM.get(package) or ID[package]
    assert "__all__" in path.read_text(), f"{package} has no __all__"


TEST_ROOT = REPO / "test"
TEST_FOLDERS = {
    "sim/base",
    "sim/physics",
    "sim/bags",
    "sim/ros",
    "sim/cli",
    ".",
    *(
        f"id/{floor}"
        for floor in ("signals", "methods", "stream", "calibration", "caving", "ros", "study")
    ),
}


def test_tests_sit_in_one_folder_per_layer():
    """Every test module lives in the folder of the layer it pins (docs/architecture.md)."""
    misplaced = [
        str(p.relative_to(TEST_ROOT))
        for p in TEST_ROOT.rglob("test_*.py")
        if str(p.parent.relative_to(TEST_ROOT)) not in TEST_FOLDERS
    ]
    assert not misplaced
    top = sorted(p.name for p in TEST_ROOT.glob("test_*.py"))
    assert top == ["test_layout.py", "test_lint.py"]


def test_every_test_says_what_it_pins():
    """Each test function carries a docstring whose first line says what it pins."""
    bare = []
    for path in TEST_ROOT.rglob("test_*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if (
                isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
                and node.name.startswith("test_")
                and not ast.get_docstring(node)
            ):
                bare.append(f"{path.relative_to(TEST_ROOT)}::{node.name}")
    assert not bare
