"""id_node counts the samples it lost from the stamps themselves, and a label decided from data
with a gap says so. Real rclpy nodes over the middleware."""

from __future__ import annotations

import math

import pytest
from id_helpers import stream_chunk
from test_id_node_wake import messages_between

from tail_beam_sim import topics

CONTACT_S = 0.3  # stamp of the one impact's contact, s
# IMU samples stamped in here are not sent, s (bounds between the 2 kHz grid's stamps)
HOLE_S = (CONTACT_S - 0.00215, CONTACT_S + 0.00415)


@pytest.mark.ros
@pytest.mark.parametrize("stream", [topics.IMU, topics.VIBRATION])
def test_a_label_from_data_with_a_gap_names_it_and_the_loss_is_counted(params, stream):
    """The IMU samples (or vibration blocks) of 6 ms across an impact's contact never reach
    id_node (as a reader's overflowing history loses them, with no DDS event): id_node counts
    exactly those samples lost. With the IMU's lost it still labels the impact, with ``gaps``
    naming the IMU and the count; with the accelerometer's, whose resuming samples can look
    like an onset, it does not label it but counts it undecided."""
    from geometry_msgs.msg import TwistStamped
    from rclpy.parameter import Parameter
    from rosprobe import Probe, ros_context, spin_for, spin_until
    from sensor_msgs.msg import FluidPressure, Imu, LaserScan
    from std_msgs.msg import String

    from tail_beam_id.ros.id_node import IdNode
    from tail_beam_sim.ros import messages as ros_messages

    impact = {"material": "sandstone", "radius_m": 0.06, "drop_height_m": 2.0, "position_m": 1.0}
    chunk = stream_chunk(params, [(CONTACT_S, impact)], CONTACT_S + 0.3)
    everything = messages_between(chunk, -math.inf, math.inf)
    in_hole = [
        topic == stream and HOLE_S[0] < ros_messages.stamp_s(m.header.stamp) < HOLE_S[1]
        for topic, m in everything
    ]
    sent = [item for item, dropped in zip(everything, in_hole) if not dropped]
    missing = sum(
        len(m.ranges) if stream == topics.VIBRATION else 1
        for (_, m), dropped in zip(everything, in_hole)
        if dropped
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
            namespace="/gaps",
            parameter_overrides=[
                Parameter("method", value="statistical"),
                Parameter("id_node.flush_after_idle_s", value=0.5),
            ],
        )
        feeder = Probe(context, {topics.LABEL: String}, namespace="/gaps", name="feeder")
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
        spin_for(executor, 0.5)
        for topic, message in sent:
            pubs[topic].publish(message)
        spin_until(executor, lambda: feeder.messages[topics.LABEL], timeout_s=5)
        spin_for(executor, 1.0)
        lost = dict(ident.lost_samples)
        undecided = (ident.undecided_impacts, ident.gap_onsets)
    labels = feeder.labels(topics.LABEL)
    assert missing >= 10
    assert lost == {topics.JACK_PRESSURE: 0, topics.IMU: 0, topics.VIBRATION: 0, stream: missing}
    if stream == topics.IMU:
        assert len(labels) == 1 and abs(labels[0].impact_stamp_s - CONTACT_S) < 0.001
        assert labels[0].extra["gaps"] == {topics.IMU: missing}
    else:
        assert not labels and undecided == (1, 1)
