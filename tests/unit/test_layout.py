"""The rules the package layout keeps (read from the source, nothing is imported).

- The core (``aes_ros`` outside ``aes_ros/ros``) never imports rclpy or a ROS
  message package: the simulator, the optimiser and ``aes-swarm simulate`` work
  on a machine without ROS, and the control law has one definition that the
  nodes only adapt.
- Nothing in ``aes_ros`` imports the node packages: nodes depend on the library,
  never the other way round.
"""

from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
ROS_PACKAGES = {
    "rclpy", "rcl_interfaces", "builtin_interfaces", "geometry_msgs", "nav_msgs", "std_msgs",
    "std_srvs", "rosgraph_msgs", "visualization_msgs", "rosidl_adapter", "mcap_ros2",
}  # fmt: skip
NODE_PACKAGES = {"robot_node", "supervisor_node", "sim_bridge"}


def imported_packages(path: Path) -> set[str]:
    """Top-level packages imported anywhere in a module (also inside functions)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.add(node.module.split(".")[0])
    return found


def modules(under: str) -> list[Path]:
    return sorted((REPO / under).rglob("*.py"))


def test_the_core_never_imports_ros() -> None:
    core = [p for p in modules("aes_ros") if "ros" not in p.relative_to(REPO / "aes_ros").parts]
    assert len(core) > 15  # the scan really sees the core
    offenders = {
        str(p.relative_to(REPO)): sorted(imported_packages(p) & ROS_PACKAGES)
        for p in core
        if imported_packages(p) & ROS_PACKAGES
    }
    assert offenders == {}


def test_the_library_never_imports_the_nodes() -> None:
    offenders = {
        str(p.relative_to(REPO)): sorted(imported_packages(p) & NODE_PACKAGES)
        for p in modules("aes_ros")
        if imported_packages(p) & NODE_PACKAGES
    }
    assert offenders == {}
