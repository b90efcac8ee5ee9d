"""The launch plan (:mod:`aes_ros.ros.launch.plan`): how each layout spreads the robots
over processes and names them, as pure command lines (nothing is started)."""

from __future__ import annotations

from aes_ros import scenario
from aes_ros.ros.launch.plan import LaunchConfig, node_commands, split_robots


def test_layouts_split_robots_and_name_hosts(tmp_path) -> None:
    assert split_robots(10, 2) == [[0, 1, 2, 3, 4], [5, 6, 7, 8, 9]]
    assert split_robots(3, 8) == [[0], [1], [2]]
    sc = scenario.load("linear").with_robots(6)
    files = (tmp_path / "s.yaml", tmp_path / "r.yaml")
    per_core = node_commands(LaunchConfig(sc, layout="per-core", cores=2), *files)
    assert [name for name, _ in per_core] == [
        "sim_bridge", "supervisor", "robot_host_0", "robot_host_1"
    ]  # fmt: skip
    assert "robot_ids:=[3,4,5]" in per_core[3][1]
    assert "robot_host:__node:=robot_host_1" in per_core[3][1]
    per_robot = node_commands(LaunchConfig(sc, layout="per-robot"), *files)
    assert len(per_robot) == 2 + 6 and "__ns:=/mona_5" in per_robot[-1][1]
    single = node_commands(LaunchConfig(sc, layout="single"), *files)
    assert len(single) == 3 and not any("robot_ids" in a for a in single[2][1])
