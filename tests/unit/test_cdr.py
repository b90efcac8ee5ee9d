"""The numpy wire formats (PoseArray, Image) equal rclpy's serialisation, both ways."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("rclpy")

from geometry_msgs.msg import PoseArray
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Image

from aes_ros.ros.cdr import PoseArrayEncoder, decode_image, decode_pose_array, encode_image
from aes_ros.ros.conversions import BadMessageError, arrays_to_poses, poses_to_arrays


def message(positions: np.ndarray, headings: np.ndarray, frame: str) -> PoseArray:
    msg = PoseArray(poses=arrays_to_poses(positions, headings))
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 345_000_000
    return msg


@pytest.mark.parametrize("n", [0, 1, 7, 100])
@pytest.mark.parametrize("frame", ["odom", "od", "world"])
def test_encoder_writes_the_bytes_rclpy_writes(n: int, frame: str) -> None:
    rng = np.random.default_rng(n)
    pos, head = rng.normal(size=(n, 2)), rng.uniform(-np.pi, np.pi, n)
    data = PoseArrayEncoder(n, frame).encode(12, 345_000_000, pos, head)
    ref = serialize_message(message(pos, head, frame))
    # Padding bytes are unspecified in CDR: compare the decoded message and the length.
    assert len(data) == len(ref)
    back = deserialize_message(data, PoseArray)
    assert back == deserialize_message(ref, PoseArray)
    assert back.header.frame_id == frame and len(back.poses) == n


@pytest.mark.parametrize("n", [0, 3, 100])
def test_decoder_reads_what_rclpy_writes(n: int) -> None:
    rng = np.random.default_rng(n)
    pos, head = rng.normal(size=(n, 2)), rng.uniform(-np.pi, np.pi, n)
    msg = message(pos, head, "odom")
    sec, nanosec, xy, yaw = decode_pose_array(serialize_message(msg))
    ref_xy, ref_yaw = poses_to_arrays(msg)
    assert (sec, nanosec) == (12, 345_000_000)
    assert np.array_equal(xy, ref_xy) and np.array_equal(yaw, ref_yaw)  # bit for bit


def test_decoder_rejects_truncated_and_non_finite_messages() -> None:
    pos, head = np.zeros((4, 2)), np.zeros(4)
    data = serialize_message(message(pos, head, "odom"))
    for bad in (b"", data[:10], data[:-8], b"\x07" + data[1:]):
        with pytest.raises(BadMessageError):
            decode_pose_array(bad)
    for value in (np.nan, np.inf, 1e9):  # the checks of poses_to_arrays, too
        pos[2, 1] = value
        msg = message(pos, head, "odom")
        with pytest.raises(BadMessageError):
            decode_pose_array(serialize_message(msg))
        with pytest.raises(BadMessageError):
            poses_to_arrays(msg)


@pytest.mark.parametrize("frame", ["odom", "o", "world_frame"])
@pytest.mark.parametrize("child", ["mona_3/base_link", "b", ""])
def test_odometry_decoder_reads_what_rclpy_wrote(frame: str, child: str) -> None:
    from nav_msgs.msg import Odometry

    from aes_ros.ros.cdr import decode_odometry
    from aes_ros.ros.conversions import odom_to_pose

    rng = np.random.default_rng(len(frame) + len(child))
    for _ in range(20):
        msg = Odometry(child_frame_id=child)
        msg.header.frame_id = frame
        msg.header.stamp.sec, msg.header.stamp.nanosec = int(rng.integers(1e6)), 123_456_789
        (msg.pose.pose,) = arrays_to_poses(rng.normal(size=(1, 2)), rng.uniform(-3, 3, 1))
        msg.twist.twist.linear.x = 0.05  # after the pose: not read
        sec, nanosec, x, y, yaw = decode_odometry(serialize_message(msg))
        stamp_ns, *pose = odom_to_pose(msg)
        assert sec * 10**9 + nanosec == stamp_ns
        assert (x, y, yaw) == pytest.approx(pose, abs=1e-12)


def test_odometry_decoder_refuses_bad_messages() -> None:
    from nav_msgs.msg import Odometry

    from aes_ros.ros.cdr import decode_odometry

    good = serialize_message(Odometry())
    for data in (good[:30], b"\x07" + good[1:], b""):
        with pytest.raises(BadMessageError):
            decode_odometry(data)
    msg = Odometry()
    msg.pose.pose.position.x = float("nan")
    with pytest.raises(BadMessageError):
        decode_odometry(serialize_message(msg))


@pytest.mark.parametrize("child", ["mona_0/base_link", "mona_123/base_link", "b"])
def test_odometry_encoder_writes_what_rclpy_reads_back(child: str) -> None:
    from nav_msgs.msg import Odometry

    from aes_ros.ros.cdr import OdometryEncoder

    encoder = OdometryEncoder("odom", child)
    rng = np.random.default_rng(len(child))
    for _ in range(10):
        x, y, fwd, side, turn = rng.normal(size=5)
        yaw = rng.uniform(-3, 3)
        qz, qw = np.sin(yaw / 2), np.cos(yaw / 2)
        sec, nanosec = int(rng.integers(1e6)), int(rng.integers(1e9))
        msg = Odometry(child_frame_id=child)
        msg.header.frame_id = "odom"
        msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
        p = msg.pose.pose
        p.position.x, p.position.y, p.orientation.z, p.orientation.w = x, y, qz, qw
        t = msg.twist.twist
        t.linear.x, t.linear.y, t.angular.z = fwd, side, turn
        data = encoder.encode(sec, nanosec, x, y, qz, qw, fwd, side, turn)
        # equal as messages (rclpy leaves whatever was in memory in the padding bytes)
        assert deserialize_message(data, Odometry) == msg
        assert len(data) == len(serialize_message(msg))


def test_twist_wire_format_round_trips_through_rclpy() -> None:
    from geometry_msgs.msg import Twist

    from aes_ros.ros.cdr import decode_twist, encode_twist

    msg = Twist()
    msg.linear.x, msg.angular.z = 0.123, -4.5
    assert encode_twist(0.123, -4.5) == serialize_message(msg)
    msg.linear.y = 7.0  # read, but not used, by decode_twist
    assert decode_twist(serialize_message(msg)) == (0.123, -4.5)
    nan = decode_twist(encode_twist(float("nan"), 0.0))
    assert np.isnan(nan[0])  # not the decoder's business: the bridge drops it
    for data in (b"", b"\x07" + encode_twist(1.0, 1.0)[1:], encode_twist(1.0, 1.0)[:40]):
        with pytest.raises(BadMessageError):
            decode_twist(data)


@pytest.mark.parametrize("frame", ["odom", "od", "world_frame"])
def test_vector3_stamped_encoder_writes_what_rclpy_reads_back(frame: str) -> None:
    from geometry_msgs.msg import Vector3Stamped

    from aes_ros.ros.cdr import Vector3StampedEncoder

    encoder = Vector3StampedEncoder(frame)
    for sec, x, y in ((1, 0.5, -0.25), (2_000_000, -1e-9, 3e5)):
        msg = Vector3Stamped()
        msg.header.frame_id = frame
        msg.header.stamp.sec, msg.header.stamp.nanosec = sec, 999_999_999
        msg.vector.x, msg.vector.y = x, y
        data = encoder.encode(sec, 999_999_999, x, y)
        assert deserialize_message(data, Vector3Stamped) == msg
        assert len(data) == len(serialize_message(msg))


def image_message(pixels: np.ndarray, encoding: str, frame: str) -> Image:
    msg = Image(height=pixels.shape[0], width=pixels.shape[1], encoding=encoding)
    msg.step = pixels.shape[1] * (pixels.shape[2] if pixels.ndim == 3 else 1)
    msg.data = pixels.tobytes()
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = 7, 50_000_000
    return msg


@pytest.mark.parametrize(
    ("shape", "encoding", "frame"),
    [((3, 5), "mono8", "arena_camera"), ((4, 2, 3), "rgb8", "c"), ((960, 1280), "mono8", "")],
)
def test_image_wire_format_both_ways(shape: tuple, encoding: str, frame: str) -> None:
    pixels = np.random.default_rng(1).integers(0, 256, shape, dtype=np.uint8)
    data = encode_image(7, 50_000_000, frame, pixels, encoding)
    ref = serialize_message(image_message(pixels, encoding, frame))
    assert len(data) == len(ref)
    assert deserialize_message(data, Image) == deserialize_message(ref, Image)
    sec, nanosec, enc, back = decode_image(ref)
    assert (sec, nanosec, enc) == (7, 50_000_000, encoding)
    assert back.shape == shape and np.array_equal(back, pixels)


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        ({"encoding": "yuv422"}, "encoding 'yuv422'"),
        ({"step": 4}, "step 4"),
        ({"height": 0, "data": b""}, "5x0"),
        ({"data": bytes(14)}, "14 bytes"),
    ],
)
def test_a_bad_image_is_refused_with_the_reason(change: dict, reason: str) -> None:
    msg = image_message(np.zeros((3, 5), np.uint8), "mono8", "c")
    for field, value in change.items():
        setattr(msg, field, value)
    with pytest.raises(BadMessageError, match=reason):
        decode_image(serialize_message(msg))
    with pytest.raises(BadMessageError):
        decode_image(serialize_message(msg)[:30])


@pytest.mark.parametrize("frame", ["map", "odo", "odomx", ""])
def test_decoder_refuses_poses_in_another_frame_when_asked(frame: str) -> None:
    pos, head = np.zeros((2, 2)), np.zeros(2)
    assert decode_pose_array(PoseArrayEncoder(2, "odom").encode(1, 0, pos, head), frame_id="odom")
    data = PoseArrayEncoder(2, frame).encode(1, 0, pos, head)
    with pytest.raises(BadMessageError, match=f"frame '{frame}', expected 'odom'"):
        decode_pose_array(data, frame_id="odom")
    assert decode_pose_array(data)[2].shape == (2, 2)  # not asked: any frame
