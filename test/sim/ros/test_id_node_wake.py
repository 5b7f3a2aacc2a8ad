"""id_node's wake: a label is decided once the data its impact waits for has arrived and been
held ``reorder_s``, not on the next periodic tick. Real rclpy nodes over the middleware."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from id_helpers import stream_chunk

from tail_beam_sim import topics

CONTACT_S = 0.3  # stamp of the one impact's contact, s
POLL_PERIOD_S = 3.0  # id_node's periodic tick, far longer than anything the wake waits for
IDLE_S = 0.5  # id_node.stream_idle_s when the IMU stops


def messages_between(chunk, lo_s: float, hi_s: float) -> list[tuple[str, object]]:
    """(topic, message) of the chunk's pressure, IMU and vibration samples stamped in (lo_s,
    hi_s] (a block by its first sample) in stamp order, then its rebounds in it."""
    from tail_beam_sim.ros import messages as ros_messages

    out = []
    for topic, stream, messages in (
        (
            topics.JACK_PRESSURE,
            chunk.pressure.stamp_s,
            ros_messages.pressure_messages(chunk.pressure),
        ),
        (topics.IMU, chunk.imu.stamp_s, ros_messages.imu_messages(chunk.imu)),
        (
            topics.VIBRATION,
            chunk.vibration.stamp_s,
            ros_messages.vibration_messages(chunk.vibration),
        ),
    ):
        out += [(stamp, topic, m) for stamp, m in zip(stream, messages) if lo_s < stamp <= hi_s]
    out.sort(key=lambda item: item[0])
    rebounds = [
        (topics.REBOUND_VELOCITY, ros_messages.rebound_message(r))
        for _, r in chunk.rebounds
        if lo_s < r.stamp_s <= hi_s
    ]
    return [(topic, m) for _, topic, m in out] + rebounds


@pytest.mark.ros
@pytest.mark.parametrize("imu_stops", [False, True])
def test_a_label_comes_when_its_data_is_in_not_on_the_next_periodic_tick(params, imu_stops):
    """A feeder sends the streams up to just after an impact's pulse, id_node's periodic tick
    (every 3 s here) finds the pulse, then the feeder sends the rest: the label comes well
    within a second of the rest, long before the next periodic tick. Before the wake it came
    with that tick (3 s). With ``imu_stops`` the rest has no IMU samples and comes after the
    IMU has been silent for stream_idle_s: a stream that stopped does not hold the wake back."""
    from geometry_msgs.msg import TwistStamped
    from rclpy.parameter import Parameter
    from rosprobe import Probe, ros_context, spin_for, spin_until
    from sensor_msgs.msg import FluidPressure, Imu, LaserScan
    from std_msgs.msg import String

    from tail_beam_id.ros.id_node import IdNode
    from tail_beam_sim.ros import messages as ros_messages

    chunk = stream_chunk(
        params,
        [
            (
                CONTACT_S,
                {
                    "material": "sandstone",
                    "radius_m": 0.06,
                    "drop_height_m": 2.0,
                    "position_m": 1.0,
                },
            )
        ],
        CONTACT_S + 0.1,
    )
    window_s = params["identification"]["vibration_window_s"]
    pulse_in_s = CONTACT_S + window_s - 0.0015  # the pulse is in, the data window is not
    first, rest = (
        messages_between(chunk, -math.inf, pulse_in_s),
        messages_between(chunk, pulse_in_s, math.inf),
    )
    types = {
        topics.JACK_PRESSURE: FluidPressure,
        topics.IMU: Imu,
        topics.VIBRATION: LaserScan,
        topics.REBOUND_VELOCITY: TwistStamped,
    }
    with ros_context() as (context, executor):
        ident = IdNode(
            context=context,
            namespace="/wake",
            parameter_overrides=[
                Parameter("method", value="statistical"),
                Parameter("id_node.poll_period_s", value=POLL_PERIOD_S),
                # the feeder pauses between its two sends: not the end of the data (nor, unless the
                # IMU stops, a stream stopped)
                Parameter("id_node.flush_after_idle_s", value=30.0),
                Parameter("id_node.stream_idle_s", value=IDLE_S if imu_stops else 30.0),
            ],
        )
        feeder = Probe(context, {topics.LABEL: String}, namespace="/wake", name="feeder")
        qos = {topics.REBOUND_VELOCITY: ros_messages.EVENT_QOS}
        pubs = {
            topic: feeder.create_publisher(
                kind, topic, qos.get(topic, ros_messages.stream_qos(10000))
            )
            for topic, kind in types.items()
        }
        for node in (ident, feeder):
            executor.add_node(node)
        assert spin_until(
            executor, lambda: all(p.get_subscription_count() >= 1 for p in pubs.values())
        )
        for topic, message in first:
            pubs[topic].publish(message)
        assert spin_until(
            executor, lambda: ident.gated.identifier.impacts.pending, timeout_s=3 * POLL_PERIOD_S
        )
        assert not feeder.messages[topics.LABEL]
        if imu_stops:
            rest = [(topic, m) for topic, m in rest if topic != topics.IMU]
            spin_for(executor, 2 * IDLE_S)
        sent_s = time.monotonic()
        for topic, message in rest:
            pubs[topic].publish(message)
        assert spin_until(
            executor, lambda: feeder.messages[topics.LABEL], timeout_s=2 * POLL_PERIOD_S
        )
        waited_s = time.monotonic() - sent_s
    labels = feeder.labels(topics.LABEL)
    assert len(labels) == 1 and abs(labels[0].impact_stamp_s - CONTACT_S) < 0.001
    assert waited_s < POLL_PERIOD_S / 3, (
        f"label {waited_s:.3f} s after the rest of the data: it waited for the periodic tick"
    )
    assert np.isfinite(labels[0].confidence)


@pytest.mark.ros
def test_the_inbox_splits_what_has_been_held_from_what_has_not():
    """id_node's inbox hands over the messages that arrived by the cutoff with the newest of
    their arrival times, then the later ones with theirs, and is empty after."""
    from tail_beam_id.ros.id_node import Inbox

    inbox = Inbox()
    for message, arrived_s in (("a", 1.0), ("b", 2.0), ("c", 3.0)):
        inbox.put(message, arrived_s)
    assert inbox.take(2.0) == ((["a", "b"], 2.0), (["c"], 3.0))
    assert inbox.take(10.0) == (([], -math.inf), ([], -math.inf))
    inbox.put("d", 4.0)
    assert inbox.take(0.0) == (([], -math.inf), (["d"], 4.0))
