"""The robot's controller state without ROS: rest-length latching, Δt from stamps,
neighbour liveness, the rotation-centre rule and the sheet checks
(robot_node.controller, robot_node.liveness, robot_node.rotation_center)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from aes_ros.model import Gains, SwarmCommand, robot_command
from aes_ros.robot_batch import evaluate_robots
from robot_node.controller import RobotController, RobotSettings, sheet_error
from robot_node.liveness import NeighborLiveness
from robot_node.rotation_center import RotationCenterRule, rotation_center_rule

S = 1_000_000_000  # ns per second
NOISE_OFF = Gains(d_r=0.0, d_theta=0.0)


def settings(**changes) -> RobotSettings:
    base = RobotSettings(
        robot_id=1,
        neighbors=(0, 2),
        rest_lengths=(0.2, 0.25),
        gains=NOISE_OFF,
        limits=None,
        neighbor_timeout=1.0,
        seed=0,
        neighbor_source="poses",
    )
    return dataclasses.replace(base, **changes)


class Log:
    """Collects the controller's warnings and notes."""

    def __init__(self) -> None:
        self.warnings: list[str] = []
        self.notes: list[str] = []


def controller(command: SwarmCommand | None = None, **changes) -> tuple[RobotController, Log]:
    log = Log()
    command = command or SwarmCommand((-1.0, 0.0), 0.0, None)
    ctl = RobotController(
        settings(**changes),
        command,
        log.warnings.append,
        log.notes.append,
        center=rotation_center_rule(command),
    )
    return ctl, log


XY = np.array([[0.5, 0.05], [0.0, 0.0], [0.5, -0.05]])
YAW = np.array([0.0, 0.3, 0.0])


def poses(ctl: RobotController, t: float, xy: np.ndarray = XY, yaw: np.ndarray = YAW):
    return ctl.poses_input(round(t * S), xy, yaw, xy.mean(axis=0))


def test_input_is_the_robots_own_pose_and_its_neighbours_positions() -> None:
    ctl, _ = controller()
    job = poses(ctl, 1.0)
    np.testing.assert_array_equal(job.position, XY[1])
    assert job.heading == YAW[1]
    np.testing.assert_array_equal(job.neighbor_positions, XY[[0, 2]])
    np.testing.assert_array_equal(job.rest_lengths, [0.2, 0.25])
    assert job.command.center == tuple(XY.mean(axis=0))  # live centroid by default
    (result,) = evaluate_robots([job])
    want = robot_command(*job.arguments())
    assert (result.linear, result.angular) == (want.linear, want.angular)


def test_rest_lengths_are_latched_at_first_sight_and_kept() -> None:
    ctl, _ = controller(rest_lengths=())
    first = poses(ctl, 1.0)
    np.testing.assert_allclose(first.rest_lengths, np.linalg.norm(XY[[0, 2]] - XY[1], axis=1))
    stretched = XY * 2.0
    later = poses(ctl, 1.05, stretched)
    np.testing.assert_array_equal(later.rest_lengths, first.rest_lengths)  # not re-latched
    # A new sheet latches again.
    ctl.configure(settings(neighbors=(0,), rest_lengths=()))
    again = poses(ctl, 1.1, stretched)
    assert again.rest_lengths.tolist() == [
        pytest.approx(np.linalg.norm(stretched[0] - stretched[1]))
    ]


def test_dt_follows_the_stamps_and_a_clock_going_back_forgets_old_liveness() -> None:
    ctl, log = controller()
    assert poses(ctl, 1.0).dt == 0.05  # the default until two stamps are known
    assert poses(ctl, 1.1).dt == pytest.approx(0.1)
    ctl.heard_force(2, round(1.1 * S))
    assert poses(ctl, 3.0).neighbor_positions.tolist() == [XY[0].tolist()]  # 2 silent: out
    assert any("neighbour 2 silent" in w for w in log.warnings)
    # A restarted simulator: the clock starts again; neighbour 2's stamp is forgotten.
    assert len(poses(ctl, 0.5).neighbor_positions) == 2


def test_a_silent_neighbour_is_left_out_and_taken_back_when_heard_again() -> None:
    ctl, log = controller()
    ctl.heard_force(0, 1 * S)
    assert len(poses(ctl, 1.5).neighbor_positions) == 2  # within the 1 s timeout
    job = poses(ctl, 2.5)
    np.testing.assert_array_equal(job.neighbor_positions, XY[[2]])
    np.testing.assert_array_equal(job.rest_lengths, [0.25])  # the right spring stays
    assert sum("silent" in w for w in log.warnings) == 1
    poses(ctl, 2.6)
    assert sum("silent" in w for w in log.warnings) == 1  # said once, not every step
    ctl.heard_force(0, round(2.6 * S))
    assert len(poses(ctl, 2.7).neighbor_positions) == 2
    assert log.notes == ["neighbour 0 heard again: back in the sum"]


def test_a_neighbour_the_tracker_lost_is_left_out_until_it_is_seen_again() -> None:
    """With a camera in the loop: the tracker's lost robots (their poses are old) are
    left out like silent ones, even in this robot's own process (never heard from)."""
    ctl, log = controller()
    assert len(poses(ctl, 1.0).neighbor_positions) == 2
    ctl.liveness.lost = frozenset({2, 7})
    job = poses(ctl, 1.05)
    np.testing.assert_array_equal(job.neighbor_positions, XY[[0]])
    np.testing.assert_array_equal(job.rest_lengths, [0.2])
    assert log.warnings == ["neighbour 2 lost by the tracker: left out"]
    poses(ctl, 1.1)
    assert len(log.warnings) == 1  # said once
    ctl.liveness.lost = frozenset()
    assert len(poses(ctl, 1.15).neighbor_positions) == 2
    assert log.notes == ["neighbour 2 heard again: back in the sum"]


def test_a_neighbour_never_heard_from_counts_as_alive() -> None:
    live = NeighborLiveness(timeout_ns=S)
    live.heard(4, 0)
    mask, changes = live.alive(np.array([4, 5]), 2 * S)
    assert mask.tolist() == [False, True]
    assert [(c.neighbor, c.silent) for c in changes] == [(4, True)]
    assert changes[0].seconds == pytest.approx(2.0)
    live.forget(4)
    assert live.alive(np.array([4, 5]), 3 * S)[0].tolist() == [True, True]


def test_poses_without_this_robot_or_its_neighbours_are_reported() -> None:
    ctl, log = controller()
    assert poses(ctl, 1.0, XY[:1], YAW[:1]) is None
    assert log.warnings[-1] == "dropped /swarm/poses: 1 poses, no pose for robot_id 1"
    job = poses(ctl, 1.05, XY[:2], YAW[:2])  # neighbour 2 missing
    np.testing.assert_array_equal(job.neighbor_positions, XY[[0]])
    np.testing.assert_array_equal(job.rest_lengths, [0.2])
    assert "neighbours [0, 2] left out" in log.warnings[-1]


def test_odom_source_uses_the_neighbours_heard_within_the_timeout() -> None:
    ctl, _ = controller(neighbor_source="odom")
    assert poses(ctl, 1.0) is None  # the poses are not its source
    ctl.neighbor_odom(0, 1 * S, *XY[0])
    ctl.neighbor_odom(2, round(0.2 * S), *XY[2])  # 0.8 s old at t = 1
    job = ctl.odom_input(1 * S, *XY[1], YAW[1])
    np.testing.assert_array_equal(job.neighbor_positions, XY[[0, 2]])
    job = ctl.odom_input(round(1.5 * S), *XY[1], YAW[1])  # 2's odometry now 1.3 s old
    np.testing.assert_array_equal(job.neighbor_positions, XY[[0]])
    np.testing.assert_array_equal(job.rest_lengths, [0.2])
    assert job.command.center is None  # no centroid known without the poses


def test_noise_is_seeded_by_seed_and_robot_id() -> None:
    def draws(**changes) -> list[float]:
        """The first noise draws of a fresh controller with these settings."""
        ctl, _ = controller(gains=Gains(), **changes)
        return poses(ctl, 1.0).rng.random(3).tolist()

    assert draws() == draws()
    assert draws() != draws(robot_id=0, neighbors=(1, 2))
    assert draws() != draws(seed=5)
    assert draws(seed=-1) != draws(seed=-1)  # -1: random
    ctl, _ = controller(gains=NOISE_OFF)
    assert poses(ctl, 1.0).rng is None  # noise off: no generator is drawn from
    # Noise switched on at runtime: the robot's own stream, untouched while it was off.
    ctl.configure(settings(gains=Gains()))
    assert poses(ctl, 1.05).rng.random(3).tolist() == draws()


def test_drive_enable_and_limits_reach_the_input() -> None:
    ctl, _ = controller(limits=(0.1, 2.0))
    ctl.set_drive((0.0, 1.0), 0.4)
    job = poses(ctl, 1.0)
    assert (job.command.direction, job.command.omega, job.limits) == ((0.0, 1.0), 0.4, (0.1, 2.0))


def test_rotation_centre_follows_the_live_centroid_only_when_the_supervisor_does() -> None:
    rule = RotationCenterRule(None)
    c1, c2 = np.array([0.1, 0.2]), np.array([0.3, 0.4])
    assert rule.center(c1) is c1  # the scenario's default: the live centroid
    rule.on_poses(1 * S, c1)
    rule.on_center(1 * S, np.array([5.0, -2.0]))  # a fixed point
    assert rule.center(c2).tolist() == [5.0, -2.0]
    rule.on_center(1 * S, c1.copy())  # the centroid of the poses with its stamp
    assert rule.center(c2) is c2
    # A centre that arrives before its poses is decided when they come.
    rule.on_center(2 * S, c2.copy())
    rule.on_poses(2 * S, c2)
    assert rule.follows_centroid
    rule.on_center(3 * S, np.array([9.0, 9.0]))
    rule.on_poses(3 * S, c1)
    assert not rule.follows_centroid and rule.center(c1).tolist() == [9.0, 9.0]
    assert RotationCenterRule(np.array([1.0, 2.0])).center(None).tolist() == [1.0, 2.0]


@pytest.mark.parametrize(
    ("robot_id", "neighbors", "rest", "field"),
    [
        (1, [0, 2], [0.2, 0.25], None),
        (1, [0, 2], [], None),
        (1, [0, 0], [], "repeats"),
        (1, [0, 1], [], "own id"),
        (1, [0, 2_000_000], [], "outside"),
        (1, [0, 2], [0.2], "1 values for 2"),
        (1, [0, 2], [0.2, float("nan")], "must all be in"),
        (1, [0, 2], [1e-9, 0.2], "must all be in"),
    ],
)
def test_sheet_checks(robot_id: int, neighbors: list[int], rest: list[float], field) -> None:
    reason = sheet_error(robot_id, neighbors, rest)
    assert (reason is None) if field is None else (field in reason)
