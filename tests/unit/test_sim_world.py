"""The pybullet world without ROS: kinematic = the offline model, dynamic = physics."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from aes_ros.model import unicycle_step
from aes_ros.scenario import load
from sim_bridge.mona import MonaGeometry, urdf
from sim_bridge.world import World


def body_centres(world: World) -> np.ndarray:
    """(N, 2) body-cylinder centres read back from pybullet."""
    centres, _ = world._base_states()
    return centres[:, :2]


def test_urdf_follows_the_parameters():
    geometry = MonaGeometry(wheel_radius=0.0128)
    root = ET.fromstring(urdf(geometry))
    links = {link.get("name") for link in root.iter("link")}
    assert links == {"base_link", "left_wheel", "right_wheel", "caster"}
    wheel = root.find("link[@name='left_wheel']/visual/geometry/cylinder")
    assert float(wheel.get("radius")) == pytest.approx(0.0128)
    ball = root.find("link[@name='left_wheel']/collision/geometry/sphere")  # touches the floor
    assert float(ball.get("radius")) == pytest.approx(0.0128)  # where the cylinder would
    body = root.find("link[@name='base_link']/collision/geometry/cylinder")
    assert float(body.get("radius")) == pytest.approx(0.04)
    joint = root.find("joint[@name='left_wheel_joint']/origin").get("xyz").split()
    assert [float(v) for v in joint] == pytest.approx([0.0, 0.039, 0.0128])
    masses = [float(m.get("value")) for m in root.iter("mass")]
    assert sum(masses) == pytest.approx(geometry.mass)


def test_wheel_speeds_saturate_keeping_the_curvature():
    g = MonaGeometry()
    left, right = g.wheel_speeds(np.array([0.05, 1.0]), np.array([0.0, 1.0]))
    assert left[0] == pytest.approx(0.05 / 0.015) and right[0] == pytest.approx(0.05 / 0.015)
    assert max(abs(left[1]), abs(right[1])) == pytest.approx(g.max_wheel_speed)
    # curvature kept: (right - left) / (right + left) as commanded
    assert (right[1] - left[1]) / (right[1] + left[1]) == pytest.approx(0.039)


@pytest.mark.parametrize("n", [1, 7, 100])
def test_kinematic_step_is_the_offline_unicycle_step(n):
    rng = np.random.default_rng(n)
    pos, head = rng.uniform(-1, 1, (n, 2)), rng.uniform(-np.pi, np.pi, n)
    with World(pos, head, mode="kinematic", dt=0.05) as world:
        for _ in range(5):
            u, turn = rng.uniform(-0.2, 0.2, n), rng.uniform(-2, 2, n)
            world.step((u, turn))
            pos, head = unicycle_step(pos, head, u, turn, 0.05)
            got_pos, got_head = world.poses()
            np.testing.assert_array_equal(got_pos, pos)
            np.testing.assert_array_equal(got_head, head)
        # pybullet's bodies were moved along (body centre axle_offset ahead)
        a = world.geometry.axle_offset
        ahead = pos + a * np.stack([np.cos(head), np.sin(head)], -1)
        np.testing.assert_allclose(body_centres(world), ahead, atol=1e-9)
        forward, _, turn_rate = world.velocities()
        np.testing.assert_array_equal(forward, u)
        np.testing.assert_array_equal(turn_rate, turn)


def test_kinematic_mode_clips_to_the_limits():
    with World(np.zeros((1, 2)), np.zeros(1), limits=(0.13, 3.4)) as world:
        world.step((np.array([1.0]), np.array([-10.0])))
        pos, head = world.poses()
        assert pos[0] == pytest.approx([0.13 * 0.05, 0.0])
        assert head[0] == pytest.approx(-3.4 * 0.05)


def test_initial_state_comes_from_the_scenario():
    scenario = load("linear").with_robots(16)
    pos, head = scenario.initial_state(3)
    with World(pos, head) as world:
        got_pos, got_head = world.poses()
    np.testing.assert_array_equal(got_pos, pos)
    np.testing.assert_array_equal(got_head, head)


def test_dynamic_drives_forward_and_turns_with_the_right_sign():
    pos = np.array([[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]])
    head = np.array([0.0, np.pi / 2, 0.0])
    with World(pos, head, mode="dynamic", cmd_timeout=10.0) as world:
        assert world.substeps == 12
        commands = (np.array([0.1, 0.1, 0.0]), np.array([0.0, 0.0, 1.0]))
        for _ in range(20):  # 1 s
            world.step(commands)
        got_pos, got_head = world.poses()
        forward, sideways, turn = world.velocities()
    # robot 0 drove ~0.1 m east, robot 1 ~0.1 m north (wheel accelerating, slip)
    assert got_pos[0] == pytest.approx([0.1, 0.0], abs=0.01)
    assert got_pos[1] == pytest.approx([0.5, 0.1], abs=0.01)
    assert got_head[:2] == pytest.approx([0.0, np.pi / 2], abs=0.05)
    # robot 2 turned counter-clockwise on the spot, ~1 rad
    assert got_pos[2] == pytest.approx([1.0, 0.0], abs=0.005)
    assert got_head[2] == pytest.approx(1.0, abs=0.1)
    assert forward[:2] == pytest.approx([0.1, 0.1], abs=0.01)
    assert turn[2] == pytest.approx(1.0, abs=0.05)
    assert np.all(np.abs(sideways) < 0.005)


def test_dynamic_wheels_saturate_at_the_mona_top_speed():
    with World(np.zeros((1, 2)), np.zeros(1), mode="dynamic", cmd_timeout=10.0) as world:
        for _ in range(20):
            world.step((np.array([1.0]), np.array([0.0])))
        forward, _, _ = world.velocities()
    assert forward[0] == pytest.approx(world.geometry.max_linear_speed, rel=0.05)


def test_dynamic_robots_collide_rather_than_pass_through():
    # head on, 0.2 m apart, both driving at each other for 3 s
    pos, head = np.array([[0.0, 0.0], [0.2, 0.0]]), np.array([0.0, np.pi])
    closest = np.inf
    with World(pos, head, mode="dynamic", cmd_timeout=10.0) as world:
        for _ in range(60):
            world.step((np.array([0.1, 0.1]), np.zeros(2)))
            c = body_centres(world)
            closest = min(closest, np.linalg.norm(c[0] - c[1]))
    assert closest > 2 * world.geometry.body_radius - 0.002
    # ... while in kinematic mode they pass through each other, as in the paper's Webots setup
    with World(pos, head, mode="kinematic") as world:
        for _ in range(60):
            world.step((np.array([0.1, 0.1]), np.zeros(2)))
        got, _ = world.poses()
    assert got[0, 0] > got[1, 0]


@pytest.mark.parametrize("mode", ["kinematic", "dynamic"])
def test_stale_command_stops_the_robot(mode):
    with World(
        np.array([[0.0, 0.0], [0.0, 0.5]]), np.zeros(2), mode=mode, cmd_timeout=0.2
    ) as world:
        world.set_command(0, 0.1, 0.0)
        world.set_command(1, 0.1, 0.0)
        path = []
        for _ in range(20):
            world.set_command(1, 0.1, 0.0)  # robot 1 keeps sending, robot 0 fell silent
            world.step()
            path.append(world.poses()[0][:, 0])
        path = np.array(path)
    # 0.2 s timeout at 0.05 s steps: robot 0 moves for 5 steps, then stops
    if mode == "kinematic":
        np.testing.assert_allclose(path[4, 0], 0.025)
        np.testing.assert_array_equal(path[5:, 0], path[5, 0])
    else:
        assert np.ptp(path[12:, 0]) < 1e-3  # at rest after braking
    assert path[-1, 1] > path[-1, 0] + 0.03  # robot 1 kept going
    assert path[-1, 1] - path[-2, 1] > 0.004


def test_reset_restores_the_initial_state_and_stops_everyone():
    pos, head = np.array([[0.0, 0.0], [0.3, 0.0]]), np.array([0.5, -0.5])
    with World(pos, head, mode="dynamic", cmd_timeout=10.0) as world:
        for _ in range(10):
            world.step((np.full(2, 0.1), np.full(2, 0.5)))
        world.reset()
        got_pos, got_head = world.poses()
        np.testing.assert_allclose(got_pos, pos, atol=1e-6)
        np.testing.assert_allclose(got_head, head, atol=1e-6)
        t = world.time
        for _ in range(5):
            world.step()
        assert world.time == pytest.approx(t + 0.25)
        np.testing.assert_allclose(world.poses()[0], pos, atol=1e-3)


def test_bad_mode_is_rejected():
    with pytest.raises(ValueError, match="mode"):
        World(np.zeros((1, 2)), np.zeros(1), mode="teleport")
