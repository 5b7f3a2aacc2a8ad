"""A client that publishes the wrong message type on a contract topic name. DDS never matches
the two, so not one of its messages arrives, and nothing said so (the middleware of the pip
wheels raises no incompatible-type event): the client saw its messages vanish. Each node now
warns once per such publisher, naming the topic, both types and the publishing node."""

from __future__ import annotations

import pytest
import rclpy
from rosprobe import ros_context, spin_until
from sensor_msgs.msg import Imu
from std_msgs.msg import String

pytestmark = [pytest.mark.ros]


def test_a_publisher_of_the_wrong_type_on_a_contract_topic_is_named(tmp_path, capfd):
    """std_msgs/String on ``imu`` and sensor_msgs/Imu on ``impact_cmd``, from another participant
    (one participant cannot hold both types on one name): sim_node, id_node and the recorder each
    warn once per publisher, naming the topic, the type it offers and the contract's."""
    from rclpy.parameter import Parameter

    from tail_beam_id.ros.id_node import IdNode
    from tail_beam_sim.ros.recorder_node import RecorderNode
    from tail_beam_sim.ros.sim_node import SimNode

    foreign = rclpy.Context()
    rclpy.init(context=foreign)
    try:
        client = rclpy.create_node("wrong_types", namespace="/typed", context=foreign)
        client.create_publisher(String, "imu", 10)
        client.create_publisher(Imu, "impact_cmd", 10)
        with ros_context() as (context, executor):
            sim = SimNode(context=context, namespace="/typed")
            ident = IdNode(context=context, namespace="/typed")
            recorder = RecorderNode(
                context=context,
                namespace="/typed",
                parameter_overrides=[Parameter("recorder.bag_path", value=str(tmp_path / "bag"))],
            )
            for node in (sim, ident, recorder):
                executor.add_node(node)
            said: list[str] = []

            def warned() -> bool:
                said.extend(
                    line for line in capfd.readouterr().err.splitlines() if "offers" in line
                )
                return (
                    sum("tail_beam_id" in s and "/typed/imu" in s for s in said) == 1
                    and sum("tail_beam_recorder" in s for s in said) == 2
                    and sum("tail_beam_sim" in s and "/typed/impact_cmd" in s for s in said) == 1
                )

            assert spin_until(executor, warned, timeout_s=20), said
            spin_until(executor, lambda: False, timeout_s=1.5)  # once, not on every look
            said.extend(line for line in capfd.readouterr().err.splitlines() if "offers" in line)
            recorder.close()
    finally:
        rclpy.try_shutdown(context=foreign)
    assert len(said) == 4, said
    line = next(s for s in said if "tail_beam_id" in s)
    assert (
        "std_msgs/msg/String" in line and "sensor_msgs/msg/Imu" in line and "wrong_types" in line
    ), line
