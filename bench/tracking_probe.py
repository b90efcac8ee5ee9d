"""What bench/bench_tracking.py measures in one run: a probe node that records the exact
and the tracked poses, ``/clock``, the camera's frames and the tracker's ``/diagnostics``
(:class:`Probe`), the figures computed from them (:func:`analyse`; how:
docs/real_robots.md#how-bench_trackingpy-measures), and one render and detection timed
in this process (:func:`in_process_times`)."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

import numpy as np

#: The camera node's defaults (sim_bridge/camera_node.py) for the in-process render.
HFOV, NOISE, BLUR = 60.0, 2.0, 0.6
#: Half-width [s of sim time] of the /clock window that gives a stamp's sim/wall offset.
OFFSET_WINDOW = 0.5


# ------------------------------------------------------------------------------ the probe


@dataclass
class Received:
    """What the probe heard, each with its arrival time (``time.monotonic`` [s])."""

    clock: list[tuple[float, float]] = field(default_factory=list)  # (arrival, sim [s])
    truth: dict[int, tuple[float, np.ndarray, np.ndarray]] = field(default_factory=dict)
    tracked: list[tuple[float, int, np.ndarray, np.ndarray]] = field(default_factory=list)
    camera: dict[int, float] = field(default_factory=dict)  # stamp [ns] -> camera_info arrival
    diagnostics: list[tuple[float, int, int]] = field(default_factory=list)  # detected, expected


class Probe:
    """A node in this process, in its own context, spun by a thread: records the exact
    and the tracked poses (raw), ``/clock`` and the tracker's ``/diagnostics``."""

    def __init__(self, n: int) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PoseArray
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from rclpy.signals import SignalHandlerOptions
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import CameraInfo

        from aes_ros.ros import interface as names
        from aes_ros.ros.launch.monitor import udp_only

        self.n = n
        self.got = Received()
        self.context = rclpy.Context()
        # UDP only, as the launcher's monitor: no shared memory for the stop to wait on.
        with udp_only():
            rclpy.init(
                args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO
            )
            self.node = rclpy.create_node("bench_tracking_probe", context=self.context)
        stream = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        sub = self.node.create_subscription
        sub(PoseArray, names.GROUND_TRUTH_POSES, self.on_truth, stream, raw=True)
        sub(PoseArray, names.POSES, self.on_tracked, stream, raw=True)
        sub(Clock, names.CLOCK, self.on_clock, stream)
        sub(CameraInfo, names.CAMERA_INFO, self.on_camera_info, stream, raw=True)
        sub(DiagnosticArray, names.DIAGNOSTICS, self.on_diagnostics, reliable)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException

        while not self._stop.is_set():
            try:
                self.executor.spin_once(timeout_sec=0.05)
            except ExternalShutdownException:
                return

    def on_clock(self, msg) -> None:
        self.got.clock.append((time.monotonic(), msg.clock.sec + 1e-9 * msg.clock.nanosec))

    def on_camera_info(self, data: bytes) -> None:
        from aes_ros.ros.cdr import decode_stamp

        sec, nanosec = decode_stamp(data)
        self.got.camera[sec * 1_000_000_000 + nanosec] = time.monotonic()

    def _decode(self, data: bytes):
        from aes_ros.ros.cdr import decode_pose_array

        sec, nanosec, positions, headings = decode_pose_array(data)
        return sec * 1_000_000_000 + nanosec, positions, headings

    def on_truth(self, data: bytes) -> None:
        t = time.monotonic()
        stamp, positions, headings = self._decode(data)
        if len(positions) == self.n:
            self.got.truth[stamp] = (t, positions, headings)

    def on_tracked(self, data: bytes) -> None:
        t = time.monotonic()
        stamp, positions, headings = self._decode(data)
        if len(positions) == self.n:
            self.got.tracked.append((t, stamp, positions, headings))

    def on_diagnostics(self, msg) -> None:
        from aes_ros.ros.diagnostics import TRACKER_STATUS

        for status in msg.status:
            if status.name == TRACKER_STATUS:
                values = {kv.key: kv.value for kv in status.values}
                self.got.diagnostics.append(
                    (time.monotonic(), int(values["detected"]), int(values["expected"]))
                )

    def close(self) -> None:
        import rclpy

        self._stop.set()
        self._thread.join(5.0)
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


# ------------------------------------------------------------------------------ analysis


def stamp_offsets(clock: np.ndarray, stamps: np.ndarray) -> np.ndarray:
    """The sim→wall offset [s] at each sim time in ``stamps`` [s]: the smallest
    ``arrival − sim`` of the ``/clock`` messages ``clock: (K, 2)`` (arrival, sim) within
    ±OFFSET_WINDOW of sim time (nan where there is none)."""
    order = np.argsort(clock[:, 1])
    sim, offset = clock[order, 1], clock[order, 0] - clock[order, 1]
    lo = np.searchsorted(sim, stamps - OFFSET_WINDOW)
    hi = np.searchsorted(sim, stamps + OFFSET_WINDOW, side="right")
    return np.array([offset[a:b].min() if b > a else np.nan for a, b in zip(lo, hi, strict=True)])


def analyse(got: Received, w0: float, w1: float, n: int) -> dict[str, float]:
    """The figures of the module docstring from what arrived in the wall window [w0, w1]."""
    from aes_ros.model import wrap_angle
    from sim_bridge.mona import MonaGeometry

    apart = 2.0 * MonaGeometry().body_radius  # closer, two bodies overlap
    tracked = [m for m in got.tracked if w0 <= m[0] <= w1]
    if len(tracked) < 3:
        raise RuntimeError(f"only {len(tracked)} tracked /swarm/poses in the window")
    arrival = np.array([m[0] for m in tracked])
    stamps_ns = np.array([m[1] for m in tracked])
    stamps = 1e-9 * stamps_ns
    updated, clear, clear_seen, pos_err, head_err, truth_lat = [], [], [], [], [], []
    for k in range(1, len(tracked)):
        t, stamp, p, h = tracked[k]
        _, _, p0, h0 = tracked[k - 1]
        seen = np.any(p != p0, axis=1) | (h != h0)
        updated.append(np.count_nonzero(seen))
        if (truth := got.truth.get(stamp)) is None:
            continue
        t_truth, p_true, h_true = truth
        truth_lat.append(t - t_truth)
        pos_err.append(np.linalg.norm(p[seen] - p_true[seen], axis=1))
        head_err.append(wrap_angle(h[seen] - h_true[seen]))
        gaps = np.linalg.norm(p_true[:, None] - p_true[None], axis=-1)
        np.fill_diagonal(gaps, np.inf)
        alone = gaps.min(axis=1) >= apart
        clear.append(np.count_nonzero(alone))
        clear_seen.append(np.count_nonzero(seen & alone))
    pos_err = np.concatenate(pos_err) if pos_err else np.array([np.nan])
    head_err = np.concatenate(head_err) if head_err else np.array([np.nan])
    clock = np.array(got.clock)
    exposure = stamps + stamp_offsets(clock, stamps)
    latency = 1e3 * (arrival - exposure)
    published = np.array([got.camera.get(s, np.nan) for s in stamps_ns])
    camera_part = 1e3 * (published - exposure)
    tracker_part = 1e3 * (arrival - published)
    inside = clock[(clock[:, 0] >= w0) & (clock[:, 0] <= w1)]
    rtf = (inside[-1, 1] - inside[0, 1]) / (inside[-1, 0] - inside[0, 0])
    diag = [d / e for t, d, e in got.diagnostics if w0 <= t <= w1]
    sim_span = stamps.max() - stamps.min()

    def pct(values, q: float) -> float:
        values = np.asarray(values, dtype=float)
        values = values[np.isfinite(values)]
        return float(np.percentile(values, q)) if len(values) else float("nan")

    return {
        "frames": len(tracked),
        "fps": len(tracked) / (w1 - w0),
        "fps_sim": (len(np.unique(stamps_ns)) - 1) / sim_span if sim_span > 0 else np.nan,
        "detection_rate": float(np.sum(updated)) / (n * len(updated)),
        "detection_rate_clear": float(np.sum(clear_seen)) / max(float(np.sum(clear)), 1.0),
        "overlapping": 1.0 - float(np.sum(clear)) / (n * max(len(clear), 1)),
        "diag_detection_rate": float(np.mean(diag)) if diag else float("nan"),
        "pos_rms_mm": 1e3 * float(np.sqrt(np.mean(pos_err**2))),
        "pos_max_mm": 1e3 * float(np.max(pos_err)),
        "heading_rms_deg": float(np.degrees(np.sqrt(np.mean(head_err**2)))),
        "latency_p50_ms": pct(latency, 50),
        "latency_p99_ms": pct(latency, 99),
        "latency_truth_p50_ms": 1e3 * pct(truth_lat, 50),
        "latency_truth_p99_ms": 1e3 * pct(truth_lat, 99),
        "camera_part_p50_ms": pct(camera_part, 50),
        "camera_part_p99_ms": pct(camera_part, 99),
        "tracker_part_p50_ms": pct(tracker_part, 50),
        "tracker_part_p99_ms": pct(tracker_part, 99),
        "rtf": float(rtf),
        "sim_s": float(inside[-1, 1] - inside[0, 1]),
    }


def in_process_times(arena, size, positions, headings, frames: int = 15) -> tuple[float, float]:
    """Median wall ms of one render with the camera node's settings and of one detection
    of the rendered frame, on the run's exact poses (``positions: (F, N, 2)``)."""
    from aes_ros.arena_layout import corner_layout
    from aes_ros.tracking.detection import detect_markers
    from sim_bridge.camera_node import arena_camera
    from sim_bridge.camera_render import CameraRenderer

    camera = arena_camera(list(arena), size[0], size[1], HFOV)
    layout = corner_layout(arena)
    renderer = CameraRenderer(
        camera, references=layout.references, noise_sigma=NOISE, blur_sigma=BLUR, rng=0
    )
    renderer.render(positions[0], headings[0])  # builds the markers' patches
    render, detect = [], []
    for k in range(frames):
        j = k * len(positions) // frames
        start = time.perf_counter()
        image = renderer.render(positions[j], headings[j])
        render.append(time.perf_counter() - start)
        start = time.perf_counter()
        detect_markers(image)
        detect.append(time.perf_counter() - start)
    return 1e3 * float(np.median(render)), 1e3 * float(np.median(detect))
