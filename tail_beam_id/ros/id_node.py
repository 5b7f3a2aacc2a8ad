"""``id_node``: a ROS 2 node over :class:`tail_beam_id.stream.identifier.StreamIdentifier`.

Subscribes to ``jack_pressure``, ``imu``, ``vibration``, ``rebound_velocity`` and, when the
camera reports it, ``impact_point`` (never ``impact_truth``), buffers what arrives, and every
``poll_period_s`` puts it in stamp order through an
:class:`tail_beam_id.ros.arrival.ArrivalGate`, hands the identifier what every live
stream has passed, and publishes its labels on ``label``. The identifier thus sees the streams
as ``tail-beam identify`` sees them in a bag, whatever order and pace the middleware delivers
them in: live and offline labels agree. When no sensor message has come for
``flush_after_idle_s`` (the data ended, or every stream stopped) the pending impacts are
decided from what there is. A time jump (stamps going back: a restarted simulator, a looped
replay; every stream ahead at once) is logged, what was pending is decided, and identification
starts afresh; a lone message stamped far ahead is set aside and counted, never let poison the
streams. Spun by ``rclpy.experimental.EventsExecutor``, which keeps up with thousands of
messages per second where the default executor loses some.

The flow's gangue share per sliding interval goes out on ``gangue_share``
(:mod:`tail_beam_id.stream.share_reader`): from the same data in the same order, so live and
offline shares agree too.

Each message is held ``reorder_s`` from its own arrival (wall clock), not from the tick that
takes it. Besides the periodic tick, a one-shot wake runs a tick ``reorder_s`` after the data
the next pending impact waits for (its onset plus its data window, on every stream) has
arrived, so that a label does not wait for the next period.

The ``vibration`` blocks are decoded with numpy and kept in running-index order by a
:class:`tail_beam_sim.physics.sensors.BlockSequencer`: a jump in the index is a lost block,
logged with the count of samples missing; a block that comes after a later one was handed on
is refused and counted (``vibration_lost_samples``, ``vibration_late_blocks``), and so is one
whose index is behind while its stamp is not, logged as an index that does not count the
samples (``vibration_misindexed_blocks``). Blocks of another source on the topic (a stray
block stamped far ahead, a second publisher's interleaved stream, a block of another sample
period) are set aside and counted (``vibration_stray_blocks``), never let move the stream in
use (tail_beam_id.ros.arrival).

The sensor topics are subscribed with the reliability their publishers offer
(tail_beam_sim.ros.follow_qos): best effort from a paced sim_node, whose slow readers cannot
hold it or the other readers up, reliable from an as-fast-as-possible one. What this node loses
is counted from the data itself, whatever the middleware says (a reader's overflowing history is
reported by no DDS event): pressure and IMU samples missing from their stamp grid
(tail_beam_sim.ros.grid_gaps; ``lost_samples``) and vibration samples missing from the running
index. Each gap is warned of (rate-limited), and a label whose data window (``window_s`` either
side of its impact stamp) holds a gap says so: ``gaps``, samples missing per stream, and a
warning; it is still published, since an impact left unlabelled would be worse than one
labelled from data with a hole that the label names. An impact found inside a vibration gap
or within GAP_ONSET_S after one is not labelled but counted undecided and warned of: the jump
where the accelerometer's samples resume can itself look like an onset. Warnings of one kind
are said at most every WARN_EVERY_S: the first at once, then the latest with the count held back.
"""

from __future__ import annotations

import bisect
import dataclasses
import math
import re
import sys
import time

import numpy as np
from geometry_msgs.msg import PointStamped, TwistStamped
from rclpy.node import Node
from sensor_msgs.msg import FluidPressure, Imu, LaserScan
from std_msgs.msg import String

from tail_beam_id.calibration.online import OnlineCalibration
from tail_beam_id.caving.controller import CAVING_NODE
from tail_beam_id.methods import Method
from tail_beam_id.methods.physics import PHYSICS
from tail_beam_id.methods.statistical import HYSTERESIS, STATISTICAL
from tail_beam_id.methods.threshold import THRESHOLD
from tail_beam_id.ros.arrival import ID_NODE, GateConfig, GatedIdentifier
from tail_beam_id.signals.contact_fit import CONTACT_FIT
from tail_beam_id.signals.imu_detection import DETECTION
from tail_beam_id.signals.timing import SENSOR_TIMING
from tail_beam_id.stream.config import EVALUATION, IDENTIFICATION, PROFILE
from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.label import Label, Revisions, match_tolerance_s
from tail_beam_id.stream.share import GANGUE_SHARE
from tail_beam_id.stream.share_reader import SharingIdentifier
from tail_beam_sim import topics
from tail_beam_sim.ros import messages as ros_messages
from tail_beam_sim.ros.follow_qos import FollowingSubscription, follow_publishers
from tail_beam_sim.ros.grid_gaps import GridGaps
from tail_beam_sim.ros.params import (
    ALL_PARAMETERS,
    config_defaults,
    declare_and_read,
    refuse_runtime_changes,
)
from tail_beam_sim.ros.spin import ForeignTypeWatch, run_node
from tail_beam_sim.spec import Section, text

# An impact found but not decided this long (wall clock, s) after it was first seen pending is
# logged and counted (``undecided_impacts``): a stream it waits for is late or gone.
UNDECIDED_AFTER_S = 2.0
# Data arriving this much later than the earliest delivery seen in the time base (wall clock
# minus stamp, s) is id_node behind real time: warned at most every LAG_WARN_PERIOD_S.
LAG_WARN_S = 0.25
LAG_WARN_PERIOD_S = 5.0
MAX_REASONS = 5  # distinct reasons for refused vibration messages named in one log line
# An impact found in a gap or this soon after one (its resuming samples) is not labelled, s.
GAP_ONSET_S = 0.005
GAPS_KEPT = 1000  # pressure and IMU gaps remembered for checking labels against, count
WARN_EVERY_S = 5.0  # wall s between two warnings of one kind (the first at once, then a count)
GANGUE_SHARE_TOPIC = "gangue_share"  # std_msgs/String JSON (docs/gangue_share.md)
WAKE_MARGIN_S = (
    2e-4  # the wake runs this long after the hold has passed, s (a timer may fire a little early)
)


ID_NODE_TOP = Section(
    "",
    "Top-level parameters of id_node.",
    (text("method", 'Identification method ("" = identification.method).'),),
    file="id_node.yaml",
)

# The identifier's parameter sections, each declared where it is read: the reference page is
# ``python -m tail_beam_sim.spec tail_beam_id.ros.id_node > docs/parameters.md``.
PARAMETER_SECTIONS = (
    ID_NODE_TOP,
    ID_NODE,
    IDENTIFICATION,
    PROFILE,
    SENSOR_TIMING,
    CONTACT_FIT,
    DETECTION,
    EVALUATION,
    GANGUE_SHARE,
    STATISTICAL,
    HYSTERESIS,
    THRESHOLD,
    PHYSICS,
    CAVING_NODE,
)


class Inbox:
    """The messages of one topic since the last tick, each with its wall-clock arrival time (s)."""

    def __init__(self) -> None:
        self.messages: list = []
        self.arrived_s: list[float] = []

    def put(self, message: object, now_s: float) -> None:
        self.messages.append(message)
        self.arrived_s.append(now_s)

    def take(self, cutoff_s: float) -> tuple[tuple[list, float], tuple[list, float]]:
        """Empty the inbox: (messages arrived by ``cutoff_s``, the newest one's arrival s), then
        (the later ones, the newest one's arrival s); -inf for an empty part."""
        k = bisect.bisect_right(self.arrived_s, cutoff_s)
        times, messages = self.arrived_s, self.messages
        self.messages, self.arrived_s = [], []
        return (messages[:k], times[k - 1] if k else -math.inf), (
            messages[k:],
            times[-1] if k < len(times) else -math.inf,
        )


class Warnings:
    """Warnings of one kind (the text with its numbers left out) said at most once every
    WARN_EVERY_S of wall time: the first at once, then the latest with how many were held back,
    so that a flood of refused messages costs a line every few seconds, not a line each."""

    def __init__(self, say) -> None:
        self._say = say  # callable taking one line
        self._last_s: dict[str, float] = {}  # kind -> wall s it was last said
        self._held: dict[str, tuple[int, str]] = {}  # kind -> (held back, the latest text)

    def warn(self, line: str, now_s: float) -> None:
        kind = re.sub(r"\d+(\.\d+)?(e[-+]?\d+)?", "#", line)[:60]
        if now_s - self._last_s.get(kind, -math.inf) >= WARN_EVERY_S:
            self._last_s[kind] = now_s
            self._say(line)
        else:
            self._held[kind] = (self._held.get(kind, (0, ""))[0] + 1, line)

    def flush(self, now_s: float) -> None:
        """Say what was held back of each kind whose period has passed."""
        for kind, (n, line) in list(self._held.items()):
            if now_s - self._last_s[kind] >= WARN_EVERY_S:
                del self._held[kind]
                self._last_s[kind] = now_s
                self._say(f"{line} [{n} warning(s) of this kind in the last {WARN_EVERY_S:g} s]")


class IdNode(Node):
    """Labels each impact in the sensor streams coal or gangue."""

    def __init__(self, **kwargs) -> None:
        super().__init__("tail_beam_id", **kwargs)
        # Its exit line names the namespace (several supports may share a process); read now,
        # while the context is valid: a stop signal shuts it down before close().
        ns = self.get_namespace()
        self.exit_name = "id_node" if ns == "/" else f"id_node {ns}"
        # A support profile (tail-beam calibrate --out) brings its `calibration` section: what
        # makes
        # the identifier decide as calibrated, as `tail-beam identify --config profile.yaml` does.
        params = declare_and_read(
            self,
            config_defaults(["id_node.yaml"], with_physics=True),
            open_sections=("calibration",),
        )
        node = params["id_node"]
        checked = ID_NODE.check(node)
        period = checked["poll_period_s"]
        self.flush_after_idle_s = checked["flush_after_idle_s"]
        depth = checked["qos_depth"]
        method = params.get("method") or None

        def new_identifier(trained: Method | None) -> StreamIdentifier:
            made = SharingIdentifier(
                method, params=params["identification"], model_params=params, prebuilt=trained
            )
            self._sharing.append(made)
            return made

        # The identifiers whose gangue shares are still to publish (a time jump starts a new
        # one; the old one's last shares go out first).
        self._sharing: list[SharingIdentifier] = []

        learn_s = checked["calibrate_online_s"]
        calibration = None
        if learn_s > 0.0:
            calibration = OnlineCalibration(
                params, learn_s, method or params["identification"]["method"]
            )
        self.gated = GatedIdentifier(new_identifier, GateConfig.from_params(node), calibration)
        self._inbox = {
            topic: Inbox()
            for topic in (
                topics.JACK_PRESSURE,
                topics.IMU,
                topics.VIBRATION,
                topics.REBOUND_VELOCITY,
                topics.IMPACT_POINT,
            )
        }
        # Continuous topic -> (newest stamp arrived, its wall-clock arrival), s: the wake's test.
        self._newest: dict[str, tuple[float, float]] = {}
        self._due_s = (
            math.inf
        )  # stamp the next pending impact waits for (identifier.next_horizon_s), s
        self._timing_said: object | None = (
            None  # the identifier's timing check whose suspicion was logged
        )
        self._woken_for_s = math.nan  # the due stamp the last wake was for
        # wall clock the last wake ran, s (another for the same due only for data it could not
        # take)
        self._woke_s = -math.inf
        self._last_arrival_s = time.monotonic()
        self._unflushed = False
        self.received = {
            topics.JACK_PRESSURE: 0,
            topics.IMU: 0,
            topics.VIBRATION: 0,
            topics.REBOUND_VELOCITY: 0,
            topics.IMPACT_POINT: 0,
        }
        self.published = 0
        # One impact, one label (tail_beam_id.stream.label.Revisions): later decisions for an
        # impact already labelled go out as revisions of it.
        self.revisions = Revisions(match_tolerance_s(params["identification"]))
        self.undecided_impacts = 0  # impacts pending longer than UNDECIDED_AFTER_S
        self._pending_since: dict[float, float] = {}  # pending impact onset -> first seen, wall s
        self._overdue: set[float] = set()  # onsets already reported as undecided
        self.lag_s = 0.0  # how far behind real time the data arrives now, s
        self.max_lag_s = 0.0
        self._lag_base_s = math.inf  # least (arrival wall clock - stamp) of this time base, s
        self._lag_warned_s = -math.inf
        # vibration messages that carried no block (their index, period or range out of range)
        self.refused_blocks = 0
        self.warnings = Warnings(self.get_logger().warning)
        event_qos = ros_messages.EVENT_QOS
        self._label_pub = self.create_publisher(
            String, topics.LABEL, ros_messages.EVENT_PUBLISHER_QOS
        )
        self.shares_published = 0
        self._share_pub = self.create_publisher(
            String, GANGUE_SHARE_TOPIC, ros_messages.EVENT_PUBLISHER_QOS
        )
        # Sensor topics with their publishers' reliability; losses counted from the data.
        self.grid_gaps = {topics.JACK_PRESSURE: GridGaps(), topics.IMU: GridGaps()}
        self._gaps: list[tuple[str, float, float, int]] = []  # (stream, from s, to s, missing)
        self._gap_window_s = float(params["identification"]["window_s"])
        self.gapped_labels = 0  # labels whose data window holds a gap
        self.gap_onsets = 0  # impacts found at a gap, not labelled (counted undecided)
        self.sensor_subscriptions = [
            FollowingSubscription(self, kind, topic, callback, depth)
            for kind, topic, callback in (
                (FluidPressure, topics.JACK_PRESSURE, self._on_pressure),
                (Imu, topics.IMU, self._on_imu),
                (LaserScan, topics.VIBRATION, self._on_vibration),
            )
        ]
        follow_publishers(self, self.sensor_subscriptions)
        self.create_subscription(
            TwistStamped, topics.REBOUND_VELOCITY, self._on_rebound, event_qos
        )
        self.create_subscription(PointStamped, topics.IMPACT_POINT, self._on_point, event_qos)
        self._foreign = ForeignTypeWatch(
            self, {topic: topics.MSG_TYPES[topic] for topic in self._inbox}
        )
        self.create_timer(period, self._tick)
        self._wake = self.create_timer(
            self.gated.gate.config.reorder_s + WAKE_MARGIN_S, self._on_wake
        )
        self._wake.cancel()
        refuse_runtime_changes(
            self,
            ALL_PARAMETERS,
            "id_node reads its parameters at start-up only (restart it to change them)",
        )
        self.get_logger().info(f"identifying with method {self.identifier.method.name}")
        if self.identifier.calibrated:
            self.get_logger().info(
                "deciding with the support profile given (its calibration section): labels say "
                "calibrated: true"
            )
        if calibration is not None:
            self.get_logger().info(
                f"calibration: learning the support from the first {learn_s:g} s of data "
                "(labels say calibrated: false until then)"
            )

    def _arrived(self, topic: str, message: object, last_stamp_s: float | None = None) -> None:
        """Keep a message with its arrival time; for a continuous topic (``last_stamp_s``: its
        newest sample's stamp) arm the wake once every stream has passed the due stamp."""
        now = time.monotonic()
        self._inbox[topic].put(message, now)
        self.received[topic] += 1
        self._last_arrival_s = now
        self._unflushed = True
        if last_stamp_s is None:
            return
        if last_stamp_s > self._newest.get(topic, (-math.inf, 0.0))[0]:
            self._newest[topic] = (last_stamp_s, now)
        if last_stamp_s >= self._due_s:
            self._arm_wake()

    def _arm_wake(self) -> None:
        """Start the one-shot wake if every live stream (one heard from within stream_idle_s)
        has passed the due stamp, and no wake for it ran or data came that the last one could
        not take (not yet held reorder_s when it ran): the impact may still wait on a stream
        the identifier sees lag only in that data (an IMU that stopped)."""
        due = self._due_s
        held_by_wake_s = self._woke_s - self.gated.gate.config.reorder_s
        if not self._wake.is_canceled() or (
            due == self._woken_for_s and self._last_arrival_s <= held_by_wake_s
        ):
            return
        live_after_s = time.monotonic() - self.gated.gate.config.stream_idle_s
        live = [stamp for stamp, arrived in self._newest.values() if arrived >= live_after_s]
        if live and min(live) >= due:
            self._woken_for_s = due
            self._wake.reset()

    def _on_wake(self) -> None:
        self._wake.cancel()
        self._woke_s = time.monotonic()
        self._tick()

    def _on_pressure(self, msg: FluidPressure) -> None:
        self._arrived(topics.JACK_PRESSURE, msg, ros_messages.stamp_s(msg.header.stamp))

    def _on_imu(self, msg: Imu) -> None:
        self._arrived(topics.IMU, msg, ros_messages.stamp_s(msg.header.stamp))

    def _on_vibration(self, msg: LaserScan) -> None:
        increment = msg.time_increment
        last = ros_messages.stamp_s(msg.header.stamp) + (
            increment * (len(msg.ranges) - 1)
            if math.isfinite(increment) and increment > 0.0
            else 0.0
        )
        self._arrived(topics.VIBRATION, msg, last)

    def _on_rebound(self, msg: TwistStamped) -> None:
        self._arrived(topics.REBOUND_VELOCITY, msg)

    def _on_point(self, msg: PointStamped) -> None:
        self._arrived(topics.IMPACT_POINT, msg)

    @property
    def refused_points(self) -> dict[str, int]:
        """impact_point messages refused or set aside, by reason (every epoch's)."""
        return self.gated.refused_points

    def _count_gaps(self, topic: str, stamps: np.ndarray) -> None:
        """Count and remember the samples missing from ``topic``'s stamp grid."""
        grid = self.grid_gaps[topic]
        gaps = grid.add(stamps.tolist())
        if not gaps:
            return
        self._gaps.extend((topic, a, b, n) for a, b, n in gaps)
        del self._gaps[:-GAPS_KEPT]
        self.warnings.warn(
            f"{topic}: {sum(n for *_, n in gaps)} sample(s) missing from the stamp grid "
            f"(first after {gaps[0][0]:.4f} s); {grid.lost_samples} lost in all",
            time.monotonic(),
        )

    @property
    def lost_samples(self) -> dict[str, int]:
        """Samples this node lost, per sensor stream: pressure and IMU from their stamp grid,
        vibration from the running index."""
        return {
            topics.JACK_PRESSURE: self.grid_gaps[topics.JACK_PRESSURE].lost_samples,
            topics.IMU: self.grid_gaps[topics.IMU].lost_samples,
            topics.VIBRATION: self.vibration_lost_samples,
        }

    def loss_report(self) -> str:
        """One line: what this node lost of each sensor stream, and the labels it concerned."""
        lost = ", ".join(f"{topic} {n}" for topic, n in self.lost_samples.items())
        return (
            f"samples lost: {lost}; {self.gapped_labels} label(s) from data with a gap, "
            f"{self.gap_onsets} impact(s) found at a gap not labelled; "
            f"{self.undecided_impacts} impact(s) not decided in time"
        )

    def close(self) -> None:
        """Say on the way out what was lost of the sensor streams."""
        print(
            f"{self.exit_name}: {self.published} labels published; {self.loss_report()}",
            file=sys.stderr,
        )

    def _gaps_near(self, stamp_s: float) -> dict[str, int]:
        """Samples missing per stream within ``window_s`` of ``stamp_s``."""
        near: dict[str, int] = {}
        lo, hi = stamp_s - self._gap_window_s, stamp_s + self._gap_window_s
        vibration = [(topics.VIBRATION, a, b, n) for a, b, n in self.gated.vibration_gaps]
        for topic, a, b, n in self._gaps + vibration:
            if a < hi and b > lo:
                near[topic] = near.get(topic, 0) + n
        return near

    @property
    def vibration_lost_samples(self) -> int:
        return self.gated.sequencer.lost_samples

    @property
    def vibration_late_blocks(self) -> int:
        return self.gated.sequencer.late_blocks

    @property
    def vibration_misindexed_blocks(self) -> int:
        """Blocks refused whose index is behind the stream's while their stamps are not."""
        return self.gated.sequencer.misindexed_blocks

    @property
    def vibration_stray_blocks(self) -> int:
        """Blocks set aside as not the vibration stream in use (another source, another
        sample period)."""
        return sum(self.gated.stray_blocks.values())

    @property
    def identifier(self) -> StreamIdentifier:
        return self.gated.identifier

    def _admit(self, part: dict[str, list], arrived_s: float) -> list[Label]:
        """Hand the gated identifier one batch of messages (the newest arrived at
        ``arrived_s``)."""
        arrivals: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        if part[topics.JACK_PRESSURE]:
            stamps, pressure = ros_messages.pressure_arrays(part[topics.JACK_PRESSURE])
            arrivals[topics.JACK_PRESSURE] = (stamps, pressure.reshape(-1, 1))
            self._count_gaps(topics.JACK_PRESSURE, stamps)
        if part[topics.IMU]:
            stamps, gyro, accel = ros_messages.imu_arrays(part[topics.IMU])
            arrivals[topics.IMU] = (stamps, np.hstack([gyro, accel]))
            self._count_gaps(topics.IMU, stamps)
        refused: list[str] = []
        # One decoding per sample period, the most common first: a message of another period
        # is then a block the gated identifier sets aside, not a cause to refuse the others.
        by_period: dict[float, list[LaserScan]] = {}
        for m in part[topics.VIBRATION]:
            by_period.setdefault(m.time_increment, []).append(m)
        groups = sorted(by_period.values(), key=len, reverse=True)
        decoded = [ros_messages.vibration_blocks(g, refused) for g in groups]
        if refused:
            self.refused_blocks += len(refused)
            reasons = list(dict.fromkeys(refused))  # each distinct reason once
            shown = "; ".join(reasons[:MAX_REASONS]) + (
                f"; and {len(reasons) - MAX_REASONS} more" if len(reasons) > MAX_REASONS else ""
            )
            self.warnings.warn(
                f"vibration: {len(refused)} message(s) refused: {shown} ({self.refused_blocks} "
                "refused in all)",
                time.monotonic(),
            )
        rebounds = [ros_messages.rebound_values(m) for m in part[topics.REBOUND_VELOCITY]]
        points = [ros_messages.point_values(m) for m in part[topics.IMPACT_POINT]]
        first = decoded[0] if decoded else ros_messages.vibration_blocks([])
        labels = self.gated.admit(arrived_s, arrivals, first, rebounds, points)
        for blocks in decoded[1:]:
            labels += self.gated.admit(arrived_s, {}, blocks, [])
        return labels

    def _tick(self) -> None:
        """Hand the gated identifier what arrived, in two batches (held long enough by now, and
        not yet); publish the labels it decides; arm the wake for the next pending impact."""
        now = time.monotonic()
        parts: tuple[dict[str, list], dict[str, list]] = ({}, {})
        arrived_s = [-math.inf, -math.inf]
        for topic, inbox in self._inbox.items():
            for k, (messages, newest_s) in enumerate(
                inbox.take(now - self.gated.gate.config.reorder_s)
            ):
                parts[k][topic] = messages
                arrived_s[k] = max(arrived_s[k], newest_s)
        labels: list[Label] = []
        jumps = self.gated.time_jumps
        for part, batch_s in zip(parts, arrived_s):
            if batch_s > -math.inf:
                before = self.gated.time_jumps
                labels += self._admit(part, batch_s)
                if self.gated.time_jumps != before:  # those labels were the old time base's
                    self._publish(labels)
                    labels = []
                    self.revisions.restart()
        if (
            self.gated.time_jumps != jumps
        ):  # a new time base: the stamps seen so far say nothing of it
            self._newest.clear()
            self._gaps.clear()
            self._lag_base_s = math.inf
        idle = self._unflushed and now - self._last_arrival_s > self.flush_after_idle_s
        self._publish(labels + self.gated.decide(now, end_of_data=idle))
        if idle:
            self._unflushed = False
        for note in self.gated.notes:
            self.warnings.warn(note, now)
        self.gated.notes.clear()
        self.warnings.flush(now)
        timing = self.identifier.timing
        if timing.suspect and timing is not self._timing_said:
            self._timing_said = timing  # once per identifier (a new time base starts a new one)
            self.get_logger().warning(f"sensor timing: {timing.describe()}")
        self._publish_shares()
        self._watch_pending(now)
        self._watch_lag(now)
        self._due_s = self.gated.next_horizon_s()
        self._arm_wake()

    def _watch_pending(self, now: float) -> None:
        """Log and count each impact still undecided UNDECIDED_AFTER_S after it was found."""
        onsets = {impact.onset_s for impact in self.identifier.impacts.pending}
        for onset in onsets - self._pending_since.keys():
            self._pending_since[onset] = now
        for onset in list(self._pending_since):
            if onset not in onsets:
                del self._pending_since[onset]
                self._overdue.discard(onset)
            elif onset not in self._overdue and now - self._pending_since[onset] > (
                UNDECIDED_AFTER_S
            ):
                self._overdue.add(onset)
                self.undecided_impacts += 1
                waits = self.gated.next_horizon_s()
                self.get_logger().warning(
                    f"impact at {onset:.4f} s found but not decided {UNDECIDED_AFTER_S:g} s later "
                    f"(waiting for data up to {waits:.4f} s on every live stream); "
                    f"{self.undecided_impacts} impact(s) not decided in time in all"
                )

    def _watch_lag(self, now: float) -> None:
        """How much later than the earliest delivery of this time base the newest data arrived
        (wall clock minus stamp: a slow publisher, a held-up middleware or this node's own
        backlog); a warning at most every LAG_WARN_PERIOD_S while it exceeds LAG_WARN_S."""
        offsets = [arrived - stamp for stamp, arrived in self._newest.values()]
        if not offsets:
            return
        self._lag_base_s = min(self._lag_base_s, min(offsets))
        self.lag_s = max(offsets) - self._lag_base_s
        self.max_lag_s = max(self.max_lag_s, self.lag_s)
        fresh = max(arrived for _, arrived in self._newest.values()) > self._lag_warned_s
        if fresh and self.lag_s > LAG_WARN_S and now - self._lag_warned_s >= LAG_WARN_PERIOD_S:
            self._lag_warned_s = now
            self.get_logger().warning(
                f"behind real time by {self.lag_s:.3f} s (data arrives that much later than the "
                f"earliest delivery seen; at most {self.max_lag_s:.3f} s so far)"
            )

    def _at_a_gap(self, stamp_s: float) -> bool:
        """Whether ``stamp_s`` falls in a gap of the vibration stream or within GAP_ONSET_S
        after one: the jump where the accelerometer's samples resume can itself look like an
        impact's onset (a lost pressure or IMU sample cannot make one)."""
        return any(a <= stamp_s <= b + GAP_ONSET_S for a, b, _ in self.gated.vibration_gaps)

    def _publish(self, labels: list[Label]) -> None:
        for decided in labels:
            if decided.revises is None and self._at_a_gap(decided.impact_stamp_s):
                self.undecided_impacts += 1
                self.gap_onsets += 1
                self.get_logger().warning(
                    f"impact at {decided.impact_stamp_s:.4f} s found where samples are missing: "
                    "not labelled (its onset may be the gap itself); "
                    f"{self.undecided_impacts} impact(s) not decided in time in all"
                )
                continue
            label = self.revisions.admit(decided)
            gaps = self._gaps_near(label.impact_stamp_s)
            if gaps:
                self.gapped_labels += 1
                label = dataclasses.replace(label, extra={**label.extra, "gaps": gaps})
                self.get_logger().warning(
                    f"impact at {label.impact_stamp_s:.4f} s labelled from data with a gap "
                    f"(samples missing: {gaps}); {self.gapped_labels} such label(s) in all"
                )
            self._label_pub.publish(String(data=label.to_json()))
            self.published += 1
            what = "impact" if label.revises is None else "revised: impact"
            self.get_logger().info(
                f"{what} at {label.impact_stamp_s:.4f} s: {label.material} "
                f"({label.confidence:.2f}, {label.method}, "
                f"signals {', '.join(label.signals)})"
            )

    def _publish_shares(self) -> None:
        """Publish the gangue share of every interval settled since the last tick."""
        current = self.gated.identifier
        for sharing in self._sharing:
            for share in sharing.take_shares():
                self._share_pub.publish(String(data=share.to_json()))
                self.shares_published += 1
        self._sharing = [s for s in self._sharing if s is current]


def main(args: list[str] | None = None) -> int:
    """Run id_node until shut down."""
    return run_node(IdNode, "id_node", args)


if __name__ == "__main__":
    sys.exit(main())
