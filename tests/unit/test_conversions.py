"""Property-based tests (hypothesis) of the ROS boundary and the control law behind it.

Any message :mod:`aes_ros.ros.conversions` is given is either rejected
(BadMessageError) or turned into finite, bounded arrays; the control law is finite
for every input that boundary lets through. tests/unit/test_properties.py covers the
core on small scenes; tests/system/test_bad_input.py sends bad input to the nodes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from geometry_msgs.msg import Pose, PoseArray, Twist
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from nav_msgs.msg import Odometry

from aes_ros import model
from aes_ros.model import Gains, SwarmCommand
from aes_ros.params import PARAMS
from aes_ros.ros.conversions import (
    MAX_COORDINATE,
    BadMessageError,
    arrays_to_poses,
    odom_to_pose,
    point_to_array,
    poses_to_arrays,
    twist_to_drive,
)
from robot_node.controller import REST_LENGTH_RANGE

any_float = st.floats(allow_nan=True, allow_infinity=True)
finite = st.floats(allow_nan=False, allow_infinity=False)
accepted = st.floats(-MAX_COORDINATE, MAX_COORDINATE)


def make_pose(x: float, y: float, q: tuple[float, float, float, float]) -> Pose:
    pose = Pose()
    pose.position.x, pose.position.y = x, y
    o = pose.orientation
    o.x, o.y, o.z, o.w = q
    return pose


@settings(max_examples=300, deadline=None)
@given(values=st.lists(st.tuples(any_float, any_float, st.tuples(*[any_float] * 4)), max_size=6))
def test_conversions_reject_or_return_finite_bounded_arrays(values) -> None:
    """Any PoseArray, Odometry or Point: either BadMessageError or finite positions
    within ±MAX_COORDINATE and headings in [-π, π] — never a NaN for the model."""
    with np.errstate(over="raise", invalid="raise", divide="raise"):  # overflow = a bug
        msg = PoseArray()
        msg.poses = [make_pose(x, y, q) for x, y, q in values]
        try:
            xy, yaw = poses_to_arrays(msg)
        except BadMessageError:
            pass
        else:
            assert xy.shape == (len(values), 2) and yaw.shape == (len(values),)
            assert np.all(np.abs(xy) <= MAX_COORDINATE) and np.all(np.abs(yaw) <= math.pi)
        for pose in msg.poses:
            odom = Odometry()
            odom.pose.pose = pose
            try:
                _, x, y, heading = odom_to_pose(odom)
            except BadMessageError:
                continue
            assert abs(x) <= MAX_COORDINATE and abs(y) <= MAX_COORDINATE
            assert abs(heading) <= math.pi
            assert point_to_array(pose.position) == pytest.approx([x, y])


@settings(max_examples=200, deadline=None)
@given(xy=arrays(float, st.tuples(st.integers(0, 6), st.just(2)), elements=accepted),
       yaw=st.floats(-math.pi, math.pi))  # fmt: skip
def test_poses_round_trip(xy, yaw) -> None:
    headings = np.full(len(xy), yaw)
    msg = PoseArray()
    msg.poses = arrays_to_poses(xy, headings)
    back, back_yaw = poses_to_arrays(msg, expected=len(xy))
    np.testing.assert_array_equal(back, xy)
    np.testing.assert_allclose(np.angle(np.exp(1j * (back_yaw - headings))), 0.0, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(values=st.tuples(any_float, any_float, any_float))
def test_twist_to_drive_is_finite_or_rejected(values) -> None:
    msg = Twist()
    msg.linear.x, msg.linear.y, msg.angular.z = values
    if all(math.isfinite(v) for v in values):
        (vx, vy), w = twist_to_drive(msg)
        assert (vx, vy, w) == values
    else:
        with pytest.raises(BadMessageError):
            twist_to_drive(msg)


direction_part = st.floats(PARAMS["direction"].low, PARAMS["direction"].high)


@settings(max_examples=300, deadline=None)
@given(
    own=st.tuples(accepted, accepted),
    heading=st.floats(-math.pi, math.pi),
    others=arrays(float, st.tuples(st.integers(0, 6), st.just(2)),
                  elements=st.sampled_from([0.0, MAX_COORDINATE, -MAX_COORDINATE]) | accepted),
    rest=st.floats(*REST_LENGTH_RANGE),
    direction=st.tuples(direction_part, direction_part),
    omega=st.floats(PARAMS["omega"].low, PARAMS["omega"].high),
    center=st.none() | st.tuples(accepted, accepted),
    coincident=st.booleans(),
    clip=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)  # fmt: skip
def test_control_law_is_finite_for_everything_the_boundary_accepts(
    own, heading, others, rest, direction, omega, center, coincident, clip, seed
) -> None:
    """Every input a robot node accepts (positions within ±MAX_COORDINATE, rest lengths
    and swarm command within their parameter ranges, neighbours possibly on top of the
    robot) gives a finite command and force: nothing non-finite reaches cmd_vel."""
    if coincident:
        others = np.vstack([others, [own]])
    out = model.robot_command(
        np.array(own), heading, others, np.full(len(others), rest), Gains(),
        SwarmCommand(direction, omega, center), 0.05, rng=np.random.default_rng(seed),
        limits=(0.13, 3.4) if clip else None,
    )  # fmt: skip
    assert math.isfinite(out.linear) and math.isfinite(out.angular)
    assert np.all(np.isfinite(out.force))
