"""``caving_node``: the caving windows' controller, a thin ROS 2 adapter over
:mod:`tail_beam_id.caving` (docs/caving.md, docs/nodes.md).

It serves one or several supports (``caving_node.supports``: their namespaces, in drawing
order; ``""`` is the node's own). Per support it subscribes to ``label``, ``gangue_share`` and
``gangue_share_truth`` and reads the support's stamp clock from a sensor topic
(``caving_node.clock_topic``: the header stamp of its newest message, read from the serialized
message without decoding it), so that every support keeps its own simulation time. The supports'
windows are drawn one after another: the first opens once its clock reaches
``caving_node.open_at_s``, each next one ``caving_node.next_open_delay_s`` of its own clock after
the previous one closed. A window opens with ``{"action": "open"}`` on its ``window_cmd``; a
fresh closing rule (``caving_node.rule``, its parameters in section ``caving``) is fed the
window's events as they come, and closes it with ``{"action": "close"}`` when it decides (or
when ``caving_node.max_open_s`` has passed). Each opening and closing goes out on
``window_state``, each closing's decision on ``caving_decision`` (JSON, transient-local as
labels, so that the recorder keeps them; docs/interface.md).

A message that does not read (not JSON, a field out of range) is set aside and counted by topic
(``refused``), with a warning naming it, at most one of a kind every few seconds; the node goes
on. A label's revision (an impact already labelled) is no new lump and is not fed.
"""

from __future__ import annotations

import json
import math
import struct
import sys
import time
from dataclasses import dataclass, field
from typing import Any

from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from tail_beam_id.caving.controller import CAVING_NODE
from tail_beam_id.caving.events import Decision, Event, Opened, Tick
from tail_beam_id.caving.feed import decision_json, label_event, share_event, truth_event
from tail_beam_id.caving.rules import Rule, rule_factories
from tail_beam_id.ros.id_node import GANGUE_SHARE_TOPIC, Warnings
from tail_beam_id.stream.label import Label
from tail_beam_id.stream.share import GangueShare
from tail_beam_sim import topics
from tail_beam_sim.errors import InputError
from tail_beam_sim.ros import messages as ros_messages
from tail_beam_sim.ros.params import (
    ALL_PARAMETERS,
    config_defaults,
    declare_and_read,
    refuse_runtime_changes,
)
from tail_beam_sim.ros.spin import ForeignTypeWatch, run_node
from tail_beam_sim.ros.usage import NodeUsage
from tail_beam_sim.spec import CAVING

WINDOW_STATES = ("waiting", "open", "closed")
_CDR_STAMP = {0: struct.Struct(">iI"), 1: struct.Struct("<iI")}  # encapsulation byte 1: endian


def cdr_stamp_s(data: bytes) -> float:
    """The header stamp (s) of a serialized message whose first field is a std_msgs/Header
    (CDR: a 4-byte encapsulation header, then the stamp's int32 sec and uint32 nanosec);
    InputError for bytes that hold none."""
    if len(data) < 12 or data[1] not in _CDR_STAMP:
        raise InputError(
            "clock_topic", f"{len(data)} bytes", "must be a CDR message with a header"
        )
    sec, nanosec = _CDR_STAMP[data[1]].unpack_from(data, 4)
    return sec + nanosec * 1e-9


def topic_of(namespace: str, name: str) -> str:
    """Topic ``name`` of the support in ``namespace`` ("" : relative, the node's own)."""
    return f"{namespace.rstrip('/')}/{name}" if namespace.strip("/") else name


@dataclass
class Window:
    """One support's caving window as the controller drives it."""

    namespace: str
    index: int  # position in the drawing order
    publishers: dict[str, Any] = field(default_factory=dict)
    state: str = "waiting"  # one of WINDOW_STATES
    turn: bool = False  # its turn in the sequence has come
    turn_base_s: float | None = None  # its clock when its turn came (None: not read yet)
    clock_s: float = -math.inf  # newest stamp of its clock topic, s
    rule: Rule | None = None
    opened_s: float = math.nan
    closed_s: float = math.nan
    decision: Decision | None = None
    closed_by: str = ""
    matched_since: float | None = None  # wall s since window_cmd has had a subscriber
    refused: dict[str, int] = field(default_factory=dict)  # topic -> messages set aside
    revisions: int = 0  # label revisions not fed
    outside: int = 0  # events that came while the window was not open

    @property
    def name(self) -> str:
        return self.namespace or "(own namespace)"


class CavingNode(Node):
    """Opens and closes the supports' caving windows on their labels and gangue shares."""

    def __init__(self, **kwargs) -> None:
        super().__init__("tail_beam_caving", **kwargs)
        params = declare_and_read(
            self, config_defaults(["face.yaml", "caving_node.yaml"], with_physics=False)
        )
        checked = CAVING_NODE.check(params.get("caving_node", {}))
        makers = rule_factories(params.get("caving", {}))
        self.oracle_level = CAVING.check(params.get("caving", {}))["oracle_level"]
        rule = checked["rule"]
        if rule not in makers:
            raise InputError("caving_node.rule", rule, f"must be one of {', '.join(makers)}")
        self.rule_name = rule
        self.make_rule = makers[rule]
        supports = list(checked["supports"]) or [""]
        for k, namespace in enumerate(supports):
            if namespace and not namespace.startswith("/"):
                raise InputError(
                    f"caving_node.supports[{k}]", namespace, 'must be "" or an absolute namespace'
                )
        if len(set(supports)) != len(supports):
            raise InputError("caving_node.supports", supports, "must name each support once")
        self.open_at_s = checked["open_at_s"]
        self.next_open_delay_s = checked["next_open_delay_s"]
        self.max_open_s = checked["max_open_s"]
        self.settle_s = checked["settle_s"]
        self.warnings = Warnings(self.get_logger().warning)
        self.windows = [Window(ns, k) for k, ns in enumerate(supports)]
        self.decisions: list[dict[str, Any]] = []  # every caving_decision published, as sent
        self.round_done = False
        clock_qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
        expected: dict[str, str] = {}
        for w in self.windows:
            ns = w.namespace
            w.publishers = {
                topics.WINDOW_CMD: self.create_publisher(
                    String, topic_of(ns, topics.WINDOW_CMD), ros_messages.EVENT_QOS
                ),
                topics.WINDOW_STATE: self.create_publisher(
                    String, topic_of(ns, topics.WINDOW_STATE), ros_messages.EVENT_PUBLISHER_QOS
                ),
                topics.CAVING_DECISION: self.create_publisher(
                    String,
                    topic_of(ns, topics.CAVING_DECISION),
                    ros_messages.EVENT_PUBLISHER_QOS,
                ),
            }
            for name, handle in (
                (topics.LABEL, self._on_label),
                (GANGUE_SHARE_TOPIC, self._on_share),
                (topics.GANGUE_SHARE_TRUTH, self._on_truth),
            ):
                self.create_subscription(
                    String,
                    topic_of(ns, name),
                    lambda msg, w=w, name=name, handle=handle: self._guarded(w, name, handle, msg),
                    ros_messages.EVENT_QOS,
                )
                expected[topic_of(ns, name)] = "std_msgs/msg/String"
            clock = checked["clock_topic"]
            self.create_subscription(
                ros_messages.message_class(topics.MSG_TYPES[clock]),
                topic_of(ns, clock),
                lambda data, w=w: self._on_clock(w, data),
                clock_qos,
                raw=True,
            )
        self._foreign = ForeignTypeWatch(self, expected)
        self.windows[0].turn = True
        self.create_timer(checked["tick_period_s"], self._tick)
        refuse_runtime_changes(
            self,
            ALL_PARAMETERS,
            "caving_node reads its parameters at start-up only (restart it to change them)",
        )
        self.get_logger().info(
            f"closing rule {rule} on {len(self.windows)} support(s): "
            f"{', '.join(w.name for w in self.windows)}; the first window opens at "
            f"{self.open_at_s:g} s of its support's clock"
        )

    # ---- input ---------------------------------------------------------------------------------
    def _on_clock(self, w: Window, data: bytes) -> None:
        try:
            stamp = cdr_stamp_s(bytes(data))
        except InputError as exc:
            self._refuse(w, "clock", exc)
            return
        if stamp > w.clock_s:
            w.clock_s = stamp

    def _guarded(self, w: Window, topic: str, handle, msg: String) -> None:
        """Read one message of ``topic`` with ``handle``; one that does not read is set aside."""
        try:
            event = handle(w, msg.data)
        except (InputError, ValueError, TypeError) as exc:
            self._refuse(w, topic, exc)
            return
        if event is not None:
            self._feed(w, event)

    def _on_label(self, w: Window, data: str) -> Event | None:
        event = label_event(Label.from_json(data))
        if event is None:
            w.revisions += 1
        return event

    def _on_share(self, w: Window, data: str) -> Event | None:
        return share_event(GangueShare.from_json(data))

    def _on_truth(self, w: Window, data: str) -> Event | None:
        return truth_event(data)

    def _refuse(self, w: Window, topic: str, exc: Exception) -> None:
        w.refused[topic] = w.refused.get(topic, 0) + 1
        self.warnings.warn(
            f"{topic_of(w.namespace, topic)}: message set aside: {exc} "
            f"[{w.refused[topic]} set aside so far]",
            time.monotonic(),
        )

    # ---- the windows ---------------------------------------------------------------------------
    def _feed(self, w: Window, event: Event) -> None:
        if w.state != "open" or w.rule is None:
            w.outside += 1
            return
        decision = w.rule.feed(event)
        if decision is not None:
            self._close(w, decision, "rule")

    def _tick(self) -> None:
        now = time.monotonic()
        for w in self.windows:
            if w.state == "waiting" and w.turn:
                self._maybe_open(w, now)
            elif w.state == "open":
                if math.isfinite(w.clock_s):
                    self._feed(w, Tick(w.clock_s))
                if w.state == "open" and w.clock_s >= w.opened_s + self.max_open_s:
                    due = w.opened_s + self.max_open_s
                    self._close(
                        w,
                        Decision(due, self.rule_name, f"open {self.max_open_s:g} s", ()),
                        "max_open_s",
                    )
        self.warnings.flush(now)

    def _maybe_open(self, w: Window, now: float) -> None:
        """Open ``w`` once its clock is due and its window_cmd has been matched for settle_s."""
        if w.publishers[topics.WINDOW_CMD].get_subscription_count() == 0:
            w.matched_since = None
            return
        if w.matched_since is None:
            w.matched_since = now
        if now - w.matched_since < self.settle_s or not math.isfinite(w.clock_s):
            return
        if w.index == 0:
            due = self.open_at_s
        else:
            if w.turn_base_s is None:
                w.turn_base_s = w.clock_s
            due = w.turn_base_s + self.next_open_delay_s
        if w.clock_s < due:
            return
        w.publishers[topics.WINDOW_CMD].publish(String(data=json.dumps({"action": "open"})))
        w.state, w.opened_s = "open", w.clock_s
        w.rule = self.make_rule()
        w.rule.feed(Opened(w.opened_s))
        self._state(w, "open", w.opened_s, f"window {w.index + 1} of {len(self.windows)} opens")

    def _close(self, w: Window, decision: Decision, closed_by: str) -> None:
        w.publishers[topics.WINDOW_CMD].publish(String(data=json.dumps({"action": "close"})))
        stamp = max(w.clock_s, decision.stamp_s)
        w.state, w.closed_s, w.decision, w.closed_by = "closed", stamp, decision, closed_by
        text = decision_json(decision, w.namespace, w.opened_s, w.index, closed_by)
        w.publishers[topics.CAVING_DECISION].publish(String(data=text))
        self.decisions.append(json.loads(text))
        self._state(w, "closed", stamp, f"{decision.rule}: {decision.reason}")
        if w.index + 1 < len(self.windows):
            self.windows[w.index + 1].turn = True
        else:
            self.round_done = True
            self.get_logger().info("round done: every window closed")

    def _state(self, w: Window, state: str, stamp_s: float, why: str) -> None:
        obj = {
            "support": w.namespace,
            "window": w.index,
            "state": state,
            "stamp_s": stamp_s,
            "rule": self.rule_name,
            "why": why,
        }
        w.publishers[topics.WINDOW_STATE].publish(String(data=json.dumps(obj)))
        self.get_logger().info(f"{w.name}: window {state} at {stamp_s:.3f} s: {why}")


USAGE = NodeUsage(
    executable="caving_node",
    summary="The caving windows' controller: opens each support's window on window_cmd and "
    "closes it when its closing rule decides on the support's label and gangue_share "
    "(docs/caving.md).",
    config_files=("caving_node.yaml",),
    examples=(
        "caving_node --ros-args -p caving_node.rule:=sprt            # the node's own namespace",
        'caving_node --ros-args -p "caving_node.supports:=[/support_001, /support_002]"',
        "caving_node --ros-args -p caving_node.rule:=oracle -p caving.oracle_level:=0.3",
    ),
)


def main(args: list[str] | None = None) -> int:
    """Run caving_node until shut down."""
    return run_node(CavingNode, USAGE, args)


if __name__ == "__main__":
    sys.exit(main())
