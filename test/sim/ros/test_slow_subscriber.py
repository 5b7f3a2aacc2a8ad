"""A slow best-effort reader of imu beside a real-time sim_node costs id_node nothing: one label
per impact, no revision, no pressure, IMU or vibration data lost.

The sensor topics are best effort (tail_beam_sim.ros.messages.sensor_qos), so a reader that
takes 2 ms per IMU message (a quarter of the 2 kHz stream) loses its own samples and cannot
hold the writer up, which would slow sim_node's publishing and burst the streams into id_node
(late, extra or missing labels).
"""

from __future__ import annotations

import subprocess
import sys

import pytest
from rclpy.parameter import Parameter
from rosprobe import Probe, ros_context, spin_for, spin_until
from std_msgs.msg import String

from tail_beam_id.stream.label import match, match_tolerance_s
from tail_beam_sim import topics
from tail_beam_sim.config import load_parameters

pytestmark = pytest.mark.ros

IMPACTS = 8
WORK_S = 0.002  # the slow reader's time per IMU message, s (asleep: no CPU taken from the nodes)


# The slow reader, a process of its own (as a client is): best effort, depth 10 000, sleeping
# WORK_S on each IMU message; prints how many IMU messages it took when stdin closes.
READER = f"""
import sys, threading, time
import rclpy
from rclpy.experimental import EventsExecutor
from sensor_msgs.msg import FluidPressure, Imu
from tail_beam_sim.ros.messages import sensor_qos
rclpy.init()
node = rclpy.create_node("slow_reader")
got = [0]
def on_imu(_msg):
    got[0] += 1
    time.sleep({WORK_S})
node.create_subscription(Imu, "imu", on_imu, sensor_qos(10000))
node.create_subscription(FluidPressure, "jack_pressure", lambda _m: None, sensor_qos(10000))
executor = EventsExecutor()
executor.add_node(node)
done = threading.Event()
threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
print("ready", flush=True)
while not done.is_set():
    executor.spin_once(timeout_sec=0.05)
print(got[0], flush=True)
"""


def test_a_slow_best_effort_reader_costs_id_node_nothing():
    """Eight impacts of a real-time sim_node, a reader sleeping 2 ms per IMU message beside it:
    id_node labels each impact once, revises none, and loses no sample of any stream."""
    from tail_beam_id.ros.id_node import IdNode
    from tail_beam_sim.ros.sim_node import SimNode

    slow = subprocess.Popen(
        [sys.executable, "-c", READER], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    try:
        assert slow.stdout.readline().strip() == "ready"
        with ros_context() as (context, executor):
            sim = SimNode(
                context=context,
                parameter_overrides=[
                    Parameter("sim_node.realtime_factor", value=1.0),
                    Parameter("sim_node.wait_for_subscribers", value=1),
                    Parameter("scenario.source", value="generated"),
                    Parameter("scenario.count", value=IMPACTS),
                ],
            )
            ident = IdNode(
                context=context,
                parameter_overrides=[
                    Parameter("method", value="threshold"),
                    Parameter("id_node.flush_after_idle_s", value=0.3),
                ],
            )
            probe = Probe(context, {topics.LABEL: String, topics.IMPACT_TRUTH: String})
            for node in (sim, ident, probe):
                executor.add_node(node)
            assert spin_until(
                executor,
                lambda: len(probe.messages[topics.IMPACT_TRUTH]) == IMPACTS,
                timeout_s=40,
            )
            assert spin_until(
                executor, lambda: len(probe.messages[topics.LABEL]) >= IMPACTS, timeout_s=10
            )
            spin_for(executor, 1.0)  # a late extra label or revision would come by now
            truths = probe.json(topics.IMPACT_TRUTH)
            labels = probe.labels(topics.LABEL)
            lost = (ident.pressure_lost_messages, ident.imu_lost_messages)
            vibration_lost = ident.vibration_lost_samples
    finally:
        out, _ = slow.communicate("", timeout=20)
    assert int(out.split()[-1]) > 0, "the slow reader got no data: QoS did not match"
    assert not [label for label in labels if label.revises is not None]
    matching = match(truths, labels, match_tolerance_s(load_parameters()["identification"]))
    assert not matching.missed and not matching.extra and len(labels) == IMPACTS
    assert lost == (0, 0) and vibration_lost == 0
