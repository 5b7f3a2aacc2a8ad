"""A rosbag2 writer that survives being killed: the bag is written in closed segments.

The ``rosbags`` Writer writes ``metadata.yaml`` only when it closes, so a process killed
mid-run would leave a bag no reader accepts. :class:`SegmentedBagWriter` writes each segment
(``segment_s`` of wall time) as a complete bag of its own under ``<bag>/.partial/``; when the
segment closes its storage file moves into the bag and the bag's ``metadata.yaml`` is
rewritten atomically to list every closed file. The result is an ordinary multi-file rosbag2
bag at every moment: a SIGKILL loses at most the open segment, and :func:`repair` salvages
the readable part of that one too (mcap: every complete record).
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import yaml
from rosbags.rosbag2 import Writer

from tail_beam_sim import topics
from tail_beam_sim.bagio import STORAGES, TYPESTORE
from tail_beam_sim.errors import InputError

PARTIAL_DIR = ".partial"  # open (or killed) segments live here until they close
METADATA = "metadata.yaml"
_SUFFIX = {"mcap": ".mcap", "sqlite3": ".db3"}


class SegmentedBagWriter:
    """Writes serialized messages to a rosbag2 bag, one closed segment at a time."""

    def __init__(self, path: str | os.PathLike[str], storage: str = "mcap", msg_types: Mapping[str, str] | None = None) -> None:
        if storage not in STORAGES:
            raise InputError("storage", storage, f"must be one of {', '.join(STORAGES)}")
        self.path = Path(path)
        if self.path.exists():
            raise InputError("bag", str(self.path), "must not exist yet (a new bag is written)")
        self.storage = storage
        self.msg_types = dict(msg_types or topics.MSG_TYPES)
        self.path.mkdir(parents=True)
        (self.path / PARTIAL_DIR).mkdir()
        self._index = 0
        self._writer: Writer | None = None
        self._connections: dict[str, Any] = {}
        self.message_count = 0
        write_metadata(self.path, empty_info(storage))

    def write(self, topic: str, log_time_ns: int, data: bytes) -> None:
        """Append one serialized (CDR) message of a known topic."""
        if self._writer is None:
            self._open_segment()
        assert self._writer is not None
        self._writer.write(self._connections[topic], log_time_ns, data)
        self.message_count += 1

    def _open_segment(self) -> None:
        segment = self.path / PARTIAL_DIR / f"{self.path.name}_{self._index:05d}"
        self._writer = Writer(segment, version=9, storage_plugin=STORAGES[self.storage])
        self._writer.open()
        self._connections = {
            topic: self._writer.add_connection(topic, msgtype, typestore=TYPESTORE) for topic, msgtype in self.msg_types.items()
        }

    def close_segment(self) -> None:
        """Close the open segment (if any) and add it to the bag."""
        if self._writer is None:
            return
        self._writer.close()
        self._writer = None
        segment = self.path / PARTIAL_DIR / f"{self.path.name}_{self._index:05d}"
        self._index += 1
        adopt_segment(self.path, segment)

    def close(self) -> None:
        """Close the last segment; the bag is complete."""
        self.close_segment()
        shutil.rmtree(self.path / PARTIAL_DIR, ignore_errors=True)


def _info(path: Path) -> dict[str, Any]:
    return yaml.safe_load((path / METADATA).read_text(encoding="utf-8"))["rosbag2_bagfile_information"]


def empty_info(storage: str) -> dict[str, Any]:
    """rosbag2 (version 9) metadata of a bag with no file yet."""
    return {
        "version": 9, "storage_identifier": storage, "relative_file_paths": [], "duration": {"nanoseconds": 0},
        "starting_time": {"nanoseconds_since_epoch": 0}, "message_count": 0, "topics_with_message_count": [],
        "compression_format": "", "compression_mode": "", "files": [], "custom_data": {}, "ros_distro": "rosbags",
    }


def merge_info(bag: dict[str, Any], segment: dict[str, Any]) -> dict[str, Any]:
    """The metadata of ``bag`` with the files and counts of ``segment`` added."""
    merged = {**bag, "files": bag["files"] + segment["files"]}
    merged["relative_file_paths"] = [f["path"] for f in merged["files"]]
    merged["message_count"] = bag["message_count"] + segment["message_count"]
    totals = {item["topic_metadata"]["name"]: dict(item) for item in bag["topics_with_message_count"]}
    for item in segment["topics_with_message_count"]:
        name = item["topic_metadata"]["name"]
        if name in totals:
            totals[name]["message_count"] += item["message_count"]
        else:
            totals[name] = dict(item)
    merged["topics_with_message_count"] = list(totals.values())
    filled = [f for f in merged["files"] if f["message_count"]]
    if filled:
        start = min(f["starting_time"]["nanoseconds_since_epoch"] for f in filled)
        end = max(f["starting_time"]["nanoseconds_since_epoch"] + f["duration"]["nanoseconds"] for f in filled)
        merged["starting_time"] = {"nanoseconds_since_epoch": start}
        merged["duration"] = {"nanoseconds": end - start}
    return merged


def adopt_segment(bag: Path, segment: Path) -> None:
    """Move a closed segment bag's storage file into ``bag`` and list it in the metadata."""
    info = _info(segment)
    for entry in info["files"]:
        os.replace(segment / entry["path"], bag / entry["path"])
    shutil.rmtree(segment)
    write_metadata(bag, merge_info(_info(bag), info))


def write_metadata(bag: Path, info: dict[str, Any]) -> None:
    """Write ``bag``'s metadata.yaml atomically (a reader never sees half of it)."""
    tmp = bag / (METADATA + ".tmp")
    tmp.write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False), encoding="utf-8")
    os.replace(tmp, bag / METADATA)


def _salvage_mcap(path: Path) -> Iterator[tuple[str, str, int, bytes]]:
    """Every complete message of a (possibly truncated) mcap file: (topic, type, log ns, data)."""
    from mcap.exceptions import McapError
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader

    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str]] = {}
    with path.open("rb") as stream:
        try:
            for record in StreamReader(stream, skip_magic=False).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record.name
                elif isinstance(record, Channel):
                    channels[record.id] = (record.topic, schemas.get(record.schema_id, ""))
                elif isinstance(record, Message) and record.channel_id in channels:
                    topic, msgtype = channels[record.channel_id]
                    yield topic, msgtype, record.log_time, bytes(record.data)
        except (McapError, EOFError, ValueError, OSError):
            return  # the file ends mid-record: what came before is kept


def repair(bag_path: str | os.PathLike[str]) -> tuple[int, int]:
    """Salvage the segments a killed recorder left open and rewrite the metadata.

    Returns (segments salvaged, messages salvaged). Only mcap segments can be salvaged; an
    open sqlite3 segment is reported as lost.
    """
    bag = Path(bag_path)
    if not bag.is_dir():
        raise InputError("bag", str(bag), "does not exist (or is not a bag directory)")
    partial = bag / PARTIAL_DIR
    segments = sorted(p for p in partial.iterdir() if p.is_dir()) if partial.is_dir() else []
    if not (bag / METADATA).exists():
        orphans = sorted(p for p in bag.iterdir() if p.suffix == ".mcap")
        if not orphans:
            raise InputError("bag", str(bag), "holds neither metadata.yaml nor mcap files: nothing to repair")
        write_metadata(bag, empty_info("mcap"))
        segments += [_isolate(p) for p in orphans]
    salvaged = messages = 0
    for segment in segments:
        count = _salvage_segment(bag, segment)
        if count:
            salvaged += 1
            messages += count
    shutil.rmtree(partial, ignore_errors=True)
    return salvaged, messages


def _isolate(mcap_file: Path) -> Path:
    """Move a bare mcap file into a segment directory of its own (to salvage it like one)."""
    segment = mcap_file.parent / PARTIAL_DIR / mcap_file.stem
    segment.mkdir(parents=True, exist_ok=True)
    os.replace(mcap_file, segment / mcap_file.name)
    return segment


def _salvage_segment(bag: Path, segment: Path) -> int:
    """Rewrite the readable messages of an open segment as a closed one; returns the count."""
    records = [r for f in sorted(segment.glob("*.mcap")) for r in _salvage_mcap(f)]
    shutil.rmtree(segment)
    if not records:
        return 0
    salvaged = bag / PARTIAL_DIR / f"{segment.name}_salvaged"
    types = {topic: msgtype for topic, msgtype, _, _ in records}
    with Writer(salvaged, version=9, storage_plugin=STORAGES["mcap"]) as writer:
        connections = {t: writer.add_connection(t, m, typestore=TYPESTORE) for t, m in types.items()}
        for topic, _, log_ns, data in sorted(records, key=lambda r: r[2]):
            writer.write(connections[topic], log_ns, data)
    adopt_segment(bag, salvaged)
    return len(records)
