"""The supports of ``tail-beam demo --face N`` that run in other processes.

One process holds one interpreter lock, so one core at most: at the shipped layout a support's
sim_node and id_node take about a third of a core and its bag_recorder more, and three
supports with their recorders do not keep real time in one process. Over P processes (one per
core by default, ``--processes P`` to choose) the demo's process keeps the controller, every
recorder and ``len // P`` supports' sim_node and id_node; the others run in P - 1 child
processes (:func:`split_supports`), each a :class:`SupportHost`: real nodes on their own
executor and context, talking to the demo's over the middleware as separate hosts would. Every
support gets the parameters it would get in one process.

A child says over a pipe when its nodes are built, then every :data:`STATUS_PERIOD_S` how far
each of its simulators has come (simulated s, window openings and closings); told to stop, it
closes its nodes and sends each support's :class:`SupportSummary`.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any

from tail_beam_id.caving.drawn import Drawn, drawn_between, oracle_close_s
from tail_beam_sim.errors import InputError

STATUS_PERIOD_S = 0.25  # wall s between a child's progress reports
READY_TIMEOUT_S = 120.0  # wall s a child may take to import and build its nodes
STOP_TIMEOUT_S = 30.0  # wall s a child may take to close its nodes and report
ORACLE_LIMIT_S = 600.0  # the oracle's window is searched this long after its opening, s

Windows = list[tuple[float, float]]  # (opened, closed) stamps, s; closed inf while open


class HostLost(RuntimeError):
    """A child process exited or fell silent: its supports stopped, the round cannot end."""


@dataclass(frozen=True)
class SupportSummary:
    """One support's round: simulated time (s), its window's (opened, closed) stamps (s), what
    it drew and what the oracle rule would have drawn from the same flow (None: the window did
    not close, or the oracle's level was not reached), the truth's interval (s), and the
    samples its identifier lost."""

    namespace: str
    simulated_s: float
    windows: Windows
    drawn: Drawn | None
    oracle: Drawn | None
    interval_s: float
    identifier_lost: int


def default_processes(supports: int) -> int:
    """One process per core this process may run on, at most one per support."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return max(1, min(supports, cores or 1))


def split_supports(namespaces: list[str], processes: int) -> list[list[str]]:
    """The supports each process runs, the demo's own first: ``len // processes`` of them there
    (it also carries the controller and every recorder), the rest in contiguous, even blocks
    over the other processes. InputError naming ``--processes`` outside [1, supports]."""
    if not 1 <= processes <= len(namespaces):
        raise InputError(
            "--processes",
            processes,
            f"must be in [1, {len(namespaces)}] (one per support at most)",
        )
    own = len(namespaces) // processes
    rest, children = namespaces[own:], processes - 1
    blocks = [namespaces[:own]]
    for k in range(children):
        blocks.append(rest[k * len(rest) // children : (k + 1) * len(rest) // children])
    return blocks


def progress(sim: Any) -> tuple[float, Windows]:
    """A flow sim_node's simulated time (s) and its window's openings and closings."""
    windows = list(sim.flow.source.windows) if sim.flow is not None else []
    return float(sim.stream.time_s), windows


def summarise(namespace: str, sim: Any, identifier: Any, level: float) -> SupportSummary:
    """What ``sim`` (a flow sim_node, stopped) drew and what the oracle at ``level`` would have
    drawn: the flow's lumps drawn again from its seed (:mod:`tail_beam_id.caving.drawn`)."""
    from tail_beam_sim.physics.lumps import LumpSource

    simulated_s, windows = progress(sim)
    flow = sim.flow
    drawn = oracle = None
    interval_s = flow.flow.interval_s if flow is not None else math.nan
    if flow is not None and windows and windows[0][1] != math.inf:
        opened, closed = windows[0]

        def fresh() -> LumpSource:
            return LumpSource(flow.flow, flow.sim.materials)

        drawn = drawn_between(fresh(), opened, closed)
        oracle_s = oracle_close_s(fresh(), opened, interval_s, level, ORACLE_LIMIT_S)
        oracle = drawn_between(fresh(), opened, oracle_s) if oracle_s is not None else None
    return SupportSummary(
        namespace,
        simulated_s,
        windows,
        drawn,
        oracle,
        interval_s,
        int(identifier.vibration_lost_samples),
    )


def add_support(
    group: Any, namespace: str, sim_values: dict[str, Any], id_values: dict[str, Any]
) -> tuple[Any, Any]:
    """One support's id_node, then its sim_node (which waits for its readers), under
    ``namespace`` in ``group`` (a :class:`~tail_beam_sim.ros.spin.NodeGroup`): (id_node,
    sim_node). The demo's process and its children build their supports alike."""
    from tail_beam_id.ros.id_node import IdNode
    from tail_beam_sim.ros.sim_node import SimNode
    from tail_beam_sim.ros.spin import overrides

    common = {"context": group.context, "namespace": namespace}
    identifier = group.add(IdNode(**common, parameter_overrides=overrides(id_values)))
    sim = group.add(SimNode(**common, parameter_overrides=overrides(sim_values)))
    return identifier, sim


def host_supports(
    namespaces: list[str],
    sim_values: list[dict[str, Any]],
    id_values: dict[str, Any],
    level: float,
    conn: Connection,
) -> None:
    """A child process's work: each support's id_node and sim_node on one executor until the
    demo says stop, then their summaries (``level``: the oracle's). Errors go back as one
    line: the demo says it and stops."""
    try:
        from tail_beam_sim.ros.spin import NodeGroup

        group = NodeGroup()
    except KeyboardInterrupt:
        return
    sims: list[Any] = []
    identifiers: list[Any] = []
    failed = False  # said as one line: no summaries of a round that did not run
    try:
        for ns, values in zip(namespaces, sim_values):
            identifier, sim = add_support(group, ns, values, id_values)
            identifiers.append(identifier)
            sims.append(sim)
        conn.send(("ready", None))
        said = time.monotonic()
        while not conn.poll():
            group.spin_once(0.05)
            if time.monotonic() - said >= STATUS_PERIOD_S:
                conn.send(("status", {ns: progress(s) for ns, s in zip(namespaces, sims)}))
                said = time.monotonic()
        conn.recv()
    except KeyboardInterrupt:  # the demo's Ctrl-C reaches its children too: the demo says it
        pass
    except InputError as exc:
        failed = True
        conn.send(("error", (exc.field, exc.value, exc.allowed)))
    except Exception as exc:  # noqa: BLE001 - said once by the demo, never a child's traceback
        failed = True
        conn.send(("failed", f"{type(exc).__name__}: {exc}"))
    finally:
        group.close()
    if failed:
        return
    try:
        summaries = [summarise(ns, s, i, level) for ns, s, i in zip(namespaces, sims, identifiers)]
        conn.send(("done", summaries))
    except (BrokenPipeError, EOFError, KeyboardInterrupt):
        pass


class SupportHost:
    """A child process running :func:`host_supports`, seen from the demo: its latest progress
    by namespace, and its summaries once stopped."""

    def __init__(
        self,
        namespaces: list[str],
        sim_values: list[dict[str, Any]],
        id_values: dict[str, Any],
        level: float,
    ) -> None:
        from multiprocessing import get_context

        context = get_context("spawn")  # a fresh interpreter: no rclpy state of the demo's
        self.namespaces = namespaces
        self.conn, child = context.Pipe()
        self.process = context.Process(
            target=host_supports,
            args=(namespaces, sim_values, id_values, level, child),
            name=f"face supports {namespaces[0]} .. {namespaces[-1]}",
            daemon=True,
        )
        self.process.start()
        child.close()
        self.status: dict[str, tuple[float, Windows]] = {}
        self.ready = False

    def poll(self) -> None:
        """Take what the child said since the last call; InputError with its one line when a
        parameter was refused there, HostLost when it failed otherwise or died."""
        while self.conn.poll():
            try:
                kind, body = self.conn.recv()
            except (EOFError, ConnectionResetError):
                raise HostLost(f"the process of {', '.join(self.namespaces)} exited") from None
            if kind == "ready":
                self.ready = True
            elif kind == "status":
                self.status = body
            elif kind == "failed":
                raise HostLost(f"the process of {', '.join(self.namespaces)} failed: {body}")
            elif kind == "error":
                raise InputError(*body)

    def wait_ready(self, timeout_s: float = READY_TIMEOUT_S) -> None:
        """Until the child's nodes are built (its imports and models loaded)."""
        deadline = time.monotonic() + timeout_s
        while not self.ready:
            if not self.process.is_alive() and not self.conn.poll():
                raise HostLost(
                    f"the process of {', '.join(self.namespaces)} exited "
                    f"(status {self.process.exitcode}) before its nodes were built"
                )
            if time.monotonic() > deadline:
                raise HostLost(
                    f"the process of {', '.join(self.namespaces)} built no node in {timeout_s:g} s"
                )
            self.conn.poll(0.1)
            self.poll()

    def stop(self) -> list[SupportSummary]:
        """Stop the child and return its supports' summaries (empty if it could not say)."""
        summaries: list[SupportSummary] = []
        try:
            self.conn.send(("stop", None))
            deadline = time.monotonic() + STOP_TIMEOUT_S
            while time.monotonic() < deadline and self.conn.poll(deadline - time.monotonic()):
                kind, body = self.conn.recv()
                if kind == "done":
                    summaries = body
                    break
        except (BrokenPipeError, EOFError, OSError):
            pass
        self.process.join(STOP_TIMEOUT_S)
        if self.process.is_alive():
            self.process.terminate()
            self.process.join(5.0)
        self.conn.close()
        return summaries
