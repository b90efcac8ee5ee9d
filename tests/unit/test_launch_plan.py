"""The launch plan (:mod:`aes_ros.ros.launch.commands`, :mod:`aes_ros.ros.launch.layout`):
how each layout spreads the robots over processes and names them, as pure command lines
(nothing is started)."""

from __future__ import annotations

import pytest

from aes_ros import scenario
from aes_ros.ros import interface as names
from aes_ros.ros.launch.commands import dashboard_command, node_commands, start_order
from aes_ros.ros.launch.config import LaunchConfig
from aes_ros.ros.launch.layout import split_robots
from aes_ros.ros.launch.param_files import ros_args


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


def test_auto_layout_uses_one_host_while_it_carries_the_load(tmp_path) -> None:
    """auto: one robot host up to 20000 robot-steps per second, and on two cores always
    (the measured cheaper and faster-starting layout there); one per core above it on
    a bigger machine."""
    from aes_ros.ros.launch.layout import resolved_layout

    def layout(robots: int, hz: float, cores: int) -> str:
        sc = scenario.load("combined", {"dt": 1.0 / hz}).with_robots(robots)
        return resolved_layout(LaunchConfig(sc, cores=cores))

    assert layout(100, 50, 8) == "single" and layout(16, 20, 8) == "single"
    assert layout(400, 50, 8) == "single" and layout(1000, 20, 8) == "single"
    assert layout(1001, 20, 8) == "per-core"  # 20020 robot-steps per second
    assert layout(1000, 50, 2) == "single"  # two cores: one host answers more
    assert layout(1000, 50, 4) == "per-core"
    sc = scenario.load("linear").with_robots(6)
    assert resolved_layout(LaunchConfig(sc, layout="per-core")) == "per-core"
    files = (tmp_path / "s.yaml", tmp_path / "r.yaml")
    assert [name for name, _ in node_commands(LaunchConfig(sc), *files)][2:] == ["robot_host_0"]


def test_dashboard_runs_on_loopback_with_sim_time(tmp_path) -> None:
    sc = scenario.load("linear").with_robots(4)
    name, argv = dashboard_command(LaunchConfig(sc, dashboard=8091), tmp_path / "s.yaml")
    assert name == "dashboard" and argv[0] == "aes-dashboard"
    assert {"host:=127.0.0.1", "port:=8091", "use_sim_time:=true"} <= set(argv)


def test_an_empty_text_parameter_survives_the_command_line() -> None:
    # rcl refuses `token:=` with nothing after it; YAML's '' is the empty string
    assert ros_args({"token": ""}) == ["--ros-args", "-p", "token:=''"]


@pytest.mark.parametrize(
    ("world", "tracking", "first", "poses"),
    [
        ("pybullet", "none", ["sim_bridge"], names.POSES),
        ("pybullet", "camera", ["sim_bridge", "arena_camera", "tracker"], names.GROUND_TRUTH_POSES),
        ("none", "camera", ["tracker"], names.POSES),  # a real arena: the tracker's poses
    ],
)
def test_start_order_starts_the_first_poses_publisher_first(
    tmp_path, world: str, tracking: str, first: list[str], poses: str
) -> None:
    """The bridge (none in a real arena), then the camera and the tracker: the first of
    them publishes the poses the launcher waits for. The launcher samples the bridge's
    exact poses when tracked in simulation, the tracker's in a real arena."""
    sc = scenario.load("linear").with_robots(4)
    real = (
        {"camera_source": "arena.mp4", "calibration": tmp_path / "c.yaml"}
        if world == "none"
        else {}
    )
    cfg = LaunchConfig(sc, world=world, tracking=tracking, layout="single", **real)
    files = (tmp_path / "s.yaml", tmp_path / "r.yaml", tmp_path / "arena.yaml")
    order = start_order(cfg, *files)
    assert [spec.name for spec in order.first] == first
    assert (order.bridge is not None) == (world != "none")
    assert order.recorder is None and order.dashboard is None
    assert list(order.by_name) == [*first, "supervisor", "robot_host_0"]
    assert cfg.poses_topic == poses


def test_start_order_starts_the_recorder_first_and_the_dashboard_last(tmp_path) -> None:
    sc = scenario.load("linear").with_robots(4)
    files = (tmp_path / "s.yaml", tmp_path / "r.yaml", tmp_path / "arena.yaml")
    recorded = start_order(
        LaunchConfig(sc, record=tmp_path / "bag", dashboard=0, layout="single"), *files
    )
    assert recorded.recorder.argv[-3:] == [str((tmp_path / "bag").resolve()), "--robots", "4"]
    assert list(recorded.by_name) == [
        "sim_bridge", "supervisor", "robot_host_0", "recorder", "dashboard"
    ]  # fmt: skip


def test_camera_frames_are_recorded_only_when_asked_and_by_a_restarted_recorder_too(
    tmp_path,
) -> None:
    from aes_ros.ros.launch.recovery import RestartCommands

    sc = scenario.load("linear").with_robots(4)
    files = (tmp_path / "s.yaml", tmp_path / "r.yaml", tmp_path / "arena.yaml")
    plain = LaunchConfig(sc, record=tmp_path / "bag", tracking="camera")
    assert "--images" not in start_order(plain, *files).recorder.argv
    asked = LaunchConfig(sc, record=tmp_path / "bag", tracking="camera", record_images=2.5)
    argv = start_order(asked, *files).recorder.argv
    assert argv[argv.index("--images") + 1] == "2.5"
    restart = RestartCommands({}, None, tmp_path / "w.npz", tmp_path / "bag", 4, images_rate=2.5)
    again = restart("recorder")
    assert again[again.index("--images") + 1] == "2.5"


def test_a_restarted_bridge_waits_at_the_run_end_as_the_first_one_did(tmp_path) -> None:
    """Once the launcher has set the bridge's pause_at (the run's end), a bridge it
    restarts is given the same, or it would run on past the end at full speed."""
    from types import SimpleNamespace

    from aes_ros.ros.launch.recovery import RestartCommands

    sc = scenario.load("linear").with_robots(4)
    files = (tmp_path / "s.yaml", tmp_path / "r.yaml", tmp_path / "arena.yaml")
    order = start_order(LaunchConfig(sc, layout="single"), *files)
    monitor = SimpleNamespace(times=[], desired=None, enabled=None)
    restart = RestartCommands(order.by_name, monitor, tmp_path / "w.npz", None, 4)
    assert not any(a.startswith("pause_at:=") for a in restart("sim_bridge"))
    restart.pause_at = 10.025
    argv = restart("sim_bridge")
    assert argv[argv.index("pause_at:=10.025") - 1] == "-p"
