"""The simulated overhead camera ``/arena_camera``: what a lab's ceiling camera sees of
the swarm, rendered from the bridge's exact poses (docs/design.md#tracking).

Start it (the launch does, with ``--tracking camera``)::

    aes-arena-camera --ros-args -p use_sim_time:=true -p arena:="[-1.0, 1.0, -0.75, 0.75]" \
        -p width:=1280 -p height:=960 -p rate:=20.0 -p layout:=arena.yaml

It reads ``/sim/ground_truth/poses`` (the bridge's exact poses, which nothing in the
control loop reads), renders a frame of the robots' ArUco markers at ``rate`` Hz of
sim time with :class:`sim_bridge.camera_render.CameraRenderer`, and publishes
``/arena_camera/image_raw`` (``sensor_msgs/Image``, mono8, stamped with the sim
time of the exposure, i.e. of the poses it shows) and ``/arena_camera/camera_info``
(``sensor_msgs/CameraInfo``: the camera's true intrinsics and distortion).

Why a process of its own and a projective model: rendering a frame takes a few
milliseconds here (``bench/bench_camera_render.py`` measures it beside pybullet's
own renderer), and in its own process it can never stall the bridge's physics or
the robots' control loop; a frame it cannot render in time is simply skipped (the
poses subscription keeps only the newest message).
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path
from typing import Any

import numpy as np
from geometry_msgs.msg import PoseArray
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image

from aes_ros.arena import arena_or_none
from aes_ros.arena_layout import CalibrationError, load_layout
from aes_ros.camera import PinholeCamera, covering_height, overhead_camera
from aes_ros.obstacles import contact_arrays
from aes_ros.params import PARAMS, ParameterError
from aes_ros.ros import interface as names
from aes_ros.ros import parameters as rp
from aes_ros.ros.cdr import decode_pose_array, encode_image
from aes_ros.ros.conversions import BadMessageError
from aes_ros.ros.node_tools import ThrottledWarnings
from aes_ros.ros.qos import IMAGES, SENSOR
from aes_ros.ros.spin import run_node_process
from sim_bridge import camera_effects
from sim_bridge.camera_render import CameraRenderer

#: ``preset`` values: the defaults of the camera effects' parameters.
PRESETS = {"none": camera_effects.Effects(), "realistic": camera_effects.REALISTIC}

#: Floor margin [m] the camera sees beyond the arena on every side, so that a robot at
#: the arena's edge is still whole in the picture, and the reference markers off its
#: corners (:func:`aes_ros.arena_layout.corner_layout`, 0.05 m out, 0.06 m wide)
#: keep 5 cm from the picture's edge (at 1 cm OpenCV missed them).
VIEW_MARGIN = 0.15


class ArenaCameraNode(Node):
    """The simulated overhead camera ``arena_camera``.

    Parameters (read at start)
    --------------------------
    arena : double[4] [m], ``[x_min, x_max, y_min, y_max]`` of the floor to see; the
        camera hangs level over its centre, at ``camera_height`` or, if 0, just high
        enough to see it and :data:`VIEW_MARGIN` around it.
    width, height : int [px], default 1280 × 960. hfov : float [deg], default 60.
    camera_height : float [m], default 0 (see ``arena``).
    rate : float [Hz of sim time], default 20.
    distortion : double[5], plumb_bob ``k1 k2 p1 p2 k3``, default none.
    noise : float [grey levels], default 2. blur : float [px], default 0.6.
    drop : float, probability that a frame is lost, default 0.
    exposure_delay : float [s of sim time] between the exposure and the frame's
        publication, default 0 (the stamp stays the exposure's).
    layout : str, an arena layout file (``arena.yaml``) whose reference markers lie
        on the floor, as in a lab; empty for none.
    seed : int, the noise's and the drops' seed, default 0.
    walls : str [m], the scenario's walls ``x_min,x_max,y_min,y_max``; empty for none.
    obstacles : str [m], its obstacles ``circle:x,y,r;box:x_min,x_max,y_min,y_max``
        (:mod:`aes_ros.obstacles`); empty for none. Both drawn as dark solids.
    preset : str, ``none`` or ``realistic``: the defaults of the five effects below
        (:mod:`sim_bridge.camera_effects`), default ``none`` (all off).
    exposure : float [s], motion blur over the exposure. vignetting, gradient : float,
        gain lost at the corners and at the right edge. full_well : float [e⁻] at white,
        shot noise (0: none). read_noise : float [e⁻ rms].
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(names.CAMERA_NODE, **kwargs)
        self._warn = ThrottledWarnings(self.get_logger())
        ro = {"read_only": True}

        def number(name: str, default: float, text: str, unit: str, lo: float, hi: float) -> Any:
            return self.declare_parameter(
                name, default, rp.float_descriptor(text, unit, lo, hi, **ro)
            ).value

        arena = self.declare_parameter(
            "arena",
            [-1.0, 1.0, -0.75, 0.75],
            rp.array_descriptor("floor seen: x_min, x_max, y_min, y_max", "m", "4 numbers"),
        ).value
        width = self.declare_parameter(
            "width", 1280, rp.int_descriptor("image width", 16, 8192, **ro)
        ).value
        height = self.declare_parameter(
            "height", 960, rp.int_descriptor("image height", 16, 8192, **ro)
        ).value
        hfov = number("hfov", 60.0, "horizontal field of view", "deg", 1.0, 170.0)
        mount = number("camera_height", 0.0, "height above the floor (0: to see the arena)",
                       "m", 0.0, 100.0)  # fmt: skip
        rate = number("rate", 20.0, "frames per second of sim time", "Hz", 0.1, 240.0)
        noise = number("noise", 2.0, "Gaussian pixel noise", "grey levels", 0.0, 100.0)
        blur = number("blur", 0.6, "Gaussian blur", "px", 0.0, 20.0)
        self.drop = number("drop", 0.0, "probability that a frame is lost", "", 0.0, 1.0)
        delay = number("exposure_delay", 0.0, "exposure to publication", "s", 0.0, 10.0)
        distortion = self.declare_parameter(
            "distortion",
            [0.0] * 5,
            rp.array_descriptor("plumb_bob k1 k2 p1 p2 k3", "", "5 numbers"),
        ).value
        layout = self.declare_parameter(
            "layout", "", rp.text_descriptor("arena layout file with reference markers", **ro)
        ).value
        seed = self.declare_parameter("seed", 0, rp.int_descriptor("noise seed", 0, 2**31 - 1))
        solids = {}
        for name in ("walls", "obstacles"):
            text = f"{PARAMS[name].description} ({PARAMS[name].allowed()})"
            value = self.declare_parameter(name, "", rp.text_descriptor(text, **ro)).value
            solids[name] = PARAMS[name].validate(value)  # ParameterError names the field
        walls, circles, boxes = contact_arrays(solids)
        preset = self.declare_parameter(
            "preset", "none", rp.text_descriptor("camera effects' defaults", PRESETS, **ro)
        ).value
        if preset not in PRESETS:
            raise ParameterError(f"preset: {preset!r} is not one of {', '.join(PRESETS)}")
        base = PRESETS[preset]
        self.effects = dataclasses.replace(
            base,
            exposure_s=number("exposure", base.exposure_s, "exposure (motion blur)", "s", 0.0, 1.0),
            vignetting=number("vignetting", base.vignetting, "gain lost at the corners", "",
                              0.0, 0.95),
            gradient=number("gradient", base.gradient, "gain lost at the right edge", "",
                            0.0, 0.95),
            full_well=number("full_well", base.full_well, "electrons at white (shot noise)",
                             "e-", 0.0, 1e7),
            read_noise=number("read_noise", base.read_noise, "read noise", "e- rms", 0.0, 1e4),
        )  # fmt: skip
        self.gain = (
            camera_effects.lighting_gain((height, width), self.effects.vignetting,
                                         self.effects.gradient)
            if self.effects.lighting else None
        )  # fmt: skip
        self.last_pose: tuple[int, np.ndarray, np.ndarray] | None = None
        if arena_or_none(list(arena)) is None:  # checked as the supervisor's arena is
            raise ParameterError("arena: the camera needs the floor it sees, four numbers")
        if len(distortion) != 5:
            raise ParameterError(f"distortion: expected 5 numbers, got {len(distortion)}")
        try:
            references = load_layout(Path(layout)).references if layout else ()
        except CalibrationError as exc:
            raise ParameterError(f"layout: {exc}") from None
        self.camera = arena_camera(arena, width, height, hfov, mount, distortion)
        self.renderer = CameraRenderer(
            self.camera,
            references=references,
            noise_sigma=noise,
            blur_sigma=blur,
            rng=seed.value,
            walls=walls,
            circles=circles,
            boxes=boxes,
        )
        self.rng = np.random.default_rng(seed.value + 1)
        self.period_ns = round(1e9 / rate)
        self.delay_ns = round(1e9 * delay)
        self.next_ns = 0
        #: frames awaiting their exposure delay: (due, encoded, stamp sec, stamp nanosec)
        self.held: list[tuple[int, bytes, int, int]] = []

        info = CameraInfo(**dataclasses.asdict(self.camera.camera_info()))
        info.header.frame_id = names.CAMERA_FRAME
        self.info = info
        self.image_pub = self.create_publisher(Image, names.CAMERA_IMAGE, IMAGES)
        self.info_pub = self.create_publisher(CameraInfo, names.CAMERA_INFO, SENSOR)
        self.create_subscription(
            PoseArray, names.GROUND_TRUTH_POSES, self.on_poses, SENSOR, raw=True
        )
        self.get_logger().info(
            f"{width}x{height} px, {hfov:g} deg, {self.camera.center[2]:.2f} m above "
            f"({self.camera.center[0]:.2f}, {self.camera.center[1]:.2f}), {rate:g} Hz, "
            f"{len(references)} reference markers"
        )

    def on_poses(self, data: bytes) -> None:
        """The bridge's exact poses: expose a frame when one is due, publish the
        frames whose exposure delay has passed."""
        try:
            sec, nanosec, positions, headings = decode_pose_array(data)
        except BadMessageError as exc:
            self._warn(f"dropped {names.GROUND_TRUTH_POSES}: {exc}")
            return
        now = sec * 1_000_000_000 + nanosec
        if now < self.next_ns - self.period_ns:  # the clock went back: a reset world
            self.next_ns, self.held = 0, []
        if now >= self.next_ns:
            self.next_ns = max(self.next_ns + self.period_ns, now)
            if self.rng.random() >= self.drop:
                frame = self.expose(now, positions, headings)
                encoded = encode_image(sec, nanosec, names.CAMERA_FRAME, frame, "mono8")
                self.held.append((now + self.delay_ns, encoded, sec, nanosec))
        self.last_pose = (now, positions, headings)
        while self.held and self.held[0][0] <= now:
            _, encoded, sec, nanosec = self.held.pop(0)
            self.info.header.stamp.sec, self.info.header.stamp.nanosec = sec, nanosec
            self.image_pub.publish(encoded)
            self.info_pub.publish(self.info)

    def expose(self, now: int, positions: np.ndarray, headings: np.ndarray) -> np.ndarray:
        """One frame of the poses at ``now`` [ns], with the effects that are on."""
        fx = self.effects
        if not (fx.exposure_s > 0.0 or fx.lighting or fx.noise):
            return self.renderer.render(positions, headings)
        velocity, yaw_rate = np.zeros_like(positions), np.zeros_like(headings)
        if self.last_pose is not None and len(self.last_pose[1]) == len(positions):
            t0, p0, h0 = self.last_pose
            if 0 < now - t0 < 1_000_000_000:  # the motion since the last poses
                dt = 1e-9 * (now - t0)
                velocity = (positions - p0) / dt
                yaw_rate = np.angle(np.exp(1j * (headings - h0))) / dt
        if fx.exposure_s > 0.0:
            frame = camera_effects.exposed(self.renderer.render, positions, headings, velocity,
                                           yaw_rate, fx.exposure_s, fx.blur_samples)  # fmt: skip
        else:
            frame = self.renderer.render(positions, headings)
        return camera_effects.apply(frame, fx, self.gain, self.rng)


def arena_camera(
    arena: list[float],
    width: int,
    height: int,
    hfov: float,
    mount: float = 0.0,
    distortion: list[float] | tuple[float, ...] = (0.0,) * 5,
) -> PinholeCamera:
    """The level camera over the centre of ``arena`` ``[x_min, x_max, y_min, y_max]``
    [m], ``mount`` [m] high or, if 0, high enough to see the arena and
    :data:`VIEW_MARGIN` around it."""
    x0, x1, y0, y1 = (float(v) for v in arena)
    extent = (x1 - x0 + 2 * VIEW_MARGIN, y1 - y0 + 2 * VIEW_MARGIN)
    z = mount or covering_height(extent, width, height, hfov)
    return overhead_camera(((x0 + x1) / 2, (y0 + y1) / 2), z, width, height, hfov, distortion)


def main(args: list[str] | None = None) -> int:
    """``aes-arena-camera``: the simulated overhead camera until SIGINT or SIGTERM."""
    return run_node_process(names.CAMERA_NODE, args, ArenaCameraNode)


if __name__ == "__main__":
    sys.exit(main())
