"""The launcher's pose monitor: it holds a window of samples, not the whole run, and
names another swarm's nodes."""

from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np
import pytest
from geometry_msgs.msg import Pose, PoseArray
from rclpy.serialization import serialize_message

from aes_ros.ros.launch import monitor as monitor_module
from aes_ros.ros.launch.monitor import Monitor

N = 4


def poses(t: float, xy: np.ndarray) -> bytes:
    msg = PoseArray()
    msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), round((t % 1) * 1e9)
    for x, y in xy:
        pose = Pose()
        pose.position.x, pose.position.y, pose.orientation.w = float(x), float(y), 1.0
        msg.poses.append(pose)
    return serialize_message(msg)


@pytest.fixture
def monitor():
    mon = Monitor(N)
    yield mon
    mon.close()


def test_released_samples_are_forgotten_and_numbering_goes_on(monitor) -> None:
    still = np.zeros((N, 2))
    for k in range(3):  # at rest, then every robot moves
        monitor.on_poses(poses(0.05 * k, still))
    for k in range(3, 1000):
        monitor.on_poses(poses(0.05 * k, still + 0.01 * k))
    assert monitor.all_moving() == 3 and monitor.last_unmoved == 2
    monitor.release(990)
    assert monitor.count == 1000 and len(monitor.times) == 10 and monitor.offset == 990
    t, xy, _ = monitor.sample(995)
    assert t == pytest.approx(0.05 * 995) and xy[0, 0] == pytest.approx(9.95)
    with pytest.raises(IndexError):
        monitor.sample(989)
    monitor.release(10_000)  # the newest sample always stays
    assert monitor.count == 1000 and monitor.sample(999)[0] == pytest.approx(49.95)
    monitor.on_poses(poses(50.0, still + 10.0))
    assert monitor.count == 1001 and len(monitor.times) == 2


def test_samples_all_moving_has_not_looked_at_stay(monitor) -> None:
    still = np.zeros((N, 2))
    for k in range(5):
        monitor.on_poses(poses(0.05 * k, still))
    assert monitor.all_moving() is None
    monitor.on_poses(poses(0.25, still))
    monitor.release(6)  # sample 5 not checked yet: kept
    assert monitor.offset == 5
    monitor.on_poses(poses(0.30, still + 1.0))
    assert monitor.all_moving() == 6


class LateNamesGraph:
    """A graph where a publisher of the poses shows at once and its node's name only
    after ``delay`` s, as discovery tells them on a loaded machine."""

    def __init__(self, delay: float) -> None:
        self.named_at = time.monotonic() + delay

    def get_node_names_and_namespaces(self) -> list[tuple[str, str]]:
        return []

    def count_publishers(self, topic: str) -> int:
        return 1

    def get_publishers_info_by_topic(self, topic: str) -> list[SimpleNamespace]:
        name = "sim_bridge" if time.monotonic() >= self.named_at else "_NODE_NAME_UNKNOWN_"
        return [SimpleNamespace(node_name=name, node_namespace="/")]


def test_another_swarms_publisher_is_named_once_discovery_tells_its_node(
    monitor, monkeypatch
) -> None:
    monkeypatch.setattr(monitor, "node", LateNamesGraph(delay=2.0))
    monkeypatch.setattr(monitor, "spin_once", time.sleep)
    assert monitor.other_swarm(wait=1.0) == ["/sim_bridge"]
    monkeypatch.setattr(monitor_module, "NAME_WAIT", 1.0)  # no need to sit out all 5 s
    monkeypatch.setattr(monitor, "node", LateNamesGraph(delay=60.0))
    assert monitor.other_swarm(wait=1.0) == ["a publisher of /swarm/poses"]
