"""``geometry_msgs/PoseArray`` in its wire format (CDR), straight from and to numpy.

``/swarm/poses`` is the busiest message of the system: the bridge publishes all
N poses every control step and every robot process reads them. Building N
``Pose`` objects in Python, and rclpy converting them field by field, cost more
than everything else the bridge does (py-spy, 100 robots at 50 Hz). The wire
format is a fixed layout, so both ends can use numpy instead:
:class:`PoseArrayEncoder` fills a preallocated buffer that ``Publisher.publish``
sends as it is, and :func:`decode_pose_array` reads a message taken with
``create_subscription(..., raw=True)``. The bytes are exactly those of
``rclpy.serialization.serialize_message`` (tested), so every other subscriber
(``ros2 topic echo``, bag recorders) sees an ordinary PoseArray.

Layout (XCDR1 as Fast DDS writes it; alignment counts from the end of the
4-byte encapsulation header): ``stamp.sec`` int32, ``stamp.nanosec`` uint32,
``frame_id`` (uint32 length including the NUL, bytes, NUL), pad to 4, uint32
pose count, pad to 8, then per pose 7 float64: position x, y, z and
orientation x, y, z, w.
"""

from __future__ import annotations

import struct

import numpy as np

from aes_ros.ros.conversions import BadMessageError, planar_pose, planar_poses

#: Encapsulation header of little-endian plain CDR.
CDR_LE = b"\x00\x01\x00\x00"
#: float64 values per Pose: position (x, y, z), orientation (x, y, z, w).
POSE_DOUBLES = 7
_HEADER = 4


def _align(offset: int, size: int) -> int:
    return (offset + size - 1) // size * size


def _byte_order(data: bytes, size: int, what: str) -> str:
    """The struct byte order ("<" or ">") of a raw message of at least ``size`` bytes
    (encapsulation header included); BadMessageError if it is shorter or not plain CDR."""
    if len(data) < size or data[0] != 0 or data[1] not in (0, 1):
        raise BadMessageError(f"{what}: not a CDR message")
    return "<" if data[1] == 1 else ">"


def _buffer_with_frame(size: int, frame: bytes) -> bytearray:
    """A zeroed message buffer of ``size`` bytes starting with the encapsulation header
    and a ``std_msgs/Header`` whose frame_id is ``frame`` (NUL included; stamp left 0)."""
    buf = bytearray(size)
    buf[:_HEADER] = CDR_LE
    struct.pack_into("<I", buf, _HEADER + 8, len(frame))
    buf[_HEADER + 12 : _HEADER + 12 + len(frame)] = frame
    return buf


class PoseArrayEncoder:
    """Serialised PoseArrays of ``n`` planar poses in one reused buffer.

    >>> enc = PoseArrayEncoder(2, "odom")
    >>> data = enc.encode(3, 0, np.zeros((2, 2)), np.zeros(2))  # bytes for Publisher.publish
    """

    def __init__(self, n: int, frame_id: str = "odom") -> None:
        name = frame_id.encode() + b"\0"
        count_at = _align(12 + len(name), 4)
        poses_at = _align(count_at + 4, 8) if n else count_at + 4
        self._buf = _buffer_with_frame(_HEADER + poses_at + 8 * POSE_DOUBLES * n, name)
        struct.pack_into("<I", self._buf, _HEADER + count_at, n)
        #: (n, 7) view into the buffer: x, y, z, qx, qy, qz, qw of every pose.
        self.poses = np.frombuffer(
            self._buf, dtype="<f8", count=POSE_DOUBLES * n, offset=_HEADER + poses_at
        ).reshape(n, POSE_DOUBLES)

    def encode(self, sec: int, nanosec: int, positions: np.ndarray, headings: np.ndarray) -> bytes:
        """The message for ``positions: (n, 2)`` [m] and ``headings: (n,)`` [rad] (z = 0)."""
        struct.pack_into("<iI", self._buf, _HEADER, sec, nanosec)
        half = 0.5 * np.asarray(headings)
        self.poses[:, 0:2] = positions
        self.poses[:, 5] = np.sin(half)
        self.poses[:, 6] = np.cos(half)
        return bytes(self._buf)


class OdometryEncoder:
    """Serialised ``nav_msgs/Odometry`` of one planar robot in one reused buffer.

    Only the stamp, x, y, the yaw's quaternion (qz, qw) and the twist (forward,
    sideways, turn) change; the frames are fixed and the covariances stay zero.
    Publishing these bytes (``Publisher.publish`` takes serialised messages) skips
    building a Python message with two 36-element covariances per robot per step.

    >>> enc = OdometryEncoder("odom", "mona_0/base_link")
    >>> data = enc.encode(1, 0, 0.5, 0.0, 0.0, 1.0, 0.05, 0.0, 0.0)  # for Publisher.publish
    """

    def __init__(self, frame_id: str, child_frame_id: str) -> None:
        frame = frame_id.encode() + b"\0"
        child = child_frame_id.encode() + b"\0"
        child_at = _align(12 + len(frame), 4)
        self._pose = _align(child_at + 4 + len(child), 8)
        self._twist = self._pose + 8 * (POSE_DOUBLES + 36)
        self._buf = _buffer_with_frame(_HEADER + self._twist + 8 * (6 + 36), frame)
        struct.pack_into("<I", self._buf, _HEADER + child_at, len(child))
        start = _HEADER + child_at + 4
        self._buf[start : start + len(child)] = child
        struct.pack_into("<d", self._buf, _HEADER + self._pose + 8 * 6, 1.0)  # qw

    def encode(
        self,
        sec: int,
        nanosec: int,
        x: float,
        y: float,
        qz: float,
        qw: float,
        forward: float,
        sideways: float,
        turn: float,
    ) -> bytes:
        """The message: position (x, y, 0) [m], orientation (0, 0, qz, qw), twist
        linear (forward, sideways, 0) [m/s] and angular (0, 0, turn) [rad/s]."""
        buf = self._buf
        struct.pack_into("<iI", buf, _HEADER, sec, nanosec)
        struct.pack_into("<2d", buf, _HEADER + self._pose, x, y)
        struct.pack_into("<2d", buf, _HEADER + self._pose + 40, qz, qw)
        struct.pack_into("<2d", buf, _HEADER + self._twist, forward, sideways)
        struct.pack_into("<d", buf, _HEADER + self._twist + 40, turn)
        return bytes(buf)


#: geometry_msgs/Twist: linear (x, y, z), angular (x, y, z), 6 float64 after the header.
_TWIST = struct.Struct("<4s6d")


def encode_twist(forward: float, turn: float) -> bytes:
    """A planar ``geometry_msgs/Twist`` (linear.x = ``forward`` [m/s], angular.z =
    ``turn`` [rad/s], the rest 0) in its wire format, for ``Publisher.publish``.

    Every robot publishes one per control step; building a Twist object and
    rclpy converting it cost more than half of publishing it.
    """
    return _TWIST.pack(CDR_LE, forward, 0.0, 0.0, 0.0, 0.0, turn)


def decode_twist(data: bytes) -> tuple[float, float]:
    """(linear.x [m/s], angular.z [rad/s]) of a raw ``geometry_msgs/Twist``; the other
    components are not looked at. BadMessageError if it is not a Twist; the values
    are not checked (the caller decides what a non-finite command means)."""
    order = _byte_order(data, _TWIST.size, "Twist")
    forward, _, _, _, _, turn = struct.unpack_from(order + "6d", data, _HEADER)
    return forward, turn


class Vector3StampedEncoder:
    """Serialised ``geometry_msgs/Vector3Stamped`` with a fixed frame, in one reused buffer.

    >>> data = Vector3StampedEncoder("odom").encode(1, 0, 0.5, -0.2)  # z = 0
    """

    def __init__(self, frame_id: str) -> None:
        frame = frame_id.encode() + b"\0"
        self._vector = _align(12 + len(frame), 8)
        self._buf = _buffer_with_frame(_HEADER + self._vector + 8 * 3, frame)

    def encode(self, sec: int, nanosec: int, x: float, y: float) -> bytes:
        """The message stamped (sec, nanosec) with vector (x, y, 0)."""
        struct.pack_into("<iI", self._buf, _HEADER, sec, nanosec)
        struct.pack_into("<2d", self._buf, _HEADER + self._vector, x, y)
        return bytes(self._buf)


def decode_stamp(data: bytes) -> tuple[int, int]:
    """(sec, nanosec) of a raw message that starts with a ``std_msgs/Header`` (its stamp
    is the first field), e.g. ``/swarm/poses``; BadMessageError if too short."""
    order = _byte_order(data, _HEADER + 8, "message with a header")
    return struct.unpack_from(order + "iI", data, _HEADER)


def _header_and_count(data: bytes, what: str) -> tuple[str, int, int, int, int]:
    """Byte order, stamp (sec, nanosec) of the leading ``std_msgs/Header``, and the
    offset and value of the uint32 after it (a sequence's length, or a string's)."""
    order = _byte_order(data, _HEADER + 12, what)
    sec, nanosec, frame_len = struct.unpack_from(order + "iII", data, _HEADER)
    at = _align(12 + frame_len, 4)
    if _HEADER + at + 4 > len(data):
        raise BadMessageError(f"{what}: truncated header")
    (value,) = struct.unpack_from(order + "I", data, _HEADER + at)
    return order, sec, nanosec, at, value


def decode_pose_array(
    data: bytes, expected: int | None = None, frame_id: str | None = None
) -> tuple[int, int, np.ndarray, np.ndarray]:
    """(stamp sec, stamp nanosec, positions (N, 2) [m], headings (N,) [rad]) of a raw PoseArray.

    Raises BadMessageError for a truncated or malformed message, a pose count other
    than ``expected`` or a header frame other than ``frame_id`` (each if given), and
    for the values :func:`aes_ros.ros.conversions.planar_poses` rejects (non-finite,
    out of range).
    """
    order, sec, nanosec, count_at, n = _header_and_count(data, "PoseArray")
    if expected is not None and n != expected:
        raise BadMessageError(f"PoseArray has {n} poses, expected {expected}")
    if frame_id is not None:
        # the frame's bytes end before the count (checked by _header_and_count)
        frame = bytes(data[_HEADER + 12 : _HEADER + count_at]).split(b"\0", 1)[0]
        if frame != frame_id.encode():
            shown = frame[:40].decode("utf-8", "replace")
            raise BadMessageError(f"PoseArray in frame {shown!r}, expected {frame_id!r}")
    poses_at = _align(count_at + 4, 8) if n else count_at + 4
    if _HEADER + poses_at + 8 * POSE_DOUBLES * n > len(data):
        raise BadMessageError(f"PoseArray: {n} poses announced, message too short")
    values = np.frombuffer(
        data, dtype=order + "f8", count=POSE_DOUBLES * n, offset=_HEADER + poses_at
    ).reshape(n, POSE_DOUBLES)
    xy, yaw = planar_poses(values[:, 0:2].astype(float), values[:, 3:7].astype(float))
    return sec, nanosec, xy, yaw


def decode_odometry(data: bytes) -> tuple[int, int, float, float, float]:
    """(stamp sec, stamp nanosec, x [m], y [m], yaw [rad]) of a raw ``nav_msgs/Odometry``.

    Reads only the header's stamp and the pose (the covariances and the twist are
    not looked at): a robot in the ``odom`` source receives one message per neighbour
    per step, and deserialising each into Python objects was most of its cost.
    Raises BadMessageError for a truncated or malformed message and for a position
    or orientation that :func:`aes_ros.ros.conversions.planar_pose` rejects.
    """
    order, sec, nanosec, child_at, child_len = _header_and_count(data, "Odometry")
    pose_at = _align(child_at + 4 + child_len, 8)
    if _HEADER + pose_at + 8 * POSE_DOUBLES > len(data):
        raise BadMessageError("Odometry: truncated pose")
    x, y, _, qx, qy, qz, qw = struct.unpack_from(order + "7d", data, _HEADER + pose_at)
    x, y, yaw = planar_pose(x, y, qx, qy, qz, qw)
    return sec, nanosec, x, y, yaw


#: ``sensor_msgs/Image`` encodings the camera and the tracker use, and their channels.
IMAGE_ENCODINGS = {"mono8": 1, "rgb8": 3, "bgr8": 3}


def encode_image(sec: int, nanosec: int, frame_id: str, image: np.ndarray, encoding: str) -> bytes:
    """A ``sensor_msgs/Image`` of ``image: (H, W)`` or ``(H, W, 3)`` uint8 in its wire
    format, for ``Publisher.publish``: a 1.2 MB frame goes out as one copy of its
    pixels instead of rclpy converting a Python sequence of them."""
    height, width = image.shape[:2]
    step = width * IMAGE_ENCODINGS[encoding]
    frame, code = frame_id.encode() + b"\0", encoding.encode() + b"\0"
    at = _align(12 + len(frame), 4)  # height, width
    at_code = at + 8
    at_flag = at_code + 4 + len(code)  # is_bigendian (uint8)
    at_step = _align(at_flag + 1, 4)
    at_data = at_step + 4  # uint32 length, then the bytes
    buf = _buffer_with_frame(_HEADER + at_data + 4 + height * step, frame)
    struct.pack_into("<iI", buf, _HEADER, sec, nanosec)
    struct.pack_into("<III", buf, _HEADER + at, height, width, len(code))
    buf[_HEADER + at_code + 4 : _HEADER + at_flag] = code
    struct.pack_into("<II", buf, _HEADER + at_step, step, height * step)
    buf[_HEADER + at_data + 4 :] = np.ascontiguousarray(image, dtype=np.uint8).tobytes()
    return bytes(buf)


def decode_image(data: bytes) -> tuple[int, int, str, np.ndarray]:
    """(stamp sec, stamp nanosec, encoding, pixels (H, W) or (H, W, 3) uint8, a view of
    ``data``) of a raw ``sensor_msgs/Image``. BadMessageError for a truncated or
    malformed message, an encoding other than :data:`IMAGE_ENCODINGS`, or a step or
    data length that does not fit height × width."""
    order, sec, nanosec, at, height = _header_and_count(data, "Image")
    if _HEADER + at + 12 > len(data):
        raise BadMessageError("Image: truncated")
    width, code_len = struct.unpack_from(order + "II", data, _HEADER + at + 4)
    at_flag = at + 12 + code_len
    if code_len == 0 or _HEADER + at_flag + 1 > len(data):
        raise BadMessageError("Image: truncated encoding")
    encoding = bytes(data[_HEADER + at + 12 : _HEADER + at_flag - 1]).decode("ascii", "replace")
    if encoding not in IMAGE_ENCODINGS:
        known = ", ".join(IMAGE_ENCODINGS)
        raise BadMessageError(f"Image: encoding {encoding!r}; this tracker reads {known}")
    at_step = _align(at_flag + 1, 4)
    if _HEADER + at_step + 8 > len(data):
        raise BadMessageError("Image: truncated")
    step, size = struct.unpack_from(order + "II", data, _HEADER + at_step)
    channels = IMAGE_ENCODINGS[encoding]
    if height == 0 or width == 0 or step != width * channels or size != height * step:
        raise BadMessageError(
            f"Image: {width}x{height} {encoding} with step {step} and {size} bytes of data"
        )
    if _HEADER + at_step + 8 + size > len(data):
        raise BadMessageError(f"Image: {size} bytes of data announced, message too short")
    pixels = np.frombuffer(data, np.uint8, count=size, offset=_HEADER + at_step + 8)
    shape = (height, width) if channels == 1 else (height, width, channels)
    return sec, nanosec, encoding, pixels.reshape(shape)
