"""The IR avoidance term (aes_ros.avoidance): its direction, its sign and how it turns a
robot through E5/E6."""

from __future__ import annotations

import numpy as np
import pytest

from aes_ros import ir
from aes_ros.avoidance import AVOIDANCE_RANGE, IR_ANGLES, avoidance_force
from aes_ros.model import Gains, motion_commands

D_MAX = AVOIDANCE_RANGE
NOTHING = np.full(5, D_MAX)


def seen(sensor: int, distance: float) -> np.ndarray:
    """Ranges where only ``sensor`` sees something, ``distance`` [m] away."""
    ranges = NOTHING.copy()
    ranges[sensor] = distance
    return ranges


def test_angles_are_those_the_simulated_sensors_cast_at() -> None:
    np.testing.assert_array_equal(IR_ANGLES, ir.IR_ANGLES)


@pytest.mark.parametrize("heading", [0.0, 1.0, -2.5])
def test_nothing_seen_gives_no_force(heading: float) -> None:
    for ranges in (NOTHING, NOTHING + 0.05, np.full(5, np.nan)):
        force = avoidance_force(ranges, heading, w_o=3.0)
        assert force.shape == (2,)
        assert np.all(force == 0.0)


@pytest.mark.parametrize("heading", [0.0, 0.7, np.pi, -2.0])
def test_obstacle_ahead_pushes_backwards(heading: float) -> None:
    force = avoidance_force(seen(0, 0.02), heading, w_o=2.0)
    ahead = np.array([np.cos(heading), np.sin(heading)])
    left = np.array([-np.sin(heading), np.cos(heading)])
    assert force @ ahead == pytest.approx(-2.0 * (1.0 - 0.02 / D_MAX))
    assert force @ left == pytest.approx(0.0, abs=1e-12)


def test_closer_pushes_harder_and_weight_scales() -> None:
    far, near = (np.linalg.norm(avoidance_force(seen(0, d), 0.0, 1.0)) for d in (0.08, 0.01))
    assert 0.0 < far < near <= 1.0
    np.testing.assert_allclose(
        avoidance_force(seen(1, 0.03), 0.4, 5.0), 5.0 * avoidance_force(seen(1, 0.03), 0.4, 1.0)
    )
    assert np.all(avoidance_force(seen(1, 0.03), 0.4, 0.0) == 0.0)


@pytest.mark.parametrize("sensor, turn", [(1, -1), (3, -1), (2, +1), (4, +1)])
def test_obstacle_on_one_side_turns_the_robot_away(sensor: int, turn: int) -> None:
    """+37°/+67° (left): a force with a negative body-y component, so E6 turns the robot
    clockwise (right); the mirrored sensors turn it left."""
    heading = 0.3
    force = avoidance_force(seen(sensor, 0.03), heading, w_o=1.0)
    left = np.array([-np.sin(heading), np.cos(heading)])
    assert np.sign(force @ left) == turn
    gains = Gains(d_r=0.0, d_theta=0.0)
    u, turn_rate = motion_commands(force, np.asarray(heading), gains, 0.05)
    assert np.sign(turn_rate) == turn
    assert u < gains.v0  # and slows it: the sensor looks forwards of abeam


def test_batch_axes_give_the_same_as_one_robot_at_a_time() -> None:
    rng = np.random.default_rng(5)
    ranges = rng.uniform(0.0, 0.15, (3, 7, 5))
    headings = rng.uniform(-np.pi, np.pi, (3, 7))
    w_o = rng.uniform(0.0, 10.0, (3, 7))
    batch = avoidance_force(ranges, headings, w_o)
    assert batch.shape == (3, 7, 2)
    for b in range(3):
        for i in range(7):
            one = avoidance_force(ranges[b, i], headings[b, i], w_o[b, i])
            np.testing.assert_array_equal(batch[b, i], one)
