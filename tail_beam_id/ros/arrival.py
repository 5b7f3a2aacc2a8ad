"""What ``id_node`` receives, put in stamp order before the identifier sees it.

Messages of the four sensor topics come over separate readers: a busy middleware delivers one
topic's backlog seconds after another's, a few large vibration blocks overtake thousands of
small pressure messages, a rebound overtakes the samples around it. Fed as they arrive, the
identifier would see one stream lag the others and declare it stopped: labels would depend on
arrival, not on the data, and live labels would differ from ``tail-beam identify`` on the bag.

:class:`ArrivalGate` holds every sample until each live continuous stream (jack pressure, IMU,
vibration) has reached its stamp, and until it has been held ``reorder_s`` of wall time (what
a late message on another topic, a rebound, may need to catch up); then it releases all
streams up to one common stamp, the watermark, as the offline replay does. A stream that has
sent nothing for ``stream_idle_s`` of wall time no longer holds the others back (a sensor
gone; at start-up, one not heard from ``stream_idle_s`` after the first is taken as absent): the
identifier then sees it lag and declares it stopped, as it does on a bag in which that sensor ends.

Time jumps: stamps that go back by more than ``time_jump_s`` on a continuous stream mean a new
time base (a simulator restarted, a replay looped): :meth:`ArrivalGate.add` reports where the
new epoch starts, so that the node can decide what it holds, start a fresh identifier and go on.
A sample stamped more than ``time_jump_s`` ahead of the other live streams (a clock gone wrong)
is held aside and counted: accepted once the others reach it, dropped when its stream goes
on in the old time base (a clock gone wrong once), or the start of a new epoch when every
stream that still talks jumped ahead.

Vibration blocks of more than one source on the topic (a second publisher, a stray block
stamped far ahead with a huge running index, a block of another sample period):
:class:`GatedIdentifier` takes the blocks whose stamps agree with their running index and the
stream in use (:class:`BlockTrack`), and sets the others aside by track, counted and noted. A
track other than the one in use is taken only once the one in use has sent nothing for
``stream_idle_s`` while that track went on (a restarted or replaced source); a track stamped
more than ``time_jump_s`` behind is then a new time base. A stray block thus costs that block,
never the stream in use, and an interleaved second stream never restarts the time base.

Pure numpy, no ROS: the node and the tests drive the same class.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from tail_beam_id.stream.release import Release, feed
from tail_beam_sim.bags.read import PERIOD_RTOL
from tail_beam_sim.physics.sensors import BlockSequencer, VibrationBlocks
from tail_beam_sim.spec import QOS_DEPTH, Section, number, positive

if TYPE_CHECKING:
    from tail_beam_id.calibration.online import OnlineCalibration
    from tail_beam_id.stream.identifier import StreamIdentifier
    from tail_beam_id.stream.label import Label

CONTINUOUS = ("jack_pressure", "imu", "vibration")
MAX_ASIDE_SAMPLES = 2_000_000  # samples held aside as "ahead of the others" (bounded memory)
MAX_ASIDE_REBOUNDS = 10_000  # rebounds held aside as ahead of the streams (bounded memory)
MAX_POINT_REASONS = 5  # reasons for refused impact points named in one note
POINT_OUT_OF_TIME = "stamped out of the streams' time (more than time_jump_s behind or ahead)"
MAX_OTHER_TRACKS = 4  # vibration block streams followed besides the one in use (blocks)


ID_NODE = Section(
    "id_node",
    "id_node: pacing, arrival order and online calibration (wall-clock s unless said).",
    (
        positive("poll_period_s", "Period at which samples go to the identifier.", "s", high=10.0),
        QOS_DEPTH,
        positive(
            "flush_after_idle_s", "With no message this long, pending impacts are decided.", "s"
        ),
        number(
            "reorder_s",
            "Hold after arrival before a sample is handed on in stamp order.",
            "s",
            0.0,
            10.0,
        ),
        positive(
            "stream_idle_s",
            "A silent stream stops holding the others back after this.",
            "s",
            high=60.0,
        ),
        positive(
            "time_jump_s", "Stamps going back more than this start a new time base.", "s", high=1e6
        ),
        number(
            "calibrate_online_s",
            "Stamp time of data to self-calibrate from (0 = never).",
            "s",
            0.0,
            3600.0,
        ),
    ),
    file="id_node.yaml",
)


@dataclass(frozen=True)
class GateConfig:
    """The ``id_node`` arrival parameters, validated (wall-clock s unless named stamp)."""

    reorder_s: float
    stream_idle_s: float
    time_jump_s: float

    @classmethod
    def from_params(cls, node: dict) -> GateConfig:
        return cls(**ID_NODE.check(node, only=("reorder_s", "stream_idle_s", "time_jump_s")))


@dataclass
class _Chunk:
    arrival_s: float  # wall clock
    stamp_s: np.ndarray  # (T,) in order
    values: np.ndarray  # (T, k)


@dataclass
class _Stream:
    chunks: list[_Chunk] = field(default_factory=list)
    latest_s: float = -math.inf  # newest stamp accepted (stamp time)
    settled_s: float = -math.inf  # newest stamp held at least reorder_s
    last_arrival_s: float = -math.inf  # wall clock of the last accepted chunk
    last_seen_s: float = -math.inf  # wall clock of the last chunk, accepted or not
    aside: list[_Chunk] = field(default_factory=list)  # samples far ahead of the others


@dataclass
class Counts:
    """Samples and rebounds the gate did not pass on, by reason (reported in the node's log)."""

    repeated_samples: int = 0  # stamp not after the stream's newest (a repeat, out of order)
    ahead_samples: int = (
        0  # set aside: a run stamped more than time_jump_s ahead of the live streams
    )
    ahead_dropped: int = 0  # of those, dropped (the time base did not move)
    # rebound not finite, stamped more than time_jump_s behind the watermark, or held aside as
    # ahead of the streams and never reached by them
    refused_rebounds: int = 0
    # impact points stamped more than time_jump_s behind the watermark or ahead of the streams
    refused_points: int = 0


class ArrivalGate:
    """Releases the continuous streams and rebounds in stamp order (module docstring)."""

    def __init__(self, config: GateConfig) -> None:
        self.config = config
        self.streams = {name: _Stream() for name in CONTINUOUS}
        self.rebounds: list[tuple[float, float, np.ndarray]] = []  # (arrival_s, stamp_s, velocity)
        # rebounds stamped more than time_jump_s ahead of the live streams: a reader of the
        # continuous topics that lags (a busy node as fast as possible) or a clock gone wrong
        self.rebounds_aside: list[tuple[float, float, np.ndarray]] = []
        self.points: list[tuple[float, str, np.ndarray]] = []  # (stamp_s, frame_id, point m)
        self.released_s = -math.inf  # the watermark last released
        self.first_arrival_s = math.inf  # wall clock of the first sample
        self.counts = Counts()

    # ---- input ---------------------------------------------------------------------------
    def backward_jump(self, name: str, stamp_s: np.ndarray) -> int | None:
        """Index of the first of ``stamp_s`` more than ``time_jump_s`` behind what stream
        ``name`` has accepted (a new time base), or None. For vibration blocks, which must be
        split before their running index is sequenced; :meth:`add` finds it for samples."""
        latest = self.streams[name].latest_s
        back = (
            np.flatnonzero(np.asarray(stamp_s) < latest - self.config.time_jump_s)
            if latest > -math.inf
            else []
        )
        return int(back[0]) if len(back) else None

    def add(self, name: str, stamp_s: np.ndarray, values: np.ndarray, now_s: float) -> int | None:
        """Samples of continuous stream ``name`` that arrived (wall clock ``now_s``), in arrival
        order. Returns None, or the index of the first sample of a new time base (stamps back by
        more than ``time_jump_s`` from what was accepted): that sample and the rest are not taken.

        The samples are cut into runs at every step of more than ``time_jump_s`` either way. A
        run that starts more than ``time_jump_s`` ahead of its own stream and of the other live
        streams is set aside (with what continues it) until the others reach it (a stream
        resuming during their backlog), its stream goes on in the old time base (a stamp gone
        wrong: dropped) or every stream jumped (:meth:`forward_jump`). A backlog delivered at
        once has no such step and passes."""
        stamp_s = np.asarray(stamp_s, dtype=float)
        values = np.asarray(values, dtype=float).reshape(stamp_s.size, -1)
        stream = self.streams[name]
        stream.last_seen_s = now_s
        if self.first_arrival_s == math.inf:
            self.first_arrival_s = now_s
        jump = self.config.time_jump_s
        previous = stream.aside[-1].stamp_s[-1] if stream.aside else stream.latest_s
        steps = np.diff(np.concatenate([[previous], stamp_s]))
        starts = [0, *(np.flatnonzero(np.abs(steps[1:]) > jump) + 1), stamp_s.size]
        for lo, hi in zip(starts[:-1], starts[1:]):
            first = stamp_s[lo]
            if first < stream.latest_s - jump:
                self._promote(now_s)
                return lo
            leap = steps[lo] > jump and first > self._reference_s(name, now_s) + jump
            if leap or (stream.aside and first > stream.aside[-1].stamp_s[-1]):
                self.counts.ahead_samples += hi - lo
                if sum(c.stamp_s.size for c in stream.aside) + hi - lo <= MAX_ASIDE_SAMPLES:
                    stream.aside.append(_Chunk(now_s, stamp_s[lo:hi], values[lo:hi]))
                else:
                    self.counts.ahead_dropped += hi - lo
                continue
            # the stream went on in the old time base: what it sent ahead was a stamp gone wrong
            if stream.aside:
                self.counts.ahead_dropped += sum(c.stamp_s.size for c in stream.aside)
                stream.aside = []
            self._accept(stream, stamp_s[lo:hi], values[lo:hi], now_s)
        self._promote(now_s)
        return None

    def _accept(
        self, stream: _Stream, stamp_s: np.ndarray, values: np.ndarray, now_s: float
    ) -> None:
        """Hold samples for release (a repeat or a step back within time_jump_s refused,
        counted)."""
        fresh = stamp_s > np.maximum.accumulate(np.concatenate([[stream.latest_s], stamp_s]))[:-1]
        self.counts.repeated_samples += int((~fresh).sum())
        if fresh.any():
            stream.chunks.append(_Chunk(now_s, stamp_s[fresh], values[fresh]))
            stream.latest_s = float(stamp_s[fresh][-1])
            stream.last_arrival_s = now_s

    def _promote(self, now_s: float) -> None:
        """Accept what was set aside once the other live streams have come within time_jump_s of
        it."""
        for name, stream in self.streams.items():
            if (
                stream.aside
                and stream.aside[0].stamp_s[0]
                <= self._reference_s(name, now_s) + self.config.time_jump_s
            ):
                aside, stream.aside = stream.aside, []
                for chunk in aside:
                    self._accept(stream, chunk.stamp_s, chunk.values, now_s)

    def add_rebound(self, stamp_s: float, velocity_mps: np.ndarray, now_s: float) -> None:
        """One rebound that arrived at wall clock ``now_s``; refused (counted) when its stamp or
        velocity is not finite, or it is stamped more than ``time_jump_s`` behind what was
        released. One stamped more than ``time_jump_s`` ahead of the live streams is held aside
        until they come within ``time_jump_s`` of it (their reader lags: the camera's few
        messages overtake a backlog of samples), and refused if they never do."""
        if not (math.isfinite(stamp_s) and np.isfinite(velocity_mps).all()):
            self.counts.refused_rebounds += (
                1  # no measurement; the identifier would leave it out too
            )
            return
        if stamp_s < self.released_s - self.config.time_jump_s:
            self.counts.refused_rebounds += 1
            return
        rebound = (now_s, float(stamp_s), np.asarray(velocity_mps, dtype=float))
        if stamp_s > self._reference_s("", now_s) + self.config.time_jump_s:
            if len(self.rebounds_aside) >= MAX_ASIDE_REBOUNDS:
                self.counts.refused_rebounds += 1
            else:
                self.rebounds_aside.append(rebound)
            return
        self.rebounds.append(rebound)

    def take_aside_rebounds(self) -> list[tuple[float, np.ndarray]]:
        """The rebounds held aside as ahead of the streams, (stamp s, velocity m/s) each (and
        forget them): a new time base gives them another chance."""
        out = [(stamp, velocity) for _, stamp, velocity in self.rebounds_aside]
        self.rebounds_aside = []
        return out

    def _admit_aside_rebounds(self, now_s: float, everything: bool) -> None:
        """Take the rebounds held aside that the live streams have come within ``time_jump_s``
        of; with ``everything`` (the data ended) the rest are refused, never released ahead of
        any data (a label from a stray rebound alone would be made up)."""
        if not self.rebounds_aside:
            return
        # only live streams reaching it admit a rebound: one beyond where the data stopped has
        # no data to rest on
        reach_s = self._reference_s("", now_s) + self.config.time_jump_s
        kept = []
        for rebound in self.rebounds_aside:
            (self.rebounds if rebound[1] <= reach_s < math.inf else kept).append(rebound)
        if everything:
            self.counts.refused_rebounds += len(kept)
            kept = []
        self.rebounds_aside = kept

    def add_point(self, stamp_s: float, frame_id: str, point_m: np.ndarray, now_s: float) -> None:
        """One impact point that arrived at wall clock ``now_s``, held until the streams reach
        its stamp; refused (counted) when stamped more than ``time_jump_s`` behind what was
        released or ahead of the live streams. Its contents are the identifier's to check."""
        if math.isfinite(stamp_s):
            behind = stamp_s < self.released_s - self.config.time_jump_s
            ahead = stamp_s > self._reference_s("", now_s) + self.config.time_jump_s
            if behind or ahead:
                self.counts.refused_points += 1
                return
        self.points.append((float(stamp_s), frame_id, np.asarray(point_m, dtype=float)))

    def _reference_s(self, name: str, now_s: float) -> float:
        """Newest stamp of the other live streams (inf when there are none to compare with)."""
        others = [
            s.latest_s for n, s in self.streams.items() if n != name and self._active(s, now_s)
        ]
        return max(others, default=math.inf)

    def _active(self, stream: _Stream, now_s: float) -> bool:
        return (
            stream.latest_s > -math.inf
            and now_s - stream.last_arrival_s <= self.config.stream_idle_s
        )

    def forward_jump(
        self, now_s: float, held_elsewhere: Mapping[str, float] | None = None
    ) -> bool:
        """Every stream still talking sends only samples far ahead of what was accepted: the
        time base moved forward (then :meth:`take_aside` gives them to the next epoch). A lone
        stamp gone wrong is not a jump: its stream goes on in the old time base.
        ``held_elsewhere``: stream name -> wall clock (s) at which the caller began holding that
        stream's samples far ahead (the vibration blocks it keeps by track)."""
        held = held_elsewhere or {}
        talking = [
            (n, s)
            for n, s in self.streams.items()
            if now_s - s.last_seen_s <= self.config.stream_idle_s
        ]
        return bool(talking) and all(
            (s.aside and s.last_arrival_s < s.aside[0].arrival_s)
            or (n in held and s.last_arrival_s < held[n])
            for n, s in talking
        )

    def take_aside(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """The samples held aside as ahead, per stream (and forget them)."""
        out = {}
        for name, stream in self.streams.items():
            if stream.aside:
                out[name] = (
                    np.concatenate([c.stamp_s for c in stream.aside]),
                    np.concatenate([c.values for c in stream.aside]),
                )
                stream.aside = []
        return out

    # ---- output --------------------------------------------------------------------------
    def watermark(self, now_s: float) -> float:
        """The stamp up to which every live continuous stream has delivered, and held for
        ``reorder_s``; +inf when no stream is live (everything may go)."""
        for stream in self.streams.values():
            for chunk in stream.chunks:
                if now_s - chunk.arrival_s >= self.config.reorder_s:
                    stream.settled_s = max(stream.settled_s, float(chunk.stamp_s[-1]))
        if now_s - self.first_arrival_s < self.config.stream_idle_s and any(
            s.latest_s == -math.inf for s in self.streams.values()
        ):
            return -math.inf  # start-up: a stream not heard from yet may still come
        live = [s.settled_s for s in self.streams.values() if self._active(s, now_s)]
        return min(live) if live else math.inf

    def release(self, now_s: float, everything: bool = False) -> Release:
        """Everything held with a stamp up to the watermark (all of it with ``everything``)."""
        self._admit_aside_rebounds(now_s, everything)
        limit = math.inf if everything else self.watermark(now_s)
        if limit == math.inf:
            held = [s.chunks[-1].stamp_s[-1] for s in self.streams.values() if s.chunks]
            limit = max(held, default=self.released_s)
            limit = max(limit, max((r[1] for r in self.rebounds), default=limit))
        out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for name, stream in self.streams.items():
            taken_t, taken_v, kept = [], [], []
            for chunk in stream.chunks:
                cut = int(np.searchsorted(chunk.stamp_s, limit, side="right"))
                if cut:
                    taken_t.append(chunk.stamp_s[:cut])
                    taken_v.append(chunk.values[:cut])
                if cut < chunk.stamp_s.size:
                    kept.append(_Chunk(chunk.arrival_s, chunk.stamp_s[cut:], chunk.values[cut:]))
            stream.chunks = kept
            if taken_t:
                out[name] = (np.concatenate(taken_t), np.concatenate(taken_v))
        due = sorted((r for r in self.rebounds if r[1] <= limit), key=lambda r: r[1])
        self.rebounds = [r for r in self.rebounds if r[1] > limit]
        points = sorted((p for p in self.points if not p[0] > limit), key=lambda p: p[0])
        self.points = [p for p in self.points if p[0] > limit]
        if limit > self.released_s:
            self.released_s = limit
        return Release(out, [(stamp, velocity) for _, stamp, velocity in due], points)


Streams = dict[str, tuple[np.ndarray, np.ndarray]]  # stream name -> (stamp_s (T,), values (T, k))


@dataclass
class BlockTrack:
    """One source's run of vibration blocks: stamps that agree with the running index.

    ``next_index`` and ``next_stamp_s`` (s) are where the run's next block is expected,
    ``period_s`` its sample period (s), ``last_arrival_s`` the wall clock (s) of its last block;
    a track other than the one in use holds its blocks (``held``) until it is taken or dropped.
    """

    next_index: int
    next_stamp_s: float
    period_s: float
    first_arrival_s: float
    last_arrival_s: float
    blocks: int = 0
    held: list[VibrationBlocks] = field(default_factory=list)
    held_samples: int = 0  # samples in ``held``

    def same_period(self, period_s: float) -> bool:
        """Periods within PERIOD_RTOL relative are one period (as the bag reader takes them)."""
        return abs(period_s - self.period_s) <= PERIOD_RTOL * self.period_s

    def continues(self, first: int, length: int, stamp_s: float, period_s: float, jump_s: float):
        """The block (first index, sample count, stamp s, period s) belongs to this run: its
        period is the run's, its stamp within ``jump_s`` of the run's next and where its index
        puts it (half a block either way, as the bag reader's index check). A block behind the
        run's index whose stamp is near the run's belongs to it too (a late or repeated block,
        or an index that does not count samples: the sequencer refuses it, counted)."""
        if not self.same_period(period_s) or abs(stamp_s - self.next_stamp_s) > jump_s:
            return False
        implied = self.next_stamp_s + (first - self.next_index) * self.period_s
        return first < self.next_index or abs(stamp_s - implied) <= 0.5 * length * self.period_s

    def extend(self, first: int, length: int, stamp_s: float, now_s: float) -> None:
        if first + length > self.next_index:
            self.next_index = first + length
            self.next_stamp_s = stamp_s + length * self.period_s
        self.last_arrival_s = now_s
        self.blocks += 1


GAPS_KEPT = 1000  # vibration gaps remembered for checking labels against, count


class GatedIdentifier:
    """A :class:`StreamIdentifier` behind an :class:`ArrivalGate`, across time jumps: what
    ``id_node`` runs each tick, free of ROS so that tests drive it the same way.

    Each :meth:`tick` takes what arrived since the last one: the pressure (values (T, 1), Pa)
    and IMU (values (T, 6): angular velocity rad/s then specific force m/s^2) samples as arrays
    in arrival order, the vibration blocks as received, the rebounds; it returns the labels now
    decided. A caller that knows when each message arrived gives them to :meth:`admit` in
    batches of arrival time, then calls :meth:`decide`, so that each is held ``reorder_s`` from
    its own arrival, not from the tick that took it. What the node should log (gaps, refusals,
    time jumps) collects in ``notes``.
    """

    def __init__(
        self,
        new_identifier: Callable[[Any], StreamIdentifier],
        config: GateConfig,
        calibration: OnlineCalibration | None = None,
    ) -> None:
        """``new_identifier(method)``: a fresh identifier reusing the trained ``method`` (None
        the first time); ``calibration``: learn a support profile from the first data and
        decide with it from then on (None: stay on the configured support)."""
        self._new_identifier = new_identifier
        self.calibration = calibration
        self._profile: tuple[dict[str, Any], Any] | None = (
            None  # (model params, method) once calibrated
        )
        self.identifier = new_identifier(None)
        self.gate = ArrivalGate(config)
        self.sequencer = BlockSequencer()
        self.vibration_track: BlockTrack | None = None  # the block stream in use
        self.other_tracks: list[BlockTrack] = []  # other block streams, held apart
        # Vibration blocks set aside as not the stream in use, by reason (not given back when
        # their track is taken after all: that is a new source, counted in ``taken_over``).
        self.stray_blocks: dict[str, int] = {}
        self.taken_over = 0  # times another block stream replaced the one in use
        self.empty_labels = 0  # labels the identifier gave that rest on no signal (dropped)
        self.time_jumps = 0
        # The latest vibration gaps: (stamp where samples went missing, stamp where they resume,
        # samples missing), s; what id_node checks a label's data window against.
        self.vibration_gaps: deque[tuple[float, float, int]] = deque(maxlen=GAPS_KEPT)
        self.notes: list[str] = []
        self._counts_before = (0, 0, 0, 0)
        self._counts_noted = (0, 0, 0, 0)
        self._refused_before = 0  # non-finite samples refused by the identifiers of earlier epochs
        self._refused_noted = 0  # the total already noted
        # impact_point messages the identifiers of earlier epochs refused or set aside, by reason
        self._points_before: dict[str, int] = {}
        self._points_noted = 0  # the total already noted
        self._gate_points_before = 0  # points the gates of earlier epochs refused

    def tick(
        self,
        now_s: float,
        arrivals: Streams,
        blocks: VibrationBlocks,
        rebounds: Sequence[tuple[float, np.ndarray]],
        end_of_data: bool = False,
        points: Sequence[tuple[float, str, np.ndarray]] = (),
    ) -> list[Label]:
        """Admit what arrived (all of it at wall clock ``now_s``); the labels of what is now
        decided (with ``end_of_data``, of everything pending): :meth:`admit` then
        :meth:`decide`."""
        labels = self.admit(now_s, arrivals, blocks, rebounds, points)
        return labels + self.decide(now_s, end_of_data)

    def admit(
        self,
        arrived_s: float,
        arrivals: Streams,
        blocks: VibrationBlocks,
        rebounds: Sequence[tuple[float, np.ndarray]],
        points: Sequence[tuple[float, str, np.ndarray]] = (),
    ) -> list[Label]:
        """Admit what arrived, the newest of it at wall clock ``arrived_s`` (its hold of
        ``reorder_s`` counts from then); ``points``: impact points, (stamp s, frame_id, (x, y,
        z) m). Returns the labels decided by a time jump it found (what was pending in the old
        time base), else none: :meth:`decide` gives the rest."""
        labels: list[Label] = []
        later: Streams = {}  # what belongs to a new time base
        for name, (stamps, values) in arrivals.items():
            cut = self.gate.add(name, stamps, values, arrived_s) if stamps.size else None
            if cut is not None:
                later[name] = (stamps[cut:], values[cut:])
        self._admit_blocks(self._sort_blocks(blocks, arrived_s), arrived_s)
        stale_s = self.gate.released_s - self.gate.config.time_jump_s
        back = self._track_back(arrived_s)
        if later or back is not None:  # stamps went back: decide the old time base, start afresh
            if later:
                name = next(iter(later))
                back_to = float(later[name][0][0])
            else:
                name, back_to = "vibration", back.held[0].stamp_s[0]  # type: ignore[union-attr]
            from_s = self.gate.streams[name].latest_s
            for stamp, velocity in rebounds:
                if stamp >= stale_s:
                    self.gate.add_rebound(stamp, velocity, arrived_s)
            for stamp, frame_id, point in points:
                if stamp >= stale_s:
                    self.gate.add_point(stamp, frame_id, point, arrived_s)
            labels += self._restart(
                arrived_s,
                f"{name} stamps went back from {from_s:.4f} s to {back_to:.4f} s "
                "(a simulator restarted or a replay looped)",
            )
            for name, (stamps, values) in later.items():
                self.gate.add(name, stamps, values, arrived_s)
            self._take_track(back, arrived_s)
            rebounds = [r for r in rebounds if r[0] < stale_s]
            points = [p for p in points if p[0] < stale_s]
        else:
            self._follow_other_track(arrived_s)
        for stamp, velocity in rebounds:
            self.gate.add_rebound(stamp, velocity, arrived_s)
        for stamp, frame_id, point in points:
            self.gate.add_point(stamp, frame_id, point, arrived_s)
        if self.gate.forward_jump(arrived_s, self._held_ahead(arrived_s)):
            aside = self.gate.take_aside()
            aside_rebounds = self.gate.take_aside_rebounds()
            labels += self._restart(
                arrived_s,
                f"every stream's stamps moved ahead by more than {self.gate.config.time_jump_s:g} "
                "s",
            )
            for name, (stamps, values) in aside.items():
                self.gate.add(name, stamps, values, arrived_s)
            for stamp, velocity in aside_rebounds:
                self.gate.add_rebound(stamp, velocity, arrived_s)
            self._take_track(None, arrived_s)
        self._note_counts()
        return labels

    # ---- vibration block streams ---------------------------------------------------------
    def _sort_blocks(self, blocks: VibrationBlocks, now_s: float) -> VibrationBlocks:
        """The blocks (in arrival order) of the stream in use, at its period; the others are
        set aside on the track they continue (a new one if none), counted by reason and noted.
        The first block of all starts the stream in use."""
        if not blocks.count:
            return blocks
        jump_s = self.gate.config.time_jump_s
        self.gate.streams["vibration"].last_seen_s = now_s
        keep = np.zeros(blocks.count, dtype=bool)
        apart: dict[str, int] = {}
        for b in range(blocks.count):
            first, length = int(blocks.first_index[b]), int(blocks.lengths[b])
            stamp, period = float(blocks.stamp_s[b]), blocks.period_s
            main = self.vibration_track
            if main is None:
                main = self.vibration_track = BlockTrack(first, stamp, period, now_s, now_s)
            if main.continues(first, length, stamp, period, jump_s):
                main.extend(first, length, stamp, now_s)
                keep[b] = True
                continue
            if main.same_period(period):
                why = "not the stream in use (index and stamp of another source)"
            else:
                why = f"sample period {period:g} s, not the stream's {main.period_s:g} s"
            apart[why] = apart.get(why, 0) + 1
            self._hold_apart(blocks.select(np.arange(blocks.count) == b), now_s)
        if apart:
            for why, n in apart.items():
                self.stray_blocks[why] = self.stray_blocks.get(why, 0) + n
            main = self.vibration_track
            said = "; ".join(f"{n} {why}" for why, n in apart.items())
            self.notes.append(
                f"vibration: {sum(apart.values())} block(s) set aside: {said} (the stream in "
                f"use is at index {main.next_index}, stamp {main.next_stamp_s:.6f} s); "
                f"{sum(self.stray_blocks.values())} set aside in all"
            )
        taken = blocks.select(keep)
        return dataclasses.replace(taken, period_s=self.vibration_track.period_s)

    def _hold_apart(self, block: VibrationBlocks, now_s: float) -> None:
        """One block not of the stream in use onto the other track it continues (bounded)."""
        first, length = int(block.first_index[0]), int(block.lengths[0])
        stamp, period = float(block.stamp_s[0]), block.period_s
        jump_s = self.gate.config.time_jump_s
        track = next(
            (t for t in self.other_tracks if t.continues(first, length, stamp, period, jump_s)),
            None,
        )
        if track is None:
            if len(self.other_tracks) >= MAX_OTHER_TRACKS:
                self.other_tracks.remove(min(self.other_tracks, key=lambda t: t.last_arrival_s))
            track = BlockTrack(first, stamp, period, now_s, now_s)
            self.other_tracks.append(track)
        track.extend(first, length, stamp, now_s)
        track.held.append(block)
        track.held_samples += block.sample_count
        while track.held_samples > MAX_ASIDE_SAMPLES // MAX_OTHER_TRACKS:
            track.held_samples -= track.held.pop(0).sample_count

    def _successor(self, now_s: float) -> BlockTrack | None:
        """The other track to take, once the stream in use has sent nothing for stream_idle_s
        (wall) while it went on: the one of most blocks among those still talking."""
        idle_s = self.gate.config.stream_idle_s
        self.other_tracks = [
            t for t in self.other_tracks if now_s - t.last_arrival_s <= 2.0 * idle_s
        ]
        main = self.vibration_track
        if main is None or now_s - main.last_arrival_s <= idle_s:
            return None
        talking = [
            t
            for t in self.other_tracks
            if t.held and t.blocks >= 2 and now_s - t.last_arrival_s <= idle_s
        ]
        return max(talking, key=lambda t: t.blocks, default=None)

    def _track_back(self, now_s: float) -> BlockTrack | None:
        """The successor track when it is stamped more than time_jump_s behind the stream in
        use (a new time base), else None."""
        track = self._successor(now_s)
        main = self.vibration_track
        if track is None or main is None:
            return None
        jump_s = self.gate.config.time_jump_s
        return track if track.held[0].stamp_s[0] < main.next_stamp_s - jump_s else None

    def _follow_other_track(self, now_s: float) -> None:
        """Take the successor track in the same time base (a replaced source: its index
        followed afresh)."""
        track = self._successor(now_s)
        if track is not None:
            self.sequencer.restart()
            self.vibration_track = None
            self._take_track(track, now_s)

    def _held_ahead(self, now_s: float) -> dict[str, float]:
        """{"vibration": wall clock s its first block held far ahead arrived} when another
        track is stamped more than time_jump_s ahead of the stream in use, else {}."""
        main = self.vibration_track
        if main is None:
            return {}
        jump_s = self.gate.config.time_jump_s
        ahead = [
            t.first_arrival_s
            for t in self.other_tracks
            if t.held and t.held[0].stamp_s[0] > main.next_stamp_s + jump_s
        ]
        return {"vibration": min(ahead)} if ahead else {}

    def _take_track(self, track: BlockTrack | None, now_s: float) -> None:
        """After a restart (the stream in use forgotten): the blocks of ``track`` (None: of the
        other track nearest the new time base, the most blocks when there is nothing to compare
        with) become the stream in use."""
        if track is None:
            candidates = [t for t in self.other_tracks if t.held]
            if not candidates:
                return
            reference = self.gate._reference_s("vibration", now_s)
            if math.isfinite(reference):
                track = min(candidates, key=lambda t: abs(t.held[0].stamp_s[0] - reference))
            else:
                track = max(candidates, key=lambda t: t.blocks)
        self.other_tracks.remove(track)
        self.taken_over += 1
        for block in track.held:
            self._admit_blocks(self._sort_blocks(block, now_s), now_s)

    def decide(self, now_s: float, end_of_data: bool = False) -> list[Label]:
        """Release what has been held ``reorder_s`` by wall clock ``now_s`` to the identifier; the
        labels it now decides (with ``end_of_data``, of everything pending)."""
        labels = self._decide(now_s, everything=end_of_data)
        self._calibrate()
        return labels

    def next_horizon_s(self) -> float:
        """Stamp every stream must pass before the next pending impact can be decided, s (inf:
        none pending): :meth:`StreamIdentifier.next_horizon_s`."""
        return self.identifier.next_horizon_s()

    def _calibrate(self) -> None:
        """Advance the online calibration; once it found a profile, decide with it."""
        if self.calibration is None or self._profile is not None:
            return
        note = self.calibration.poll()
        if note:
            self.notes.append(note)
        result = self.calibration.result
        if result is not None and result.model_params is not None:
            self._profile = (result.model_params, result.method)
            self.identifier.recalibrate(*self._profile)

    def _restart(self, now_s: float, why: str) -> list[Label]:
        """Decide everything of the old time base; then a fresh identifier and gate."""
        labels = self._decide(now_s, everything=True)
        self.notes.append(
            f"time jump: {why}; decided what was pending ({len(labels)} labels), identifying "
            "afresh"
        )
        self.time_jumps += 1
        self._counts_before = self.count_totals()
        self._refused_before += sum(self.identifier.refused_samples.values())
        for reason, n in self.identifier.refused_points.items():
            self._points_before[reason] = self._points_before.get(reason, 0) + n
        self.identifier = self._new_identifier(self.identifier.method)
        if self.calibration is not None:
            # A new time base may be another support (a restarted simulator with another
            # scene, a replayed recording): what was learned is dropped and learned afresh.
            learned = self._profile is not None or self.calibration.state != "learning"
            self._profile = None
            self.calibration.restart()
            if learned:
                self.notes.append(
                    "calibration: a new time base; the learned profile dropped, learning again "
                    f"from its first {self.calibration.learn_s:g} s (labels say calibrated: "
                    "false until then)"
                )
        self._gate_points_before += self.gate.counts.refused_points
        self.gate = ArrivalGate(self.gate.config)
        self.sequencer.restart()
        self.vibration_track = None
        return labels

    def _admit_blocks(self, blocks: VibrationBlocks, now_s: float) -> None:
        """Vibration blocks of the stream in use into running-index order (gaps and late blocks
        noted), then the gate."""
        if not blocks.count:
            return
        report = self.sequencer.push(blocks)
        if report.gaps:
            accepted = report.accepted
            resumes = dict(zip(accepted.first_index.tolist(), accepted.stamp_s.tolist()))
            for first_missing, n in report.gaps:
                after_s = resumes.get(first_missing + n)
                if after_s is not None:
                    self.vibration_gaps.append((after_s - n * accepted.period_s, after_s, n))
            missing = sum(n for _, n in report.gaps)
            self.notes.append(
                f"vibration: {len(report.gaps)} gap(s), {missing} samples lost (first missing "
                "index "
                f"{report.gaps[0][0]}); {self.sequencer.lost_samples} lost in all"
            )
        if report.late:
            self.notes.append(
                f"vibration: {report.late} block(s) arrived after a later one and were refused; "
                f"{self.sequencer.late_blocks} in all"
            )
        if report.misindexed:
            self.notes.append(
                f"vibration: {report.misindexed} block(s) refused whose running index (angle_min, "
                "angle_max) "
                "is behind the samples already used while their stamps are not: the publisher's "
                "index must "
                f"count the samples (docs/interface.md); {self.sequencer.misindexed_blocks} in all"
            )
        if report.accepted.count:
            accepted = report.accepted
            self.gate.add(
                "vibration",
                accepted.sample_stamps_s(),
                accepted.accel_mps2.astype(float).reshape(-1, 1),
                now_s,
            )

    def _decide(self, now_s: float, everything: bool) -> list[Label]:
        """Feed the identifier what the gate releases; its labels (all pending with
        ``everything``)."""
        release = self.gate.release(now_s, everything=everything)
        if self.calibration is not None:
            self.calibration.record(release)
        feed(self.identifier, release)
        refused = self._refused_before + sum(self.identifier.refused_samples.values())
        if refused > self._refused_noted:
            self._refused_noted = refused
            counts = ", ".join(
                f"{name} {n}" for name, n in self.identifier.refused_samples.items() if n
            )
            self.notes.append(
                f"identification: {refused} sample(s) with a non-finite stamp or value left out "
                "(totals; "
                f"this epoch: {counts})"
            )
        labels = self.identifier.poll()
        if everything:
            labels += self.identifier.flush()
        self._note_points()
        empty = [label for label in labels if not label.signals]
        if empty:  # a label must rest on some signal; published from nothing it would mislead
            self.empty_labels += len(empty)
            self.notes.append(
                f"identification: {len(empty)} label(s) resting on no signal dropped; "
                f"{self.empty_labels} in all"
            )
            labels = [label for label in labels if label.signals]
        return labels

    @property
    def refused_points(self) -> dict[str, int]:
        """impact_point messages refused or set aside by the identifiers of every epoch, by
        reason (``field = value: what is allowed``, or no rebound at its stamp), and by the
        gate (stamped out of the streams' time)."""
        totals = dict(self._points_before)
        for reason, n in self.identifier.refused_points.items():
            totals[reason] = totals.get(reason, 0) + n
        if self.gate_refused_points:
            totals[POINT_OUT_OF_TIME] = self.gate_refused_points
        return totals

    @property
    def gate_refused_points(self) -> int:
        return self.gate.counts.refused_points + self._gate_points_before

    def _note_points(self) -> None:
        """Note the impact_point messages refused or set aside since the last note, by reason
        (at most MAX_POINT_REASONS named)."""
        totals = self.refused_points
        total = sum(totals.values())
        if total <= self._points_noted:
            return
        self._points_noted = total
        reasons = sorted(totals.items(), key=lambda item: -item[1])
        shown = "; ".join(f"{n} {reason}" for reason, n in reasons[:MAX_POINT_REASONS])
        more = len(reasons) - MAX_POINT_REASONS
        self.notes.append(
            f"impact_point: {total} message(s) refused or set aside in all: {shown}"
            + (f"; and {more} more reason(s)" if more > 0 else "")
        )

    def count_totals(self) -> tuple[int, int, int, int]:
        """What the gates of every epoch refused or set aside: repeated samples, samples ahead,
        of those dropped, rebounds out of the streams' time."""
        c = self.gate.counts
        now = (c.repeated_samples, c.ahead_samples, c.ahead_dropped, c.refused_rebounds)
        return tuple(a + b for a, b in zip(now, self._counts_before))  # type: ignore[return-value]

    def _note_counts(self) -> None:
        total = self.count_totals()
        if total != self._counts_noted:
            self._counts_noted = total
            self.notes.append(
                f"arrival: {total[0]} repeated or out-of-order samples refused, {total[1]} "
                "samples stamped more than "
                f"{self.gate.config.time_jump_s:g} s ahead of the other streams ({total[2]} of "
                "them dropped), "
                f"{total[3]} rebounds refused (not finite, or stamped out of the streams' time) "
                "(totals)"
            )
