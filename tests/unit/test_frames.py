"""Yaw and quaternions (aes_ros.frames): the one conversion every part uses."""

from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest
from geometry_msgs.msg import Quaternion

from aes_ros.frames import planar_yaw, quaternion_from_yaw, yaw_from_quaternion
from aes_ros.ros.conversions import quaternion_to_yaw, yaw_to_quaternion


@pytest.mark.parametrize("yaw", [0.0, 0.3, -2.0, np.pi - 1e-9, -np.pi + 1e-9])
def test_yaw_round_trips_and_agrees_with_pybullet_and_the_messages(yaw: float) -> None:
    q = quaternion_from_yaw(yaw)
    np.testing.assert_allclose(q, pb.getQuaternionFromEuler((0.0, 0.0, yaw)), atol=1e-12)
    assert yaw_from_quaternion(q) == pytest.approx(yaw, abs=1e-12)
    assert planar_yaw(*q.tolist()) == pytest.approx(yaw, abs=1e-12)
    msg = yaw_to_quaternion(yaw)
    assert quaternion_to_yaw(msg) == pytest.approx(yaw, abs=1e-12)
    np.testing.assert_allclose([msg.x, msg.y, msg.z, msg.w], q, atol=1e-15)


def test_batched_shapes_and_roll_pitch_are_ignored() -> None:
    yaw = np.linspace(-3.0, 3.0, 12).reshape(3, 4)
    q = quaternion_from_yaw(yaw)
    assert q.shape == (3, 4, 4)
    np.testing.assert_allclose(yaw_from_quaternion(q), yaw, atol=1e-12)
    tilted = pb.getQuaternionFromEuler((0.05, -0.04, 1.2))  # a robot on a slight slope
    assert yaw_from_quaternion(tilted) == pytest.approx(1.2, abs=1e-2)
    assert planar_yaw(*tilted) == pytest.approx(float(yaw_from_quaternion(tilted)), abs=1e-15)
    assert quaternion_to_yaw(Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)) == 0.0
