"""Nodes against a hostile participant of the domain: requests and messages no honest client
sends are refused by name, and the node keeps running."""

from __future__ import annotations

import pytest
from bag_helpers import records, write_segments
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters, SetParametersAtomically
from rclpy.parameter import Parameter
from rosprobe import Probe, call_until_answered, ros_context, spin_until

pytestmark = [pytest.mark.ros]


def build(kind: str, context, tmp_path):
    """One of the four nodes, in-process, with the parameters it needs to start."""

    def given(**values):
        return [Parameter(k, value=v) for k, v in values.items()]

    if kind == "sim_node":
        from tail_beam_sim.ros.sim_node import SimNode

        return SimNode(
            context=context, parameter_overrides=given(**{"sim_node.realtime_factor": 0.0})
        )
    if kind == "id_node":
        from tail_beam_id.ros.id_node import IdNode

        return IdNode(context=context, parameter_overrides=given(method="threshold"))
    if kind == "bag_recorder":
        from tail_beam_sim.ros.recorder_node import RecorderNode

        return RecorderNode(
            context=context,
            parameter_overrides=given(**{"recorder.bag_path": str(tmp_path / "recorded")}),
        )
    from tail_beam_sim.ros.replay_node import ReplayNode

    write_segments(tmp_path / "to_replay", [records(20)])
    return ReplayNode(
        context=context,
        parameter_overrides=given(
            **{"replay.bag_path": str(tmp_path / "to_replay"), "replay.wait_for_subscribers": 50}
        ),
    )


def call(executor, client, request):
    assert spin_until(executor, client.service_is_ready, timeout_s=30), (
        f"{client.srv_name} never came"
    )
    return call_until_answered(executor, lambda: client.call_async(request), client.srv_name)


@pytest.mark.parametrize("kind", ["sim_node", "id_node", "bag_recorder", "bag_replay"])
def test_a_parameter_request_no_client_library_makes_is_refused_by_name(kind, tmp_path):
    """A SetParameters request holding a value of type 99 (no ParameterType), or naming no
    parameter of the node: refused naming the parameter, the node answers on (was: ValueError
    '99 is not a valid Parameter.Type' out of the executor, ending every node)."""
    with ros_context() as (context, executor):
        node = build(kind, context, tmp_path)
        executor.add_node(node)
        probe = Probe(context, {}, name="intruder")
        executor.add_node(probe)
        name = node.get_fully_qualified_name()
        declared = sorted(node._parameters)[0]
        bad = ParameterMsg(name=declared, value=ParameterValue(type=99))
        setter = probe.create_client(SetParameters, f"{name}/set_parameters")
        results = call(
            executor,
            setter,
            SetParameters.Request(
                parameters=[
                    bad,
                    ParameterMsg(
                        name="no.such_parameter", value=ParameterValue(type=3, double_value=1.0)
                    ),
                    ParameterMsg(name=declared, value=ParameterValue(type=4, string_value="x")),
                ]
            ),
        ).results
        assert len(results) == 3 and not any(r.successful for r in results)
        assert (
            declared in results[0].reason
            and "value type 99" in results[0].reason
            and "0-9" in results[0].reason
        )
        assert (
            "no.such_parameter" in results[1].reason and "no such parameter" in results[1].reason
        )
        assert (
            declared in results[2].reason and "start-up" in results[2].reason
        )  # the node's own refusal, as before
        atomic = probe.create_client(SetParametersAtomically, f"{name}/set_parameters_atomically")
        result = call(executor, atomic, SetParametersAtomically.Request(parameters=[bad])).result
        assert (
            not result.successful
            and declared in result.reason
            and "value type 99" in result.reason
        )
        getter = probe.create_client(GetParameters, f"{name}/get_parameters")
        values = call(executor, getter, GetParameters.Request(names=[declared])).values
        assert len(values) == 1 and values[0].type != 99
        assert context.ok()
