"""The rules the package layout keeps (read from the source with ``ast``, nothing is
imported; imports inside functions count too).

- The core (``aes_ros`` outside ``aes_ros.ros`` and ``aes_ros.cli``) never imports rclpy
  or a ROS message package: the simulator, the optimiser and ``aes-swarm simulate`` work
  on a machine without ROS, and the control law has one definition that the nodes only
  adapt. It imports neither ``aes_ros.ros`` nor ``aes_ros.cli``: they build on it.
- Nothing in ``aes_ros`` imports a node package: nodes depend on the library, never the
  other way round (``aes-swarm dashboard`` runs the dashboard node as a child process;
  ``aes-swarm calibrate`` and the tracker share :mod:`aes_ros.tracking`).
- No node package imports another: what two of them share lives in ``aes_ros``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
ROS_PACKAGES = {
    "rclpy", "rcl_interfaces", "builtin_interfaces", "geometry_msgs", "nav_msgs", "std_msgs",
    "std_srvs", "rosgraph_msgs", "visualization_msgs", "sensor_msgs", "diagnostic_msgs",
    "rosidl_adapter", "mcap_ros2",
}  # fmt: skip
#: Every node package; one that appears in the repository must be listed here.
NODE_PACKAGES = {
    "robot_node", "supervisor_node", "sim_bridge", "dashboard_node", "tracker_node",
    "mona_driver",
}  # fmt: skip
#: Top-level packages that are neither the library nor a node.
NOT_NODES = {"aes_ros", "tests", "bench", "scripts", "firmware", "docs"}


def parse(path: Path) -> ast.Module:
    return ast.parse(path.read_text(), str(path))


def imports(tree: ast.AST) -> list[tuple[str, ast.AST]]:
    """Every module ``tree`` imports (dotted, absolute), with the node that does it; also
    inside functions. ``from aes_ros import ros`` counts as ``aes_ros.ros``."""
    found: list[tuple[str, ast.AST]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(alias.name, node) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.module, node))
            found += [(f"{node.module}.{alias.name}", node) for alias in node.names]
    return found


def packages(path: Path) -> set[str]:
    """Top-level packages a file imports."""
    return {name.split(".")[0] for name, _ in imports(parse(path))}


def modules(under: str) -> list[Path]:
    return sorted((REPO / under).rglob("*.py"))


def rel(path: Path) -> str:
    return str(path.relative_to(REPO))


def core_modules() -> list[Path]:
    inside = ("ros", "cli")
    return [p for p in modules("aes_ros") if p.relative_to(REPO / "aes_ros").parts[0] not in inside]


def node_packages() -> list[str]:
    """The node packages of this checkout: top-level Python packages besides the library."""
    found = {p.parent.name for p in REPO.glob("*/__init__.py")} - NOT_NODES
    return sorted(found)


def test_every_node_package_is_known() -> None:
    """The rules below cover every node package of the checkout, and only those."""
    assert set(node_packages()) == NODE_PACKAGES, "NODE_PACKAGES lists the node packages"


def test_the_core_never_imports_ros() -> None:
    core = core_modules()
    assert len(core) > 15  # the scan really sees the core
    offenders = {rel(p): sorted(packages(p) & ROS_PACKAGES) for p in core}
    assert {k: v for k, v in offenders.items() if v} == {}


def test_the_core_never_imports_the_ros_layer_or_the_cli() -> None:
    offenders = {
        rel(p): sorted(
            name for name, _ in imports(parse(p)) if name.startswith(("aes_ros.ros", "aes_ros.cli"))
        )
        for p in core_modules()
    }
    assert {k: v for k, v in offenders.items() if v} == {}


def test_the_library_never_imports_the_nodes() -> None:
    library = modules("aes_ros")
    assert any(rel(p).startswith("aes_ros/cli/") for p in library)  # the front door too
    offenders = {rel(p): sorted(packages(p) & NODE_PACKAGES) for p in library}
    assert {k: v for k, v in offenders.items() if v} == {}


@pytest.mark.parametrize("package", node_packages())
def test_no_node_package_imports_another(package: str) -> None:
    others = NODE_PACKAGES - {package}
    offenders = {rel(p): sorted(packages(p) & others) for p in modules(package)}
    assert {k: v for k, v in offenders.items() if v} == {}
    assert modules(package)  # the scan really sees the package
