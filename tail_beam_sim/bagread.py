"""Reading the suite's rosbag2 bags with clear errors: missing, not a bag, empty, truncated, or
lacking a topic. A bad bag is reported as one :class:`InputError`, never half-read.

Topics are matched by their contract name, with or without a namespace (``imu`` and
``/support_07/imu`` both count as ``imu``); a bag holding one topic under two namespaces is
ambiguous and says so.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.rosbag2 import ReaderError

from tail_beam_sim import topics
from tail_beam_sim.bagio import TYPESTORE
from tail_beam_sim.bagwrite import METADATA, PARTIAL_DIR
from tail_beam_sim.errors import InputError

SENSOR_TOPICS = (topics.JACK_PRESSURE, topics.IMU, topics.REBOUND_VELOCITY)
_REPAIR_HINT = "run `tail-beam bag repair PATH` to recover what was written"


def contract_name(topic: str) -> str:
    """The contract name of a recorded topic: its last path component."""
    return topic.rstrip("/").rsplit("/", 1)[-1]


def check_bag_path(path: str | os.PathLike[str]) -> Path:
    """Return the bag directory, or InputError saying why it is not a readable bag."""
    bag = Path(path)
    if not bag.exists():
        raise InputError("bag", str(bag), "does not exist")
    if bag.is_file():
        if bag.suffix in (".mcap", ".db3"):
            raise InputError("bag", str(bag), "is a storage file; give the bag directory that holds it and metadata.yaml")
        raise InputError("bag", str(bag), "is not a rosbag2 bag directory")
    if not (bag / METADATA).exists():
        if any(p.suffix in (".mcap", ".db3") for p in bag.iterdir()):
            raise InputError("bag", str(bag), f"has no metadata.yaml (its writer was killed?); {_REPAIR_HINT}")
        raise InputError("bag", str(bag), "is not a rosbag2 bag (no metadata.yaml)")
    return bag


@dataclass
class RawMessage:
    """One recorded message: contract topic, type, log time (ns) and CDR bytes."""

    topic: str
    msgtype: str
    log_time_ns: int
    data: bytes


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


def raw_messages(path: str | os.PathLike[str], wanted: Iterable[str] | None = None, required: Iterable[str] = ()) -> Iterator[RawMessage]:
    """The bag's messages in log-time order (``wanted`` contract topics; None = all).

    Raises InputError before the first message if the bag is unreadable, empty or lacks a
    ``required`` topic, and if it turns out truncated while reading.
    """
    bag = check_bag_path(path)
    try:
        reader = AnyReader([bag], default_typestore=TYPESTORE)
        reader.open()
    except (AnyReaderError, ReaderError, OSError, KeyError, ValueError) as exc:
        raise InputError("bag", str(bag), f"cannot be read ({_first_line(exc)}): truncated or damaged? {_REPAIR_HINT}") from None
    try:
        if reader.message_count == 0:
            raise InputError("bag", str(bag), "holds no messages")
        by_name: dict[str, set[str]] = {}
        for connection in reader.connections:
            by_name.setdefault(contract_name(connection.topic), set()).add(connection.topic)
        for name in required:
            present = [c for c in reader.connections if contract_name(c.topic) == name and c.msgcount > 0]
            if not present:
                raise InputError("bag", str(bag), f"lacks messages on topic '{name}' ({topics.MSG_TYPES.get(name, '?')}); it has: {', '.join(sorted(by_name)) or 'none'}")
        for name, full in by_name.items():
            if len(full) > 1:
                raise InputError("bag", str(bag), f"holds '{name}' under several namespaces ({', '.join(sorted(full))}); record one support per bag")
        names = set(wanted) if wanted is not None else set(by_name)
        connections = [c for c in reader.connections if contract_name(c.topic) in names]
        try:
            for connection, log_ns, data in reader.messages(connections=connections):
                yield RawMessage(contract_name(connection.topic), connection.msgtype, log_ns, bytes(data))
        except (AnyReaderError, ReaderError, OSError, ValueError, EOFError) as exc:
            raise InputError("bag", str(bag), f"is truncated or damaged ({_first_line(exc)}); {_REPAIR_HINT}") from None
    finally:
        reader.close()


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def read_sensors(path: str | os.PathLike[str], required: Iterable[str] = SENSOR_TOPICS) -> BagSensors:
    """Read and decode a bag's sensor topics (and its JSON topics) into arrays, all or nothing."""
    pressure: list[tuple[float, float]] = []
    imu: list[tuple[float, ...]] = []
    rebounds: list[tuple[float, np.ndarray]] = []
    json_topics: dict[str, list[dict[str, Any]]] = {topics.LABEL: [], topics.IMPACT_TRUTH: [], topics.IMPACT_CMD: []}
    for raw in raw_messages(path, None, required):
        if raw.topic not in topics.MSG_TYPES:
            continue
        msg = TYPESTORE.deserialize_cdr(raw.data, raw.msgtype)
        if raw.topic == topics.JACK_PRESSURE:
            pressure.append((_stamp(msg), msg.fluid_pressure))
        elif raw.topic == topics.IMU:
            w, a = msg.angular_velocity, msg.linear_acceleration
            imu.append((_stamp(msg), w.x, w.y, w.z, a.x, a.y, a.z))
        elif raw.topic == topics.REBOUND_VELOCITY:
            v = msg.twist.linear
            rebounds.append((_stamp(msg), np.array([v.x, v.y, v.z])))
        else:
            json_topics[raw.topic].append(_json(msg.data))
    p = np.array(pressure).reshape(-1, 2)
    i = np.array(imu).reshape(-1, 7)
    p, i = p[np.argsort(p[:, 0], kind="stable")], i[np.argsort(i[:, 0], kind="stable")]
    rebounds.sort(key=lambda r: r[0])
    partial = (Path(path) / PARTIAL_DIR).is_dir() and any((Path(path) / PARTIAL_DIR).iterdir())
    return BagSensors(p[:, 0], p[:, 1], i[:, 0], i[:, 1:4], i[:, 4:7], rebounds, json_topics, partial)


def _stamp(msg: Any) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def _json(text: str) -> dict[str, Any]:
    """A JSON topic's object; a text that is not JSON is kept under ``_unparsed``."""
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return {"_unparsed": text}  # impact_cmd may hold a rejected command: kept, not fatal
