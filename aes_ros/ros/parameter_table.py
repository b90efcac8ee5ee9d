"""The nodes' ROS parameters and their ``aes-swarm params`` / ``--set`` names (``params --ros``).

A ROS parameter has a ``params`` counterpart when the node declares it with that
entry's descriptor (:func:`aes_ros.ros.parameters.descriptor` of ``PARAMS[name]``);
``tests/unit/test_parameter_table.py`` starts every node listed here and checks this
table against what it declares.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from aes_ros.ros import interface as names

#: Declared by every node that reads the scenario (``parameters.declare_scenario``).
SCENARIO = ("scenario", "num_robots")
#: The gains every controller node declares from ``PARAMS``.
GAINS = ("alpha", "beta", "k", "v0", "w_l", "w_r", "d_r", "d_theta", "w_o")


@dataclass(frozen=True)
class NodeParameters:
    """One node's ROS parameters: ``same`` (the ``params`` name too), ``renamed`` (ROS name
    -> ``params`` name) and ``ros_only`` (no ``params`` counterpart)."""

    same: tuple[str, ...] = ()
    renamed: dict[str, str] = field(default_factory=dict)
    ros_only: tuple[str, ...] = ()

    def rows(self) -> list[tuple[str, str | None]]:
        """(ROS name, ``params`` name or None), sorted by the ROS name."""
        pairs = [(n, n) for n in self.same] + list(self.renamed.items())
        return sorted(pairs + [(n, None) for n in self.ros_only])


#: Node name -> its parameters (``use_sim_time`` and rclpy's own left out). The robot
#: nodes run in the namespace ``/mona_<i>``.
NODE_PARAMETERS: dict[str, NodeParameters] = {
    names.SUPERVISOR_NODE: NodeParameters(
        same=(*GAINS, "arena", "arena_policy", "arena_margin"),
        renamed={"desired_direction": "direction", "rotation_rate": "omega"},
        ros_only=(
            *SCENARIO,
            "enabled",
            "publish_rate",
            "rotation_center",
            "rotation_center_mode",
        ),
    ),
    names.ROBOT_NODE: NodeParameters(
        same=(*GAINS, "max_linear_speed", "max_angular_speed"),
        ros_only=(
            *SCENARIO,
            "clip",
            "neighbor_source",
            "neighbor_timeout",
            "neighbors",
            "rest_lengths",
            "robot_id",
            "seed",
        ),
    ),
    names.ROBOT_HOST_NODE: NodeParameters(
        ros_only=(*SCENARIO, "neighbor_source", "robot_ids", "robots_per_participant"),
    ),
    names.SIM_BRIDGE_NODE: NodeParameters(
        ros_only=(
            *SCENARIO,
            "clip",
            "cmd_timeout",
            "gui",
            "ir_falling",
            "ir_gain",
            "ir_max_range",
            "ir_min_range",
            "ir_noise",
            "ir_offset",
            "ir_quantise",
            "ir_rate",
            "lockstep",
            "lockstep_timeout",
            "mode",
            "pause_at",
            "physics_rate",
            "publish_rate",
            "real_time_factor",
            "resume_from",
            "seed",
            "wait_for_recorder",
        ),
    ),
    names.CAMERA_NODE: NodeParameters(
        ros_only=(
            "arena",
            "blur",
            "camera_height",
            "distortion",
            "drop",
            "exposure",
            "exposure_delay",
            "full_well",
            "gradient",
            "height",
            "hfov",
            "layout",
            "noise",
            "obstacles",
            "preset",
            "rate",
            "read_noise",
            "seed",
            "vignetting",
            "walls",
            "width",
        ),
    ),
    names.DASHBOARD_NODE: NodeParameters(
        ros_only=(*SCENARIO, "frame_rate", "host", "label", "markers_rate", "port"),
    ),
}

#: Where a ROS-only parameter still follows a ``params`` entry, how.
NOTES: dict[tuple[str, str], str] = {
    (names.SUPERVISOR_NODE, "rotation_center"): "set from `rotation_center` when it is given",
    (names.SUPERVISOR_NODE, "rotation_center_mode"): "`centroid` if `rotation_center` is null",
    (names.ROBOT_NODE, "clip"): "set from `clip` at start",
    (names.SIM_BRIDGE_NODE, "clip"): "set from `clip` at start",
    (names.SIM_BRIDGE_NODE, "ir_rate"): "defaults to the scenario's `ir_rate`; 0 = off",
}


def node_label(node: str) -> str:
    """The node's full name as ``ros2 node list`` shows it."""
    return f"/mona_<i>/{node}" if node == names.ROBOT_NODE else f"/{node}"


def markdown_table() -> str:
    """Every node's ROS parameters and their ``aes-swarm params`` / ``--set`` names."""
    lines = [
        "| node | ROS parameter | `aes-swarm params` / `--set` name |",
        "|---|---|---|",
    ]
    for node, params in NODE_PARAMETERS.items():
        for ros_name, name in params.rows():
            if name is not None:
                shown = f"`{name}`"
            else:
                note = NOTES.get((node, ros_name))
                shown = f"none; {note}" if note else "none (ROS only)"
            lines.append(f"| `{node_label(node)}` | `{ros_name}` | {shown} |")
    return "\n".join(lines)
