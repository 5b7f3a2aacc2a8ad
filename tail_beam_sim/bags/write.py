"""A rosbag2 writer that survives being killed: the bag is written in closed segments.

The ``rosbags`` Writer writes ``metadata.yaml`` only when it closes, so a process killed
mid-run would leave a bag no reader accepts. :class:`SegmentedBagWriter` writes each segment
(``segment_s`` of wall time) as a complete bag of its own under ``<bag>/.partial/``; when the
segment closes its storage file moves into the bag and the bag's ``metadata.yaml`` is
rewritten atomically to list every closed file. The result is an ordinary multi-file rosbag2
bag at every moment. Between closes, :meth:`SegmentedBagWriter.flush` puts what the open
segment holds on disk (mcap: a complete chunk; sqlite3: a commit), so a SIGKILL loses only
what came after the last flush, and :func:`repair` salvages the rest of the open segment.

:func:`repair` also rewrites a closed file that turns out truncated (keeping its complete
messages), rebuilds a missing ``metadata.yaml``, and checks that the bag reads at the end; it
never follows a symbolic link out of the bag and never deletes or writes through one.

A segment is also closed when its messages span ``max_duration_s`` of log time or its file
reaches ``max_size_bytes`` (rosbag2's split by duration and by size; the size counts what the
file holds on disk plus its pending chunk before compression, so a file never passes the
limit by more than one message). With ``compression="zstd"`` (the default) every mcap chunk
is zstd-compressed inside the file (:func:`tail_beam_sim.bags.records.open_writer`).
"""

from __future__ import annotations

import json
import os
import shutil
import sqlite3
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import yaml
from rosbags.rosbag2 import Writer
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer

from tail_beam_sim import topics
from tail_beam_sim.bags.records import STORAGES, TYPESTORE, open_writer
from tail_beam_sim.errors import InputError, require_new_path

PARTIAL_DIR = ".partial"  # open (or killed) segments live here until they close
METADATA = "metadata.yaml"
_SUFFIX = {"mcap": ".mcap", "sqlite3": ".db3"}
_STORAGE_OF = {suffix: storage for storage, suffix in _SUFFIX.items()}

Salvaged = tuple[str, str, int, bytes]  # (topic, type, log time ns, CDR bytes)


class SegmentedBagWriter:
    """Writes serialized messages to a rosbag2 bag, one closed segment at a time."""

    def __init__(
        self,
        path: str | os.PathLike[str],
        storage: str = "mcap",
        msg_types: Mapping[str, str] | None = None,
        compression: str = "zstd",
        max_duration_s: float = 0.0,
        max_size_bytes: int = 0,
    ) -> None:
        if not isinstance(storage, str) or storage not in STORAGES:
            raise InputError("storage", storage, f"must be one of {', '.join(STORAGES)}")
        self.compression = compression
        self.max_duration_ns = int(max_duration_s * 1e9)  # 0: no split by duration
        self.max_size_bytes = int(max_size_bytes)  # 0: no split by size
        self._segment_start_ns: int | None = None
        self._segment_payload_bytes = 0
        self._custom_data: dict[str, str] = {}
        self.path = require_new_path("bag", path)
        self.storage = storage
        self.msg_types = dict(msg_types or topics.MSG_TYPES)
        try:
            self.path.mkdir(parents=True)
            (self.path / PARTIAL_DIR).mkdir()
        except OSError as exc:
            raise InputError(
                "bag", str(self.path), f"cannot be created ({exc.strerror or exc})"
            ) from None
        self._index = 0
        self._writer: Writer | None = None
        self._connections: dict[str, Any] = {}
        self.message_count = 0
        self._info = empty_info(storage)  # the bag's metadata, kept here: never re-read from disk
        write_metadata(self.path, self._info)

    def write(self, topic: str, log_time_ns: int, data: bytes) -> None:
        """Append one serialized (CDR) message of a known topic (a new file first if the open
        one has reached the split duration or size)."""
        if self._writer is not None and self._split_due(log_time_ns):
            self.close_segment()
        if self._writer is None:
            self._open_segment()
            self._segment_start_ns = log_time_ns
        assert self._writer is not None
        self._writer.write(self._connections[topic], log_time_ns, data)
        self._segment_payload_bytes += len(data)
        self.message_count += 1

    def _split_due(self, log_time_ns: int) -> bool:
        if (
            self.max_duration_ns
            and self._segment_start_ns is not None
            and log_time_ns - self._segment_start_ns >= self.max_duration_ns
        ):
            return True
        return bool(self.max_size_bytes) and self.segment_size_bytes() >= self.max_size_bytes

    def segment_size_bytes(self) -> int:
        """Size of the open file: on disk plus the pending chunk (mcap), or the payload
        written (sqlite3)."""
        storage = getattr(self._writer, "storage", None)
        bio, chunk = getattr(storage, "bio", None), getattr(storage, "chunk", None)
        if bio is not None and chunk is not None:
            return bio.tell() + chunk.bio.tell()
        return self._segment_payload_bytes

    def set_custom_data(self, key: str, value: str) -> None:
        """A ``custom_data`` entry of the bag's metadata.yaml (written at the next segment
        close)."""
        self._custom_data[key] = value

    def _open_segment(self) -> None:
        segment = self.path / PARTIAL_DIR / f"{self.path.name}_{self._index:05d}"
        self._writer = open_writer(segment, self.storage, self.compression)
        self._writer.open()
        self._segment_payload_bytes = 0
        self._connections = {
            topic: self._writer.add_connection(topic, msgtype, typestore=TYPESTORE)
            for topic, msgtype in self.msg_types.items()
        }

    def flush(self) -> None:
        """Put every message written so far on disk, readable by :func:`repair` after a kill.

        mcap: the pending chunk is closed (a complete, indexed record) and the file flushed;
        sqlite3: the open transaction is committed. The segment stays open.
        """
        if self._writer is None:
            return
        storage = self._writer.storage
        if isinstance(storage, McapWriter):
            if storage.chunk.bio.tell():
                storage.close_chunk()
            storage.bio.flush()
        elif isinstance(storage, Sqlite3Writer):
            storage.conn.commit()

    def close_segment(self) -> None:
        """Close the open segment (if any) and add it to the bag."""
        if self._writer is None:
            return
        self._writer.close()
        self._writer = None
        segment = self.path / PARTIAL_DIR / f"{self.path.name}_{self._index:05d}"
        self._index += 1
        self._info = adopt_segment(self.path, segment, self._info)

    def close(self) -> None:
        """Close the last segment; the bag is complete."""
        self.close_segment()
        if self._custom_data:
            info = _info(self.path)
            info["custom_data"] = {**(info.get("custom_data") or {}), **self._custom_data}
            write_metadata(self.path, info)
        shutil.rmtree(self.path / PARTIAL_DIR, ignore_errors=True)


# libyaml's loader and dumper when PyYAML has them: the metadata of a long recording lists
# thousands of files, rewritten at every segment close.
_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)


def _info(path: Path) -> dict[str, Any]:
    return yaml.load((path / METADATA).read_text(encoding="utf-8"), Loader=_LOADER)[
        "rosbag2_bagfile_information"
    ]


def empty_info(storage: str) -> dict[str, Any]:
    """rosbag2 (version 9) metadata of a bag with no file yet."""
    return {
        "version": 9,
        "storage_identifier": storage,
        "relative_file_paths": [],
        "duration": {"nanoseconds": 0},
        "starting_time": {"nanoseconds_since_epoch": 0},
        "message_count": 0,
        "topics_with_message_count": [],
        "compression_format": "",
        "compression_mode": "",
        "files": [],
        "custom_data": {},
        "ros_distro": "rosbags",
    }


def merge_info(bag: dict[str, Any], segment: dict[str, Any]) -> dict[str, Any]:
    """The metadata of ``bag`` with the files and counts of ``segment`` added."""
    merged = {**bag, "files": bag["files"] + segment["files"]}
    merged["relative_file_paths"] = [f["path"] for f in merged["files"]]
    merged["message_count"] = bag["message_count"] + segment["message_count"]
    totals = {
        item["topic_metadata"]["name"]: dict(item) for item in bag["topics_with_message_count"]
    }
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
        end = max(
            f["starting_time"]["nanoseconds_since_epoch"] + f["duration"]["nanoseconds"]
            for f in filled
        )
        merged["starting_time"] = {"nanoseconds_since_epoch": start}
        merged["duration"] = {"nanoseconds": end - start}
    return merged


def adopt_segment(
    bag: Path, segment: Path, bag_info: dict[str, Any] | None = None
) -> dict[str, Any]:
    """Move a closed segment bag's storage file into ``bag`` and list it in the metadata;
    returns the bag's new metadata. ``bag_info`` is the bag's current metadata if the caller
    keeps it (else it is read from disk)."""
    info = _info(segment)
    for entry in info["files"]:
        os.replace(segment / entry["path"], bag / entry["path"])
    shutil.rmtree(segment)
    merged = merge_info(_info(bag) if bag_info is None else bag_info, info)
    write_metadata(bag, merged)
    return merged


def write_metadata(bag: Path, info: dict[str, Any]) -> None:
    """Write ``bag``'s metadata.yaml atomically (a reader never sees half of it).

    The temporary file is created exclusively (a link in its place is removed, never written
    through), and the rename replaces ``metadata.yaml`` itself, even if that is a link.
    """
    tmp = bag / (METADATA + ".tmp")
    if tmp.is_symlink() or tmp.is_file():
        tmp.unlink()
    with tmp.open("x", encoding="utf-8") as stream:
        stream.write(metadata_text(info))
    os.replace(tmp, bag / METADATA)


_LISTS = ("relative_file_paths", "files")  # grow by one entry a segment: rendered once each


def metadata_text(info: dict[str, Any]) -> str:
    """``metadata.yaml``'s text for ``info``, the same mapping as ``yaml.dump`` gives.

    A long recording lists thousands of files and rewrites the list at every segment close;
    PyYAML's representer costs about 0.2 ms an entry, so the whole list would cost a growing
    share of a core. Each file's lines are rendered once (:func:`_file_lines`, cached) and the
    rest, a few dozen lines, is dumped as usual.
    """
    head = {key: value for key, value in info.items() if key not in _LISTS}
    text = yaml.dump({"rosbag2_bagfile_information": head}, Dumper=_DUMPER, sort_keys=False)
    parts = [text]
    paths = info.get("relative_file_paths", [])
    parts.append("  relative_file_paths:" + (" []\n" if not paths else "\n"))
    parts.extend(f"  - {json.dumps(path)}\n" for path in paths)
    files = info.get("files", [])
    parts.append("  files:" + (" []\n" if not files else "\n"))
    parts.extend(
        _file_lines(
            entry["path"],
            entry["starting_time"]["nanoseconds_since_epoch"],
            entry["duration"]["nanoseconds"],
            entry["message_count"],
        )
        for entry in files
    )
    return "".join(parts)


@lru_cache(maxsize=65536)
def _file_lines(path: str, start_ns: int, duration_ns: int, message_count: int) -> str:
    """One ``files`` entry of metadata.yaml (the path as a JSON string: a valid YAML scalar
    whatever characters it holds)."""
    return (
        f"  - path: {json.dumps(path)}\n"
        f"    starting_time:\n      nanoseconds_since_epoch: {int(start_ns)}\n"
        f"    duration:\n      nanoseconds: {int(duration_ns)}\n"
        f"    message_count: {int(message_count)}\n"
    )


@dataclass
class RepairReport:
    """What :func:`repair` did to a bag."""

    kept_files: int = 0  # closed storage files that read whole, kept as they were
    rewritten: int = (
        0  # open segments and damaged or unlisted files whose complete messages were rewritten
    )
    salvaged_messages: int = 0  # messages in the rewritten files
    lost: list[str] = field(
        default_factory=list
    )  # storage files or open segments with nothing readable
    kept_aside: list[str] = field(
        default_factory=list
    )  # damaged closed files, renamed *.damaged (not deleted)
    unknown_type_messages: int = 0  # complete messages of types the suite cannot write (left out)
    skipped_links: list[str] = field(default_factory=list)  # symbolic links in the bag, left alone

    def summary(self) -> str:
        """One line: what was kept, salvaged, lost and left alone."""
        parts = [
            f"kept {self.kept_files} closed file(s)",
            f"salvaged {self.salvaged_messages} messages into {self.rewritten} rewritten file(s)",
        ]
        if self.lost:
            parts.append(f"nothing readable in {', '.join(self.lost)}")
        if self.kept_aside:
            parts.append(f"damaged originals kept aside as {', '.join(self.kept_aside)}")
        if self.unknown_type_messages:
            parts.append(f"left out {self.unknown_type_messages} messages of unknown types")
        if self.skipped_links:
            parts.append(
                f"left alone symbolic link(s), not followed: {', '.join(self.skipped_links)}"
            )
        return "; ".join(parts)


_REPAIR_DIR = ".repair"  # repair's own working directory inside the bag
DAMAGED_SUFFIX = ".damaged"  # a damaged closed file, kept aside by repair


def repair(bag_path: str | os.PathLike[str]) -> RepairReport:
    """Make a bag whose recorder was killed, or whose files were cut short, readable again.

    Every closed file that reads whole is kept; a damaged one, an open segment (``.partial``)
    and a storage file the metadata does not list are rewritten with their complete messages
    (mcap: every complete chunk; sqlite3: every committed row); ``metadata.yaml`` is rebuilt
    from what is there. A damaged original is renamed ``*.damaged``, never deleted; an open
    segment is removed once its messages are rewritten. Symbolic links anywhere in the bag are
    reported and left alone: repair never reads, deletes or writes through one. Whether the result
    reads is for the caller to check (``tail_beam_sim.bags.read``).
    """
    bag = Path(bag_path)
    if bag.is_symlink():
        raise InputError(
            "bag",
            str(bag),
            f"is a symbolic link (to {os.readlink(bag)!r}): repair the bag directory itself",
        )
    if not bag.is_dir():
        raise InputError("bag", str(bag), "does not exist (or is not a bag directory)")
    report = RepairReport()
    old = _read_info(bag)
    files = _storage_files(bag, report)
    segments = _open_segments(bag, report)
    suffixes = {p.suffix for p in files} | {p.suffix for seg in segments for p in seg}
    storage = old.get("storage_identifier") if old else None
    if not isinstance(storage, str) or storage not in _SUFFIX:
        if not suffixes:
            raise InputError(
                "bag", str(bag), "holds neither metadata.yaml nor storage files: nothing to repair"
            )
        storage = "mcap" if ".mcap" in suffixes else "sqlite3"
    work = bag / _REPAIR_DIR
    if work.is_symlink():
        raise InputError(
            "bag",
            str(bag),
            f"holds {_REPAIR_DIR} as a symbolic link: remove it, then repair again",
        )
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir()
    listed = [entry["path"] for entry in old["files"]] if old else []
    topic_meta = (
        {
            t["topic_metadata"]["name"]: t["topic_metadata"]
            for t in old["topics_with_message_count"]
        }
        if old
        else {}
    )
    info = empty_info(storage)
    for path in files:
        records, complete = _read_storage(path)
        if (
            path.name in listed
            and complete
            and path.suffix == _SUFFIX[storage]
            and all(r[0] in topic_meta for r in records)
        ):
            info = merge_info(info, _file_info(path.name, records, topic_meta))
            report.kept_files += 1
        else:
            info = _rewrite(work, bag, path.stem, storage, records, info, report, path.name)
            if complete:
                path.unlink()  # every message of it is in the rewritten file
            else:  # damaged: kept aside, never destroyed (its suffix takes it out of the bag)
                os.replace(path, path.with_name(path.name + DAMAGED_SUFFIX))
                report.kept_aside.append(path.name + DAMAGED_SUFFIX)
    for segment in segments:
        records = [r for path in segment for r in _read_storage(path)[0]]
        info = _rewrite(
            work,
            bag,
            segment[0].parent.name if segment else "segment",
            storage,
            records,
            info,
            report,
            f"{PARTIAL_DIR}/{segment[0].parent.name}" if segment else PARTIAL_DIR,
        )
    write_metadata(bag, info)
    partial = bag / PARTIAL_DIR
    if partial.is_dir() and not partial.is_symlink():
        shutil.rmtree(partial)
    shutil.rmtree(work)
    return report


def _read_info(bag: Path) -> dict[str, Any] | None:
    """The bag's metadata if it is a regular, well-formed file; None otherwise."""
    path = bag / METADATA
    if path.is_symlink() or not path.is_file():
        return None
    try:
        info = _info(bag)
        files = info["files"]
        [t["topic_metadata"]["name"] for t in info["topics_with_message_count"]]
        [f["path"] for f in files]
    # A damaged metadata file is rebuilt, whatever is wrong with it.
    except Exception:  # noqa: BLE001
        return None
    return info


def _storage_files(bag: Path, report: RepairReport) -> list[Path]:
    """The bag's own storage files (regular files); links are reported, never followed."""
    found = []
    for entry in sorted(os.scandir(bag), key=lambda e: e.name):
        if entry.is_symlink():
            report.skipped_links.append(entry.name)
        elif entry.is_file(follow_symlinks=False) and Path(entry.name).suffix in _STORAGE_OF:
            found.append(Path(entry.path))
    return found


def _open_segments(bag: Path, report: RepairReport) -> list[list[Path]]:
    """The storage files of each segment a killed writer left under .partial (no link followed)."""
    partial = bag / PARTIAL_DIR
    if partial.is_symlink() or not partial.is_dir():
        return []
    segments = []
    for entry in sorted(os.scandir(partial), key=lambda e: e.name):
        if entry.is_symlink():
            report.skipped_links.append(f"{PARTIAL_DIR}/{entry.name}")
        elif entry.is_dir(follow_symlinks=False):
            files = []
            for inner in sorted(os.scandir(entry.path), key=lambda e: e.name):
                if inner.is_symlink():
                    report.skipped_links.append(f"{PARTIAL_DIR}/{entry.name}/{inner.name}")
                elif (
                    inner.is_file(follow_symlinks=False) and Path(inner.name).suffix in _STORAGE_OF
                ):
                    files.append(Path(inner.path))
            segments.append(files)
    return segments


def _read_storage(path: Path) -> tuple[list[Salvaged], bool]:
    """Every complete message of one (possibly cut or killed) storage file, and whether the
    file read to its end without a fault."""
    return _read_mcap(path) if path.suffix == ".mcap" else _read_sqlite(path)


def _read_mcap(path: Path) -> tuple[list[Salvaged], bool]:
    from mcap.records import Channel, Footer, Message, Schema
    from mcap.stream_reader import StreamReader

    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str]] = {}
    records: list[Salvaged] = []
    ended = False
    with path.open("rb") as stream:
        try:
            for record in StreamReader(stream, skip_magic=False).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record.name
                elif isinstance(record, Channel):
                    channels[record.id] = (record.topic, schemas.get(record.schema_id, ""))
                elif isinstance(record, Message) and record.channel_id in channels:
                    topic, msgtype = channels[record.channel_id]
                    records.append((topic, msgtype, record.log_time, bytes(record.data)))
                elif isinstance(record, Footer):
                    ended = True
        # The file ends mid-record or is damaged: what came before is kept.
        except Exception:  # noqa: BLE001
            return records, False
    return records, ended


def _read_sqlite(path: Path) -> tuple[list[Salvaged], bool]:
    """Committed rows of a rosbag2 sqlite3 file (opened read-write so that a killed writer's
    hot journal is rolled back first)."""
    records: list[Salvaged] = []
    try:
        connection = sqlite3.connect(f"file:{path}?mode=rw", uri=True)
    except sqlite3.Error:
        return records, False
    try:
        names = {
            row[0]: (row[1], row[2])
            for row in connection.execute("SELECT id, name, type FROM topics")
        }
        for topic_id, stamp, data in connection.execute(
            "SELECT topic_id, timestamp, data FROM messages ORDER BY id"
        ):
            if topic_id in names:
                records.append((*names[topic_id], int(stamp), bytes(data)))
    except sqlite3.Error:
        return records, False
    finally:
        connection.close()
    return records, True


def _file_info(
    name: str, records: list[Salvaged], topic_meta: Mapping[str, Any]
) -> dict[str, Any]:
    """Metadata of one kept storage file, from its messages (a bag-level info of one file)."""
    counts: dict[str, int] = {}
    for topic, *_ in records:
        counts[topic] = counts.get(topic, 0) + 1
    stamps = [r[2] for r in records] or [0]
    entry = {
        "path": name,
        "starting_time": {"nanoseconds_since_epoch": min(stamps)},
        "duration": {"nanoseconds": max(stamps) - min(stamps)},
        "message_count": len(records),
    }
    info = empty_info("")
    info.update(
        files=[entry],
        message_count=len(records),
        topics_with_message_count=[
            {"topic_metadata": topic_meta[t], "message_count": c} for t, c in counts.items()
        ],
    )
    return info


def _rewrite(
    work: Path,
    bag: Path,
    stem: str,
    storage: str,
    records: list[Salvaged],
    info: dict[str, Any],
    report: RepairReport,
    source: str,
) -> dict[str, Any]:
    """Write ``records`` as a new closed file of the bag; returns the metadata with it added."""
    known = [r for r in records if r[1] in TYPESTORE.types]
    report.unknown_type_messages += len(records) - len(known)
    if not known:
        report.lost.append(source)
        return info
    name = f"{stem}_salvaged"
    while any(
        (bag / f"{name}{suffix}").exists() or (bag / f"{name}{suffix}").is_symlink()
        for suffix in _STORAGE_OF
    ):
        name += "_"
    segment = work / name
    types = {topic: msgtype for topic, msgtype, _, _ in known}
    with Writer(segment, version=9, storage_plugin=STORAGES[storage]) as writer:
        connections = {
            t: writer.add_connection(t, m, typestore=TYPESTORE) for t, m in types.items()
        }
        for topic, _, log_ns, data in sorted(known, key=lambda r: r[2]):
            writer.write(connections[topic], log_ns, data)
    segment_info = _info(segment)
    for entry in segment_info["files"]:
        os.replace(segment / entry["path"], bag / entry["path"])
    shutil.rmtree(segment)
    report.rewritten += 1
    report.salvaged_messages += len(known)
    return merge_info(info, segment_info)
