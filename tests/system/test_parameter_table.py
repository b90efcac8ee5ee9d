"""``aes-swarm params --ros`` tells the truth: every node of its table, built here, declares
exactly the parameters listed, and a parameter has a ``params`` name exactly when the
node declares it with that entry's descriptor."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import rclpy
from helpers.ros_env import reserved_domain_id, ros_variables
from rclpy.node import Node

from aes_ros.params import PARAMS
from aes_ros.ros import interface as names
from aes_ros.ros import parameters as rp
from aes_ros.ros.parameter_table import NODE_PARAMETERS

#: rclpy's own parameters, in every node.
RCLPY = {"use_sim_time", "start_type_description_service"}


@pytest.fixture(scope="module")
def declared() -> Iterator[dict[str, dict[str, str]]]:
    """Each node of the table, built in-process: parameter name -> its description."""
    with reserved_domain_id() as domain, pytest.MonkeyPatch.context() as mp:
        for key, value in ros_variables(domain).items():
            mp.setenv(key, value)
        mp.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "OFF")  # nobody else sees these nodes
        from dashboard_node.node import DashboardNode
        from robot_node.host import RobotHostNode
        from robot_node.node import RobotNode
        from sim_bridge.camera_node import ArenaCameraNode
        from sim_bridge.parameters import declare_bridge_parameters
        from supervisor_node.node import SupervisorNode

        context = rclpy.Context()
        rclpy.init(args=[], context=context)
        bridge = Node(names.SIM_BRIDGE_NODE, context=context)  # its parameters, no pybullet
        rp.declare_scenario(bridge)
        declare_bridge_parameters(bridge)
        nodes = [
            SupervisorNode(context=context),
            RobotNode(context=context, namespace="/mona_0"),
            RobotHostNode(context=context),
            bridge,
            ArenaCameraNode(context=context),
            DashboardNode(context=context),
        ]
        try:
            yield {
                n.get_name(): {
                    p: n.describe_parameter(p).description for p in set(n._parameters) - RCLPY
                }
                for n in nodes
            }
        finally:
            for n in nodes:
                n.destroy_node()
            rclpy.try_shutdown(context=context)


def test_the_table_lists_every_node_and_parameter(declared) -> None:
    assert set(declared) == set(NODE_PARAMETERS)
    for node, table in NODE_PARAMETERS.items():
        assert {ros for ros, _ in table.rows()} == set(declared[node]), node


def test_a_params_name_is_the_descriptor_the_node_uses(declared) -> None:
    by_description = {rp.descriptor(spec).description: name for name, spec in PARAMS.items()}
    for node, table in NODE_PARAMETERS.items():
        for ros, name in table.rows():
            assert by_description.get(declared[node][ros]) == name, (node, ros)
    supervisor = dict(NODE_PARAMETERS[names.SUPERVISOR_NODE].rows())
    assert supervisor["desired_direction"] == "direction"
    assert supervisor["rotation_rate"] == "omega"
