"""The tracker node ``/tracker``: robot poses from an overhead camera's markers.

See docs/design.md#tracking.

Start it (the launch does, with ``--tracking camera``)::

    aes-tracker --ros-args -p num_robots:=16 -p layout:=arena.yaml -p use_sim_time:=true
    aes-tracker --source /dev/video0 --ros-args -p num_robots:=16 -p calibration:=cal.yaml
    aes-tracker --source run.mp4 --ros-args -p num_robots:=16 -p calibration:=cal.yaml

From ``/arena_camera/image_raw`` + ``/arena_camera/camera_info`` (or, with
``--source``, frames read by OpenCV from a camera device or a video file, stamped
with the wall clock when read) it finds the robots' ArUco markers
(:mod:`aes_ros.tracking.detection`), maps them to the arena through a calibration
(:mod:`aes_ros.tracking.calibration`, :mod:`aes_ros.tracking.pose`) and publishes
``/swarm/poses`` with the bridge's contract: index = robot id, stamp = the frame's
exposure time. A robot not seen in a frame keeps its last pose and its age grows
(:mod:`aes_ros.tracking.tracks`); nothing is published before every robot has been
seen once. ``/diagnostics`` says once a second what it sees: detected / expected,
the missing and the lost ids, each robot's age, the reprojection error, frames/s.

The calibration: a file (``calibration``, made by ``aes-swarm calibrate``), or, when
none is given, one computed from the first frame that shows the reference markers
of ``layout`` (with the camera_info's intrinsics), as a lab would at the start of
a session.
"""

from __future__ import annotations

import functools
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseArray
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image

from aes_ros.arena_layout import CalibrationError, load_layout
from aes_ros.markers import RobotMarker, reference_ids
from aes_ros.params import ParameterError
from aes_ros.ros import interface as names
from aes_ros.ros import parameters as rp
from aes_ros.ros.cdr import PoseArrayEncoder, decode_image
from aes_ros.ros.conversions import BadMessageError
from aes_ros.ros.diagnostics import TRACKER_STATUS
from aes_ros.ros.node_tools import ThrottledWarnings
from aes_ros.ros.qos import IMAGES, LATCHED, SENSOR, STREAM_WRITER
from aes_ros.ros.spin import run_node_process
from aes_ros.tracking.calibration import Calibration, calibrate
from aes_ros.tracking.camera_info import intrinsics, load_camera_info
from aes_ros.tracking.detection import detect_markers
from aes_ros.tracking.pose import marker_poses
from aes_ros.tracking.tracks import Tracks


class TrackerNode(Node):
    """The tracker ``tracker``.

    Parameters (read at start)
    --------------------------
    num_robots : int, the swarm's size (robot i wears marker id i).
    calibration : str, a calibration file (``aes-swarm calibrate``); empty: compute
        one from the first frame with ``layout``'s reference markers.
    layout : str, the arena layout file (reference markers, marker height).
    camera_info : str, the camera's intrinsics (ROS camera_info YAML) for a ``source``
        with no camera_info topic, to calibrate from its first frame with ``layout``.
    lost_after : float [s], default 0.5: a robot unseen this long is reported lost.

    ``source``: None to read the camera topics; a device (``/dev/video0``, ``0``) or a
    video file to read frames from with OpenCV, paced at the file's frame rate, each
    stamped with this node's clock when read.
    """

    def __init__(self, source: str | None = None, **kwargs: Any) -> None:
        super().__init__(names.TRACKER_NODE, **kwargs)
        self._warn = ThrottledWarnings(self.get_logger())
        ro = {"read_only": True}
        n = self.declare_parameter(
            "num_robots", 1, rp.int_descriptor("robots (robot i wears id i)", 1, 249, **ro)
        ).value
        calibration = self.declare_parameter(
            "calibration", "", rp.text_descriptor("calibration file; empty: from layout", **ro)
        ).value
        layout = self.declare_parameter(
            "layout", "", rp.text_descriptor("arena layout file (reference markers)", **ro)
        ).value
        camera_info = self.declare_parameter(
            "camera_info", "", rp.text_descriptor("intrinsics YAML for --source", **ro)
        ).value
        self.lost_after = self.declare_parameter(
            "lost_after", 0.5, rp.float_descriptor("unseen this long: lost", "s", 0.01, 60.0)
        ).value
        if not calibration and not layout:
            raise ParameterError("calibration, layout: give one (the camera must be calibrated)")
        try:
            self.layout = load_layout(Path(layout)) if layout else None
            self.calibration = Calibration.load(Path(calibration)) if calibration else None
            self.info = load_camera_info(Path(camera_info)) if camera_info else None
        except CalibrationError as exc:
            raise ParameterError(f"calibration, layout or camera_info: {exc}") from None
        self.marker = RobotMarker()
        # without a layout, the top ids are taken for reference markers (their convention)
        references = (
            [r.marker_id for r in self.layout.references] if self.layout else reference_ids(16)
        )
        self.tracks = Tracks(n, references=frozenset(references))
        self.encoder = PoseArrayEncoder(n, names.WORLD_FRAME)
        self.frames = 0
        self._frame_walls: list[float] = []
        self._reprojection = float("nan")
        self._stamp_ns = 0

        self.poses_pub = self.create_publisher(PoseArray, names.POSES, STREAM_WRITER)
        self.diagnostics_pub = self.create_publisher(DiagnosticArray, names.DIAGNOSTICS, LATCHED)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(1.0, self.on_diagnostics, clock=steady)
        self.capture = None
        if source is None:
            self.create_subscription(CameraInfo, names.CAMERA_INFO, self.on_camera_info, SENSOR)
            self.create_subscription(Image, names.CAMERA_IMAGE, self.on_image, IMAGES, raw=True)
        else:
            self.capture = open_source(source)
            fps = self.capture.get(cv2.CAP_PROP_FPS)
            period = 1.0 / fps if 0.5 <= fps <= 240.0 else 0.05
            self.get_logger().info(f"reading {source} at {1.0 / period:g} frames/s")
            self.source = source
            self.create_timer(period, self.on_capture, clock=steady)

    # --- inputs -----------------------------------------------------------------------

    def on_camera_info(self, msg: CameraInfo) -> None:
        """The camera's intrinsics; a broken one is dropped and the last good one kept."""
        try:
            K, dist = intrinsics(msg.k, msg.d)
        except CalibrationError as exc:
            self._warn(f"dropped camera_info: {exc}")
            return
        if msg.width == 0 or msg.height == 0:
            self._warn(f"dropped camera_info: image size {msg.width}x{msg.height}")
            return
        self.info = (K, dist, (int(msg.width), int(msg.height)))

    def on_image(self, data: bytes) -> None:
        try:
            sec, nanosec, _, pixels = decode_image(data)
        except BadMessageError as exc:
            self._warn(f"dropped {names.CAMERA_IMAGE}: {exc}")
            return
        self.track(sec * 1_000_000_000 + nanosec, pixels)

    def on_capture(self) -> None:
        """The next frame of ``--source``, stamped now; at the end of a file, stop."""
        if self.capture is None:
            return
        ok, frame = self.capture.read()
        if not ok:
            self.get_logger().info(f"{self.source}: no more frames after {self.frames}")
            self.capture.release()
            self.capture = None
            return
        self.track(self.get_clock().now().nanoseconds, frame)

    # --- the work ---------------------------------------------------------------------

    def track(self, stamp_ns: int, pixels: np.ndarray) -> None:
        """One frame exposed at ``stamp_ns``: detect, map, remember, publish."""
        image = pixels if pixels.ndim == 2 else cv2.cvtColor(pixels, cv2.COLOR_BGR2GRAY)
        if not self._calibrated(image):
            return
        size = (image.shape[1], image.shape[0])
        if size != self.calibration.image_size:
            self._warn(
                f"dropped a frame of {size[0]}x{size[1]} px: the calibration is for "
                f"{self.calibration.image_size[0]}x{self.calibration.image_size[1]}"
            )
            return
        detected = detect_markers(image)
        if len(detected.duplicates):
            self._warn(f"ignored marker ids seen twice in one frame: {list(detected.duplicates)}")
        positions, headings, error = marker_poses(
            detected.ids, detected.corners, self.calibration, self.marker
        )
        report = self.tracks.update(stamp_ns, detected.ids, positions, headings)
        if report.unknown:
            self._warn(f"ignored unknown marker ids {list(report.unknown)}")
        self.frames += 1
        self._frame_walls.append(time.monotonic())
        self._reprojection = error
        self._stamp_ns = stamp_ns
        if not self.tracks.complete:
            self._warn(f"waiting to see robots {self.tracks.missing().tolist()} once")
            return
        sec, nanosec = divmod(stamp_ns, 1_000_000_000)
        self.poses_pub.publish(
            self.encoder.encode(sec, nanosec, self.tracks.positions, self.tracks.headings)
        )

    def _calibrated(self, image: np.ndarray) -> bool:
        if self.calibration is not None:
            return True
        if self.info is None:
            self._warn(f"waiting for {names.CAMERA_INFO} to calibrate from the first frame")
            return False
        K, dist, size = self.info
        if size != (image.shape[1], image.shape[0]):
            self._warn(
                f"dropped a frame of {image.shape[1]}x{image.shape[0]} px: "
                f"camera_info says {size[0]}x{size[1]}"
            )
            return False
        try:
            self.calibration, residuals = calibrate(image, K, dist, self.layout)
        except CalibrationError as exc:
            self._warn(f"cannot calibrate from this frame: {exc}")
            return False
        self.get_logger().info(f"calibrated from the first frame: {residuals}")
        return True

    def on_diagnostics(self) -> None:
        """Once a second: what the tracker sees (detected / expected, missing, lost,
        ages, reprojection error, frames/s). Ages count to this node's clock (sim time
        or wall time, as the camera's stamps), so a camera that stops makes every robot
        age and, after ``lost_after``, lost."""
        now = time.monotonic()
        self._frame_walls = [t for t in self._frame_walls if t > now - 2.0]
        fps = len(self._frame_walls) / 2.0
        clock_ns = max(self._stamp_ns, self.get_clock().now().nanoseconds)
        ages = self.tracks.ages(clock_ns)
        lost = self.tracks.lost(clock_ns, self.lost_after)
        in_frame = self.tracks.ages(self._stamp_ns) == 0.0
        seen = int(np.count_nonzero(in_frame)) if self.frames else 0
        silent = now - self._frame_walls[-1] if self._frame_walls else float("inf")
        message = f"{seen} of {self.tracks.n} robots in the last frame, {len(lost)} lost, "
        message += f"{fps:.1f} frames/s"
        if silent > self.lost_after:
            message = f"no frame for {silent:.1f} s; " + message
        ok = len(lost) == 0 and silent <= self.lost_after
        status = DiagnosticStatus(
            level=DiagnosticStatus.OK if ok else DiagnosticStatus.WARN,
            name=TRACKER_STATUS,
            message=message,
            values=[
                KeyValue(key="detected", value=str(seen)),
                KeyValue(key="expected", value=str(self.tracks.n)),
                KeyValue(key="missing", value=" ".join(map(str, np.flatnonzero(~in_frame)))),
                KeyValue(key="lost", value=" ".join(map(str, lost))),
                KeyValue(
                    key="ages_s",
                    value=" ".join("inf" if np.isinf(a) else f"{a:.2f}" for a in ages),
                ),
                KeyValue(key="reprojection_px", value=f"{self._reprojection:.3f}"),
                KeyValue(key="frames_per_s", value=f"{fps:.1f}"),
                KeyValue(key="calibrated", value=str(self.calibration is not None).lower()),
            ],
        )
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.get_clock().now().to_msg()
        self.diagnostics_pub.publish(msg)


def open_source(source: str) -> cv2.VideoCapture:
    """An OpenCV capture of a camera device (``/dev/video0`` or its number) or a video
    file; ParameterError naming the source when it cannot be opened or read."""
    device = int(source) if source.isdigit() else source
    capture = cv2.VideoCapture(device)
    if not capture.isOpened():
        raise ParameterError(f"--source {source}: OpenCV cannot open it (no such device or file, "
                             "or not a video it can decode)")  # fmt: skip
    ok, _ = capture.read()
    if not ok:
        capture.release()
        raise ParameterError(f"--source {source}: opened, but no frame could be read from it")
    capture.set(cv2.CAP_PROP_POS_FRAMES, 0)
    return capture


def main(args: list[str] | None = None) -> int:
    """``aes-tracker [--source DEVICE|FILE]``: track until SIGINT or SIGTERM."""
    argv = list(sys.argv if args is None else args)
    source = None
    own = argv[: argv.index("--ros-args")] if "--ros-args" in argv else argv
    if "--source" in own:
        at = argv.index("--source")
        if at + 1 >= len(own):
            print("aes-tracker: error: --source needs a device or a video file", file=sys.stderr)
            return 2
        source = argv[at + 1]
        del argv[at : at + 2]
    return run_node_process(names.TRACKER_NODE, argv, functools.partial(TrackerNode, source))


if __name__ == "__main__":
    sys.exit(main())
