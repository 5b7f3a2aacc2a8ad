"""``face_host``: several supports' nodes in one process, on one executor.

For each support (``face_host.supports`` of them, as ``/support_001`` ..., or the namespaces of
``face_host.namespaces``) it builds that support's sim_node and id_node (and, with
``face_host.record``, its bag_recorder) under the support's namespace, so that a face does not
need three processes per support. Every other parameter reaches the nodes as it reaches a lone
node: ``--ros-args -p`` and ``/**`` files for all of them, ``/support_002/tail_beam_sim:`` keys
of a ``--params-file`` for one. One seed sets the face: support k (counting from 0) runs with
``flow.seed``, ``scenario.seed`` and ``sensors.seed`` plus k * ``face_host.seed_stride``, k read
from the namespace's ``support_NNN`` (NNN - 1) so that a face spread over several hosts draws
as the same face in one host would (:func:`support_index`). Each
support's sim_node waits for its own readers (id_node, and the recorder) before it starts.

The process stops on SIGINT or SIGTERM, or once every sim_node is done (``exit_after_idle_s``),
as the lone nodes do; each node closes and says what it lost.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any

from rclpy.node import Node
from rclpy.task import Future

from tail_beam_id.ros.id_node import IdNode
from tail_beam_sim.errors import InputError
from tail_beam_sim.ros.params import config_defaults, declare_and_read, refuse_runtime_changes
from tail_beam_sim.ros.recorder_node import RecorderNode, default_bag_path
from tail_beam_sim.ros.sim_node import SimNode
from tail_beam_sim.ros.spin import overrides, run_node
from tail_beam_sim.ros.usage import NodeUsage
from tail_beam_sim.spec import FACE_HOST

DONE_CHECK_PERIOD_S = 0.5  # wall s between two looks at whether every sim_node is done
# The seeds one face seed sets, each with the config file that ships it.
SEEDS = {
    "flow.seed": "flow.yaml",
    "scenario.seed": "sim_node.yaml",
    "sensors.seed": "sensors.yaml",
}


def host_namespaces(checked: dict[str, Any]) -> list[str]:
    """The supports' namespaces: ``namespaces`` when given, else /support_001 .. by count;
    InputError naming the parameter for one that is not absolute or is named twice."""
    given = [ns for ns in checked["namespaces"] if ns != ""]
    if not given:
        return [f"/support_{k:03d}" for k in range(1, checked["supports"] + 1)]
    for k, ns in enumerate(given):
        if not ns.startswith("/") or ns.rstrip("/") == "" or " " in ns:
            raise InputError(f"face_host.namespaces[{k}]", ns, "must be an absolute namespace")
    if len(set(given)) != len(given):
        raise InputError("face_host.namespaces", given, "must name each support once")
    return given


SUPPORT_NAME = re.compile(r"support_(\d+)$")  # a namespace's last name that numbers its support


def support_index(namespace: str, position: int) -> int:
    """Which support of the face ``namespace`` is, from 0: NNN - 1 for one ending in
    ``support_NNN`` (NNN >= 1), so that ``/support_004`` is the fourth on whichever host runs it;
    else ``position``, its place in this host's list."""
    found = SUPPORT_NAME.search(namespace.rstrip("/"))
    if found is not None and int(found.group(1)) >= 1:
        return int(found.group(1)) - 1
    return position


def support_indices(namespaces: list[str]) -> list[int]:
    """Each namespace's :func:`support_index`; InputError naming ``face_host.namespaces`` when
    two of them would be the same support of the face (``/support_002`` and a second name in
    second place): they would draw the same impacts."""
    indices = [support_index(ns, k) for k, ns in enumerate(namespaces)]
    for k, index in enumerate(indices):
        if index in indices[:k]:
            raise InputError(
                "face_host.namespaces",
                namespaces,
                f"{namespaces[indices.index(index)]} and {namespaces[k]} would both be support "
                f"{index + 1} of the face (the same seeds): number them /support_NNN apart",
            )
    return indices


def shared_defaults() -> dict[str, Any]:
    """The shipped values of :data:`SEEDS` and ``recorder.bag_path``, nested: the host reads
    them as the supports' nodes would."""
    files = sorted({*SEEDS.values(), "recorder.yaml"})
    shipped = config_defaults(files, with_physics=False)
    out: dict[str, Any] = {}
    for dotted in [*SEEDS, "recorder.bag_path"]:
        section, name = dotted.split(".")
        out.setdefault(section, {})[name] = shipped[section][name]
    return out


class FaceHost(Node):
    """Builds and owns each support's sim_node, id_node (and bag_recorder)."""

    def __init__(self, **kwargs) -> None:
        super().__init__("tail_beam_face_host", **kwargs)
        params = declare_and_read(
            self, config_defaults(["face_host.yaml"], with_physics=False) | shared_defaults()
        )
        checked = FACE_HOST.check(params["face_host"])
        self.namespaces = host_namespaces(checked)
        indices = support_indices(self.namespaces)
        seeds = {d: params[d.split(".")[0]][d.split(".")[1]] for d in SEEDS}
        for dotted, value in seeds.items():
            if isinstance(value, bool) or not float(value).is_integer() or float(value) < 0:
                raise InputError(dotted, value, "must be an integer >= 0")
        bag = None
        if checked["record"]:
            recorded = params["recorder"]["bag_path"]
            bag = Path(recorded) if recorded else default_bag_path("face")
        refuse_runtime_changes(
            self, None, "face_host reads its parameters at start-up only (restart it)"
        )
        self.members: list[Node] = []
        self.sims: list[SimNode] = []
        self.identifiers: list[IdNode] = []
        self.recorders: list[RecorderNode] = []
        try:
            for index, ns in zip(indices, self.namespaces):
                self._add_support(index, ns, seeds, checked["seed_stride"], bag)
        except BaseException:
            for node in self.members:
                node.destroy_node()
            raise
        self.finished = Future()
        self.create_timer(DONE_CHECK_PERIOD_S, self._check_done)
        self.get_logger().info(
            f"{len(self.namespaces)} support(s) {self.namespaces[0]} .. {self.namespaces[-1]}: "
            f"sim_node, id_node{' and bag_recorder' if bag else ''} each, one executor"
            + (f"; recording to {bag}/support_NNN" if bag else "")
        )

    def _add_support(
        self, k: int, ns: str, seeds: dict[str, Any], stride: int, bag: Path | None
    ) -> None:
        """One support's readers first (its sim_node waits for them), then its sim_node."""
        common = {"context": self.context, "namespace": ns}
        if bag is not None:
            path = str(bag / ns.strip("/").replace("/", "_"))
            recorder = RecorderNode(
                **common, parameter_overrides=overrides({"recorder.bag_path": path})
            )
            self.recorders.append(recorder)
            self.members.append(recorder)
        identifier = IdNode(**common)
        self.identifiers.append(identifier)
        self.members.append(identifier)
        sim_values = {d: int(v) + k * stride for d, v in seeds.items()}
        sim_values["sim_node.wait_for_subscribers"] = 2 if bag is not None else 1
        sim = SimNode(**common, parameter_overrides=overrides(sim_values))
        self.sims.append(sim)
        self.members.append(sim)

    def _check_done(self) -> None:
        if not self.finished.done() and all(s.finished.done() for s in self.sims):
            self.finished.set_result(True)


USAGE = NodeUsage(
    executable="face_host",
    summary="Several supports in one process: each support's sim_node and id_node (and "
    "bag_recorder) under /support_001 ..., on one executor (docs/nodes.md).",
    config_files=("face_host.yaml",),
    examples=(
        "face_host --ros-args -p face_host.supports:=3 -p scenario.source:=flow",
        'face_host --ros-args -p "face_host.namespaces:=[/support_004, /support_005]"',
        "face_host --ros-args -p face_host.record:=true -p recorder.bag_path:=out/bags/face1",
        "face_host --ros-args --params-file face.yaml   # /support_002/tail_beam_sim: ... keys",
    ),
)


def main(args: list[str] | None = None) -> int:
    """Run face_host until shut down."""
    return run_node(FaceHost, USAGE, args)


if __name__ == "__main__":
    sys.exit(main())
