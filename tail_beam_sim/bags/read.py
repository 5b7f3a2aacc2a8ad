"""Reading the suite's rosbag2 bags with clear errors: missing, not a bag, empty, truncated, or
lacking a topic. A bad bag is reported as one :class:`InputError`, never half-read.

Topics are matched by their contract name under any namespace (``/support_07/imu``, ``/imu``
and an old bag's relative ``imu`` all count as ``imu``). A bag holding the contract topics of
several supports (namespaces) is read one support at a time: the caller names the namespace,
and without one the error lists those present.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.highlevel import AnyReader

from tail_beam_sim import topics
from tail_beam_sim.bags.records import TYPESTORE, vibration_fields
from tail_beam_sim.bags.write import METADATA, PARTIAL_DIR
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.sensors import BlockSequencer, VibrationBlocks

ANY_NAMESPACE = "*"  # read every namespace of the bag (tail-beam bag info)
SENSOR_TOPICS = (topics.JACK_PRESSURE, topics.IMU, topics.REBOUND_VELOCITY)
# The streams the identifier labels from: any one of them makes a bag identifiable (a support
# without a camera, or with the accelerometer and the camera only, is labelled as id_node does).
IDENTIFY_TOPICS = (topics.JACK_PRESSURE, topics.IMU, topics.VIBRATION, topics.REBOUND_VELOCITY)
# The continuous streams: their stamps set a recording's time base (id_node's arrival gate).
CONTINUOUS_TOPICS = (topics.JACK_PRESSURE, topics.IMU, topics.VIBRATION)
# Where an event's JSON says when it happened.
EVENT_STAMPS = {
    topics.IMPACT_TRUTH: "contact_start_stamp",
    topics.LABEL: "impact_stamp",
    topics.GANGUE_SHARE_TRUTH: "end_stamp_s",
    topics.WINDOW_CMD: "stamp_s",
    topics.WINDOW_STATE: "stamp_s",
    topics.CAVING_DECISION: "stamp_s",
}
# Stamps back by more than this on a stream: a new time base (id_node.time_jump_s's default)
TIME_JUMP_S = 1.0
_REPAIR_HINT = "run `tail-beam bag repair PATH` to recover what was written"


def open_segments_note(path: str | os.PathLike[str]) -> str | None:
    """One line when the bag has segments under ``.partial`` (open while a recorder writes, left
    open by a killed one): no reader reads them, so what a command reports of the bag leaves
    their messages out; ``tail-beam bag repair`` salvages them. None when there are none."""
    partial = Path(path) / PARTIAL_DIR
    try:
        count = (
            sum(1 for _ in partial.iterdir())
            if partial.is_dir() and not partial.is_symlink()
            else 0
        )
    except OSError:
        return None
    if not count:
        return None
    return (
        f"{path}: {count} segment(s) in {PARTIAL_DIR} not read (its recorder is still writing it, "
        "or was killed): "
        f"their messages are left out; after a killed recorder, run `tail-beam bag repair {path}` "
        "to salvage them"
    )


def contract_name(topic: str) -> str:
    """The contract name of a recorded topic: its last path component."""
    return topic.rstrip("/").rsplit("/", 1)[-1]


def check_bag_path(path: str | os.PathLike[str]) -> Path:
    """Return the bag directory, or InputError saying why it is not a readable bag."""
    bag = Path(path)
    if bag.is_symlink() and not bag.exists():
        raise InputError(
            "bag",
            str(bag),
            f"is a dangling symbolic link (to {os.readlink(bag)!r}): give the bag directory",
        )
    if not bag.exists():
        raise InputError("bag", str(bag), "does not exist")
    if bag.is_file():
        if bag.suffix in (".mcap", ".db3"):
            raise InputError(
                "bag",
                str(bag),
                "is a storage file; give the bag directory that holds it and metadata.yaml",
            )
        raise InputError("bag", str(bag), "is not a rosbag2 bag directory")
    if not bag.is_dir():
        raise InputError("bag", str(bag), "is not a rosbag2 bag directory")
    try:
        has_metadata = (bag / METADATA).is_file()
        storage_files = any(p.suffix in (".mcap", ".db3") for p in bag.iterdir())
    except OSError as exc:
        raise InputError("bag", str(bag), f"cannot be listed ({exc.strerror or exc})") from None
    if not has_metadata:
        if storage_files:
            raise InputError(
                "bag", str(bag), f"has no metadata.yaml (its writer was killed?); {_REPAIR_HINT}"
            )
        raise InputError("bag", str(bag), "is not a rosbag2 bag (no metadata.yaml)")
    return bag


@dataclass
class RawMessage:
    """One recorded message: contract topic, type, log time (ns) and CDR bytes."""

    topic: str
    msgtype: str
    log_time_ns: int
    data: bytes
    full_topic: str = ""  # the name as recorded, e.g. /support_07/imu


@dataclass
class BagSensors:
    """A bag's sensor data as arrays (stamps in s of simulation time), plus its JSON topics."""

    pressure_stamp_s: np.ndarray
    pressure_pa: np.ndarray
    imu_stamp_s: np.ndarray
    angular_velocity_radps: np.ndarray
    linear_acceleration_mps2: np.ndarray
    rebounds: list[tuple[float, np.ndarray]]
    json_topics: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    partial: bool = False  # the bag had segments a killed recorder left open
    vibration: VibrationBlocks = field(
        default_factory=VibrationBlocks.empty
    )  # in index order, each block once
    vibration_gaps: list[tuple[int, int]] = field(
        default_factory=list
    )  # (first missing index, samples missing)
    namespace: str = "/"  # the support's namespace the topics were read from
    repeated_samples: dict[str, int] = field(
        default_factory=dict
    )  # per topic: samples at a stamp already read, left out
    time_jumps: dict[str, tuple[float, float]] = field(
        default_factory=dict
    )  # per topic, the first: (log time s, stamps back by s)
    # Messages set aside (not read) by "topic: why", with their count: one message that cannot be
    # taken costs that message, not the recording.
    set_aside: dict[str, int] = field(default_factory=dict)
    # impact_point messages as recorded, in stamp order: (stamp s, frame_id, point (3,) m). Not
    # checked here (whether a point lies on the plate depends on the support): the identifier
    # refuses what is no point on its plate, by name.
    points: list[tuple[float, str, np.ndarray]] = field(default_factory=list)

    @property
    def vibration_lost_samples(self) -> int:
        """Accelerometer samples missing between the first and the last block of the bag."""
        return sum(n for _, n in self.vibration_gaps)


def namespaces(connections: Iterable[Any]) -> list[str]:
    """The namespaces under which a bag holds contract topics, sorted."""
    return sorted(
        {
            topics.namespace_of(c.topic)
            for c in connections
            if contract_name(c.topic) in topics.MSG_TYPES
        }
    )


def _normalise(namespace: str) -> str:
    return "/" + namespace.strip("/") if namespace.strip("/") else "/"


def choose_namespace(bag: Path, connections: Iterable[Any], namespace: str | None) -> str | None:
    """The namespace to read (None: every one, ``ANY_NAMESPACE``); InputError when the bag holds
    several supports and none was chosen, or the chosen one is not there, listing those present."""
    if namespace == ANY_NAMESPACE:
        return None
    present = namespaces(connections)
    if namespace is None or namespace == "":
        if len(present) > 1:
            raise InputError(
                "bag",
                str(bag),
                f"holds the topics of several supports (namespaces {', '.join(present)}); "
                "choose one with --namespace (bag_replay: replay.namespace)",
            )
        return present[0] if present else None
    chosen = _normalise(namespace)
    if chosen not in present:
        raise InputError(
            "namespace",
            namespace,
            f"not in the bag {bag}; it holds {', '.join(present) or 'no contract topic'}",
        )
    return chosen


def raw_messages(
    path: str | os.PathLike[str],
    wanted: Iterable[str] | None = None,
    required: Iterable[str] = (),
    namespace: str | None = None,
    any_of: Iterable[str] = (),
    any_type: bool = False,
) -> Iterator[RawMessage]:
    """The bag's messages in log-time order (``wanted`` contract topics; None = all) of one
    support: ``namespace``, or the only one the bag holds (see :func:`choose_namespace`).

    A contract topic recorded with another message type than the contract's (a hand-made or
    foreign bag: the recorder subscribes with the contract's types) is refused by name, since
    its messages would be decoded as what they are not; ``any_type`` reads it as it is
    (``tail-beam bag info`` lists such a bag, ``bag repair`` checks it reads).

    Raises InputError before the first message if the bag is unreadable, empty, lacks a
    ``required`` topic, has messages on none of ``any_of`` (when given) or holds none of the
    ``wanted`` ones; and while reading if it turns out
    truncated or damaged, or ends before the count its metadata lists (a bad bag is reported,
    not half-read). A damaged storage file can fail in any way inside the reader, so every
    error of the reader becomes that one line.
    """
    bag = check_bag_path(path)
    try:
        reader = AnyReader([bag], default_typestore=TYPESTORE)
        reader.open()
    except Exception as exc:  # noqa: BLE001 - a hostile file can break the reader anywhere
        raise InputError(
            "bag",
            str(bag),
            f"cannot be read ({_first_line(exc)}): truncated or damaged? {_REPAIR_HINT}",
        ) from None
    # What the closed segments lack may lie in segments a killed recorder left open: say so.
    unread = (
        f"; {PARTIAL_DIR} holds segment(s) a recorder left open, which are not read: "
        f"{_REPAIR_HINT}"
        if open_segments_note(bag)
        else ""
    )
    try:
        if reader.message_count == 0:
            raise InputError("bag", str(bag), f"holds no messages{unread}")
        chosen = choose_namespace(bag, reader.connections, namespace)
        support = [
            c
            for c in reader.connections
            if chosen is None or topics.namespace_of(c.topic) == chosen
        ]
        by_name: dict[str, set[str]] = {}
        for connection in support:
            by_name.setdefault(contract_name(connection.topic), set()).add(connection.topic)
        # The topics that hold messages: a connection without any (a recorder lists every
        # contract topic) is not what the bag "has".
        filled = sorted({contract_name(c.topic) for c in support if c.msgcount > 0})
        has = ", ".join(filled) or "none"
        for name in required:
            if name not in filled:
                raise InputError(
                    "bag",
                    str(bag),
                    f"lacks messages on topic '{name}' ({topics.MSG_TYPES.get(name, '?')}); it "
                    f"has: {has}{unread}",
                )
        any_of = tuple(any_of)
        if any_of and not set(any_of) & set(filled):
            raise InputError(
                "bag",
                str(bag),
                f"holds no messages on any of {', '.join(any_of)}; it has: {has}{unread}",
            )
        names = set(wanted) if wanted is not None else set(by_name)
        connections = [c for c in support if contract_name(c.topic) in names]
        if not any(c.msgcount > 0 for c in connections):
            # An empty selection would read as "every topic" to the reader: refuse it here.
            raise InputError(
                "bag",
                str(bag),
                f"holds no messages on {', '.join(sorted(names)) or 'no topic'}; it has: "
                f"{has}{unread}",
            )
        foreign = [
            c
            for c in connections
            if c.msgcount > 0
            and contract_name(c.topic) in topics.MSG_TYPES
            and c.msgtype != topics.MSG_TYPES[contract_name(c.topic)]
        ]
        if foreign and not any_type:
            c = foreign[0]
            raise InputError(
                "bag",
                str(bag),
                f"records topic '{c.topic}' as {c.msgtype}, not the contract's "
                f"{topics.MSG_TYPES[contract_name(c.topic)]} (docs/interface.md): not a bag of "
                "this suite's topics",
            )
        listed = {id(c): c.msgcount for c in connections}
        read = dict.fromkeys(listed, 0)
        try:
            for connection, log_ns, data in reader.messages(connections=connections):
                read[id(connection)] += 1
                yield RawMessage(
                    contract_name(connection.topic),
                    connection.msgtype,
                    log_ns,
                    bytes(data),
                    connection.topic,
                )
        except Exception as exc:  # noqa: BLE001 - as above
            raise InputError(
                "bag", str(bag), f"is truncated or damaged ({_first_line(exc)}); {_REPAIR_HINT}"
            ) from None
        short = sum(listed.values()) - sum(read.values())
        if any(read[key] < listed[key] for key in listed):
            raise InputError(
                "bag",
                str(bag),
                f"is truncated: {short} of the messages its metadata lists are missing; "
                f"{_REPAIR_HINT}",
            )
    finally:
        try:
            reader.close()
        except Exception:  # noqa: BLE001 - closing a damaged file must not hide the first error
            pass


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


class SetAside:
    """Messages set aside while reading, counted by "topic: why" (what a warning names)."""

    def __init__(self) -> None:
        self.counts: dict[str, int] = {}

    def add(self, topic: str, why: str, count: int = 1) -> None:
        key = f"{topic}: {why}"
        self.counts[key] = self.counts.get(key, 0) + count


@dataclass
class _Run:
    """One time base's decoded messages, as read (the arrays are assembled at the end)."""

    pressure: list[tuple[float, float]] = field(default_factory=list)
    imu: list[tuple[float, ...]] = field(default_factory=list)
    vibration: list[tuple[int, float, np.ndarray, float, float]] = field(default_factory=list)
    rebounds: list[tuple[float, np.ndarray]] = field(default_factory=list)
    json_topics: dict[str, list[dict[str, Any]]] = field(
        default_factory=lambda: {
            topics.LABEL: [],
            topics.IMPACT_TRUTH: [],
            topics.IMPACT_CMD: [],
            topics.WINDOW_CMD: [],
            topics.GANGUE_SHARE_TRUTH: [],
            topics.WINDOW_STATE: [],
            topics.CAVING_DECISION: [],
        }
    )
    points: list[tuple[float, str, np.ndarray]] = field(default_factory=list)

    def merged(self, other: _Run) -> _Run:
        return _Run(
            self.pressure + other.pressure,
            self.imu + other.imu,
            self.vibration + other.vibration,
            self.rebounds + other.rebounds,
            {k: v + other.json_topics[k] for k, v in self.json_topics.items()},
            self.points + other.points,
        )


def read_sensors(
    path: str | os.PathLike[str],
    required: Iterable[str] = SENSOR_TOPICS,
    namespace: str | None = None,
    any_of: Iterable[str] = (),
) -> BagSensors:
    """Read and decode one support's sensor topics (and its JSON topics) into arrays, all or
    nothing (``required``, ``any_of``: :func:`raw_messages`). The vibration blocks come back in
    index order (a block recorded late is put back in its place, a repeated one dropped), with
    the index gaps listed; the pressure and IMU samples in stamp order, a sample at a stamp
    already read left out (counted in ``repeated_samples``: a topic recorded twice), as id_node
    leaves out a repeated stamp. A bag holding several time bases (``time_jumps``) comes back
    merged by stamp: :func:`read_runs` takes each alone."""
    runs, chosen, jumps, partial, aside = _read(path, required, namespace, any_of)
    whole = runs[0]
    for run in runs[1:]:
        whole = whole.merged(run)
    return _assemble(whole, partial, chosen, jumps, aside)


def read_runs(
    path: str | os.PathLike[str],
    required: Iterable[str] = SENSOR_TOPICS,
    namespace: str | None = None,
    any_of: Iterable[str] = (),
) -> list[BagSensors]:
    """As :func:`read_sensors`, one :class:`BagSensors` per time base, in recorded order: where a
    sensor topic's stamps go back by more than TIME_JUMP_S (a restarted simulator, a looped
    replay) its next messages belong to the next run, as id_node starts afresh there. Each
    run's ``time_jumps`` are the whole bag's."""
    runs, chosen, jumps, partial, aside = _read(path, required, namespace, any_of)
    return [_assemble(run, partial, chosen, jumps, aside) for run in runs]


def _read(
    path: str | os.PathLike[str],
    required: Iterable[str],
    namespace: str | None,
    any_of: Iterable[str],
) -> tuple[list[_Run], str, dict[str, tuple[float, float]], bool, SetAside]:
    """The bag's messages decoded into runs (one per time base), the namespace read, the first
    time jump of each topic (log time s, stamps back by s), whether the bag is partial and the
    messages set aside."""
    reader = _Sorter()
    for raw in raw_messages(path, None, required, namespace, any_of):
        if raw.topic not in topics.MSG_TYPES:
            continue
        reader.chosen = topics.namespace_of(raw.full_topic)
        reader.add(raw, TYPESTORE.deserialize_cdr(raw.data, raw.msgtype))
    reader.finish()
    for run in reader.runs:
        run.vibration = _sift_vibration(run.vibration, reader.aside)
        _check_index(run.vibration)
    partial = (Path(path) / PARTIAL_DIR).is_dir() and any((Path(path) / PARTIAL_DIR).iterdir())
    return reader.runs, reader.chosen, reader.jumps, partial, reader.aside


class _Sorter:
    """Puts a bag's decoded messages, in recorded order, into runs (one per time base), setting
    aside what id_node would not take, each counted by topic and reason:

    * a continuous stream (jack pressure, IMU, vibration) whose stamps go back by more than
      TIME_JUMP_S starts its next run (a restarted simulator, a looped replay);
    * a message of a continuous stream stamped more than TIME_JUMP_S ahead of its own stream
      and of the others (a clock gone wrong) is held: taken once another stream reaches it
      (when that one jumped there too, every stream moved to a new time base: the next run, as
      id_node starts a new epoch), set aside when its stream goes on before it or the recording
      ends without another stream reaching it (a stream alone takes it as its next run);
    * an event (rebound, impact point, truth, label) goes to the newest run, and is set aside
      when it is stamped before that run's first continuous sample: a recorder started late
      receives transient-local events of impacts from before its recording;
    * a message that cannot be taken at all (a vibration message carrying no block, JSON with
      an integer past the digit limit) is set aside.
    """

    def __init__(self) -> None:
        self.aside = SetAside()
        self.runs = [_Run()]
        self.chosen = "/"
        self.jumps: dict[str, tuple[float, float]] = {}
        self.latest: dict[str, float] = {}  # per continuous topic, the newest stamp taken
        self.run_of: dict[str, int] = {}  # per continuous topic, the run its messages go to
        self.held: dict[str, list[tuple[float, Any]]] = {}  # per topic: (stamp, decoded) ahead
        self.events: list[list[tuple[str, float | None, Any]]] = [[]]  # per run, in order
        self.log_s = 0.0  # log time of the latest message, s

    def add(self, raw: RawMessage, msg: Any) -> None:
        """One decoded message, in recorded order."""
        self.log_s = raw.log_time_ns * 1e-9
        if raw.topic in CONTINUOUS_TOPICS:
            decoded = self._decode(raw.topic, msg)
            if decoded is not None:
                self._continuous(raw, _stamp(msg), decoded)
            return
        newest = max(self.run_of.values(), default=0)
        if raw.topic == topics.REBOUND_VELOCITY:
            v = msg.twist.linear
            event = (_stamp(msg), np.array([v.x, v.y, v.z]))
            self.events[newest].append((raw.topic, event[0], event))
            return
        if raw.topic == topics.IMPACT_POINT:
            p = msg.point
            point = (_stamp(msg), str(msg.header.frame_id), np.array([p.x, p.y, p.z]))
            self.events[newest].append((raw.topic, point[0], point))
            return
        value = _json(msg.data)
        if value is None:
            self.aside.add(raw.topic, "holds a number past the 4300-digit limit")
            return
        stamp = value.get(EVENT_STAMPS.get(raw.topic, ""))
        finite = isinstance(stamp, (int, float)) and not isinstance(stamp, bool)
        self.events[newest].append((raw.topic, float(stamp) if finite else None, value))

    def _decode(self, topic: str, msg: Any) -> Any:
        if topic == topics.JACK_PRESSURE:
            return _stamp(msg), msg.fluid_pressure
        if topic == topics.IMU:
            w, a = msg.angular_velocity, msg.linear_acceleration
            return _stamp(msg), w.x, w.y, w.z, a.x, a.y, a.z
        try:
            return vibration_fields(msg)
        except InputError as exc:
            self.aside.add(topic, f"carries no block ({exc.field} {exc.allowed})")
            return None

    def _continuous(self, raw: RawMessage, stamp: float, decoded: Any) -> None:
        topic = raw.topic
        log_s = raw.log_time_ns * 1e-9
        held = self.held.get(topic)
        if held:
            if stamp >= held[0][0] - TIME_JUMP_S:
                held.append((stamp, decoded))  # the run ahead goes on
                return
            self._set_aside_held(topic)  # its stream went on before it: a stamp gone wrong
        latest = self.latest.get(topic, -math.inf)
        taken = max(self.latest.values(), default=-math.inf)
        new_base = False
        if stamp < latest - TIME_JUMP_S:
            self._next_run(topic, log_s, latest - stamp)
            self.latest[topic] = stamp
        elif stamp > max(latest, self._reach(topic)) + TIME_JUMP_S:
            self.held[topic] = [(stamp, decoded)]
            return
        elif latest > -math.inf and stamp > taken + TIME_JUMP_S:
            # Ahead of everything taken, and another stream holds messages there: every
            # stream moved to a new time base (id_node starts a new epoch).
            self._next_run(topic, log_s, latest - stamp)
            new_base = True
        elif stamp > latest + TIME_JUMP_S and self._newest_run(topic) > self.run_of.get(topic, 0):
            # Jumped ahead to where the others went on in a new time base: it goes there too.
            self._next_run(topic, log_s, latest - stamp, self._newest_run(topic))
        self._take(topic, stamp, decoded)
        # What another stream holds ahead is taken once this one reaches it.
        for name, other in list(self.held.items()):
            if name != topic and stamp >= other[0][0] - TIME_JUMP_S:
                self._release(name, log_s, new_base)

    def _newest_run(self, topic: str) -> int:
        """The newest run the other continuous streams have reached."""
        return max((r for name, r in self.run_of.items() if name != topic), default=0)

    def _next_run(self, topic: str, log_s: float, back_s: float, to: int | None = None) -> None:
        """``topic``'s messages from here on go to its next run (a new time base), or to run
        ``to``."""
        self.jumps.setdefault(topic, (log_s, back_s))
        self.run_of[topic] = self.run_of.get(topic, 0) + 1 if to is None else to
        if self.run_of[topic] == len(self.runs):
            self.runs.append(_Run())
            self.events.append([])

    def _release(self, topic: str, log_s: float, new_base: bool) -> None:
        """Take what ``topic`` held ahead (in its next run when it is a new time base)."""
        held = self.held.pop(topic)
        latest = self.latest.get(topic, -math.inf)
        if new_base and latest > -math.inf:
            self._next_run(topic, log_s, latest - held[0][0])
        for item in held:
            self._take(topic, *item)

    def _reach(self, topic: str) -> float:
        """The newest stamp the other continuous streams have taken or hold (-inf: none)."""
        stamps = [s for name, s in self.latest.items() if name != topic]
        stamps += [h[-1][0] for name, h in self.held.items() if name != topic and h]
        return max(stamps, default=-math.inf)

    def _take(self, topic: str, stamp: float, decoded: Any) -> None:
        self.latest[topic] = max(stamp, self.latest.get(topic, -math.inf))
        run = self.runs[self.run_of.setdefault(topic, 0)]
        {
            topics.JACK_PRESSURE: run.pressure,
            topics.IMU: run.imu,
            topics.VIBRATION: run.vibration,
        }[topic].append(decoded)

    def _set_aside_held(self, topic: str) -> None:
        held = self.held.pop(topic, [])
        if held:
            self.aside.add(
                topic,
                f"stamped more than {TIME_JUMP_S:g} s ahead of the recording "
                "(a stamp gone wrong; id_node sets it aside too)",
                len(held),
            )

    def finish(self) -> None:
        """The end of the recording: what is held ahead of the other streams is set aside (a
        stream alone is taken as it is); the events go to their runs, those stamped before
        their run's first continuous sample set aside."""
        for topic in list(self.held):
            if any(name != topic for name in self.latest):
                self._set_aside_held(topic)
            else:  # a stream alone: its own new time base
                self._release(topic, self.log_s, True)
        for run, events in zip(self.runs, self.events):
            stamps = [min(r[0] for r in run.pressure)] if run.pressure else []
            stamps += [min(r[0] for r in run.imu)] if run.imu else []
            stamps += [min(v[1] for v in run.vibration)] if run.vibration else []
            first = min(stamps, default=-math.inf)
            for topic, stamp, value in events:
                if stamp is not None and stamp < first:
                    self.aside.add(
                        topic,
                        "stamped before the recording's first sensor sample (an event from "
                        "before the recorder started)",
                    )
                elif topic == topics.REBOUND_VELOCITY:
                    run.rebounds.append(value)
                elif topic == topics.IMPACT_POINT:
                    run.points.append(value)
                else:
                    run.json_topics[topic].append(value)


def _assemble(
    run: _Run,
    partial: bool,
    chosen: str,
    jumps: dict[str, tuple[float, float]],
    aside: SetAside,
) -> BagSensors:
    """One run's messages as arrays: samples in stamp order, each stamp once, vibration blocks
    in index order with their gaps."""
    p = np.array(run.pressure).reshape(-1, 2)
    i = np.array(run.imu).reshape(-1, 7)
    p, i = p[np.argsort(p[:, 0], kind="stable")], i[np.argsort(i[:, 0], kind="stable")]
    (p, p_repeated), (i, i_repeated) = _first_of_each_stamp(p), _first_of_each_stamp(i)
    repeated = {
        name: n for name, n in ((topics.JACK_PRESSURE, p_repeated), (topics.IMU, i_repeated)) if n
    }
    rebounds = sorted(run.rebounds, key=lambda r: r[0])
    blocks = _vibration_blocks(run.vibration)
    gaps = BlockSequencer().push(blocks).gaps
    return BagSensors(
        p[:, 0],
        p[:, 1],
        i[:, 0],
        i[:, 1:4],
        i[:, 4:7],
        rebounds,
        run.json_topics,
        partial,
        blocks,
        gaps,
        chosen,
        repeated,
        dict(jumps),
        dict(aside.counts),
        sorted(run.points, key=lambda p: p[0]),
    )


def _first_of_each_stamp(rows: np.ndarray) -> tuple[np.ndarray, int]:
    """Rows sorted by stamp (column 0, stable: in recorded order within a stamp) without those
    at a stamp an earlier row has (the first recorded kept), and how many were left out."""
    if rows.shape[0] < 2:
        return rows, 0
    keep = np.concatenate([[True], np.diff(rows[:, 0]) != 0.0])
    return (rows, 0) if keep.all() else (rows[keep], int((~keep).sum()))


PERIOD_RTOL = 1e-6  # sample periods this close (relative) are one period (float rounding)
MAX_ODD_SHARE = 0.25  # more blocks than this at odds with the stream: the stream is inconsistent


def _sift_vibration(
    decoded: list[tuple[int, float, np.ndarray, float, float]], aside: SetAside
) -> list[tuple[int, float, np.ndarray, float, float]]:
    """One run's vibration blocks without the few that are at odds with the stream, each set
    aside and counted: a block of another sample period than the stream's (within PERIOD_RTOL
    relative it is the same one), and of two blocks whose running indices overlap while their
    stamps set them apart (:meth:`VibrationBlocks.index_conflict`: a stale or repeated block
    sent again at a later stamp, a block claiming its predecessor's index) the one whose stamp
    agrees less with its neighbours' index and stamp. When more than MAX_ODD_SHARE of the
    blocks are at odds (two accelerometers on one topic, a publisher whose index words do not
    count samples) nothing is set aside: the stream is refused as a whole by the checks after."""
    if len(decoded) < 2:
        return decoded
    periods = np.array([d[3] for d in decoded])
    values, counts = np.unique(periods, return_counts=True)
    weight = [counts[np.abs(values - v) <= PERIOD_RTOL * v].sum() for v in values]
    period = float(values[int(np.argmax(weight))])
    same = np.abs(periods - period) <= PERIOD_RTOL * period
    if (~same).sum() > MAX_ODD_SHARE * len(decoded):
        return decoded
    if not same.all():
        aside.add(
            topics.VIBRATION,
            f"sample period other than the stream's {period:g} s",
            int((~same).sum()),
        )
        # Within PERIOD_RTOL the blocks take the stream's period.
        decoded = [(d[0], d[1], d[2], period, d[4]) for d, ok in zip(decoded, same) if ok]
    else:
        decoded = [(d[0], d[1], d[2], period, d[4]) for d in decoded]
    dropped = 0
    for _ in range(8):  # rounds: a block set aside may uncover another conflict
        blocks = _vibration_blocks(decoded, in_order=False)
        odd = _odd_blocks(blocks)
        if not odd:
            break
        if dropped + len(odd) > MAX_ODD_SHARE * len(decoded):
            return decoded
        dropped += len(odd)
        decoded = [d for k, d in enumerate(decoded) if k not in odd]
    if dropped:
        aside.add(
            topics.VIBRATION,
            "running index taken by another block at another stamp (a stale or repeated block)",
            dropped,
        )
    return decoded


def _odd_blocks(blocks: VibrationBlocks) -> set[int]:
    """Positions of the blocks to set aside: of each pair whose running indices overlap while
    their stamps are further apart than the indices say (as index_conflict finds them), the one
    whose offset (stamp less index times period) is further from its stamp neighbours'."""
    order = np.lexsort((blocks.stamp_s, blocks.first_index))
    first, length = blocks.first_index[order], blocks.lengths[order]
    stamp, period = blocks.stamp_s[order], blocks.period_s
    overlap = first[1:] < first[:-1] + length[:-1]
    off = np.abs(np.diff(stamp) - np.diff(first) * period) > 0.5 * length[:-1] * period
    pairs = np.flatnonzero(overlap & off)
    if not pairs.size:
        return set()
    offset = blocks.stamp_s - blocks.first_index * period
    by_stamp = np.argsort(blocks.stamp_s, kind="stable")
    rank = np.empty_like(by_stamp)
    rank[by_stamp] = np.arange(by_stamp.size)
    odd: set[int] = set()
    for p in pairs:
        a, b = int(order[p]), int(order[p + 1])
        if a in odd or b in odd:
            continue

        def deviation(k: int) -> float:
            near = by_stamp[max(0, rank[k] - 4) : rank[k] + 5]
            near = [n for n in near if n not in (a, b)]
            if not near:
                return 0.0
            return float(abs(offset[k] - np.median(offset[near])))

        odd.add(a if deviation(a) > deviation(b) else b)
    return odd


def _check_index(decoded: list[tuple[int, float, np.ndarray, float, float]]) -> None:
    """InputError naming the index fields when one run's blocks give overlapping running
    indices to samples their stamps set apart (:meth:`VibrationBlocks.index_conflict`): taken
    as they are, all but one of them would be dropped as repeats."""
    blocks = _vibration_blocks(decoded, in_order=False)
    conflict = blocks.index_conflict()
    if conflict is not None:
        (i, t, _), (j, u, _) = blocks.block(conflict[0]), blocks.block(conflict[1])
        raise InputError(
            "vibration.angle_min/angle_max",
            f"running index {i} at stamp {t:.6f} s and {j} at {u:.6f} s",
            "must be the running sample index: each block's is the one before it plus that "
            "block's sample "
            "count (docs/interface.md)",
        )


def _vibration_blocks(
    decoded: list[tuple[int, float, np.ndarray, float, float]], in_order: bool = True
) -> VibrationBlocks:
    """Decoded vibration messages as blocks in index order (each index once; as recorded
    unless ``in_order``); InputError when they disagree on the sample period (two
    accelerometers on one topic, or a foreign message): one period for all would misplace the
    others' samples in time."""
    if not decoded:
        return VibrationBlocks.empty()
    periods = sorted({d[3] for d in decoded})
    if periods[-1] - periods[0] > PERIOD_RTOL * periods[0]:
        raise InputError(
            "vibration.time_increment",
            periods[:3],
            f"must be one sample period for the whole bag (first: {decoded[0][3]:g} s)",
        )
    blocks = VibrationBlocks(
        first_index=np.array([d[0] for d in decoded], dtype=np.int64),
        lengths=np.array([d[2].size for d in decoded], dtype=np.int64),
        stamp_s=np.array([d[1] for d in decoded]),
        accel_mps2=np.concatenate([d[2] for d in decoded]),
        period_s=decoded[0][3],
        range_mps2=decoded[0][4],
    )
    return blocks.sorted() if in_order else blocks


def _stamp(msg: Any) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def _json(text: str) -> dict[str, Any] | None:
    """A JSON topic's object; a text that is no JSON object (not JSON, nested too deep to read,
    or JSON but a list, number or string) is kept under ``_unparsed``: impact_cmd may hold a
    rejected command, and a foreign publisher may have written anything on label. None for JSON
    that holds an integer past Python's digit limit (it cannot be taken as a value at all)."""
    try:
        value = json.loads(text)
    except (json.JSONDecodeError, RecursionError):
        return {"_unparsed": text}
    except ValueError:
        return None
    return value if isinstance(value, dict) else {"_unparsed": text}
