"""The dashboard's ROS node ``/dashboard``: it listens to the swarm, and steers it through
the same public interface as the CLI and ``ros2`` (docs/design.md#ros-interface).

It reads ``/swarm/poses``, the supervisor's command and metrics, ``/clock`` and the
bridge's ``/diagnostics`` (which robots are silent) into a
:class:`dashboard_node.view.SwarmView`;
publishes ``/swarm/markers`` while anyone subscribes; calls ``/swarm/enable``,
``/sim/pause``, ``/sim/reset``, the robots' and the supervisor's ``set_parameters``
(gains) and the supervisor's ``set_parameters_atomically`` (the swarm command: only
the part a viewer changed, so that the other part stays the swarm's own). The web
server (:mod:`dashboard_node.server`) runs in another thread; it hands control
requests over with :meth:`DashboardNode.submit`, and they run in the node's own
thread.

Start it (or ``aes-swarm dashboard``, or ``aes-swarm launch --dashboard``)::

    aes-dashboard --ros-args -p scenario:=combined -p port:=8080 -p use_sim_time:=true
"""

from __future__ import annotations

import concurrent.futures
import queue
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, PoseArray, TwistStamped
from rcl_interfaces.srv import SetParametersAtomically
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from std_msgs.msg import Bool, Float64
from std_srvs.srv import SetBool, Trigger
from visualization_msgs.msg import MarkerArray

from aes_ros.ros import interface as names
from aes_ros.ros import parameters as rp
from aes_ros.ros.cdr import decode_pose_array
from aes_ros.ros.conversions import (
    BadMessageError,
    point_to_array,
    stamp_to_ns,
    twist_to_drive,
)
from aes_ros.ros.diagnostics import silent_robots
from aes_ros.ros.markers import swarm_markers
from aes_ros.ros.node_tools import ThrottledWarnings
from aes_ros.ros.qos import DISPLAY_WRITER, LATCHED, SENSOR
from dashboard_node.controls import Control
from dashboard_node.requests import CALL_TIMEOUT as CALL_TIMEOUT  # the server waits as long
from dashboard_node.requests import ControlRequests
from dashboard_node.view import PosesError, SwarmView


class DashboardNode(ControlRequests, Node):
    """The dashboard's node ``dashboard``.

    Parameters (read at start): ``host`` (string, default ``127.0.0.1``) and
    ``port`` (int, default 8080) of the web server (its token is not a parameter:
    :mod:`dashboard_node.access`); ``frame_rate``
    [Hz] (default 15) of the page's updates; ``label``: the run's name in the status
    line (default: the scenario file's name); ``markers_rate`` [Hz] (default 10,
    at most 10 and at most ``frame_rate``: both come from one frame) of
    ``/swarm/markers``; ``scenario`` and ``num_robots``: the sheet it draws (an
    n-robot grid of the scenario when the poses have n robots).
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(names.DASHBOARD_NODE, **kwargs)
        self._warn = ThrottledWarnings(self.get_logger())
        scenario = rp.declare_scenario(self)
        ro = {"read_only": True}
        self.declare_parameter("host", "127.0.0.1", rp.text_descriptor("web server address", **ro))
        self.declare_parameter(
            "port", 8080, rp.int_descriptor("web server port (0: any free one)", 0, 65535, **ro)
        )
        self.declare_parameter(
            "frame_rate", 15.0, rp.float_descriptor("updates of the page", "Hz", 1.0, 60.0, **ro)
        )
        self.declare_parameter(
            "markers_rate",
            10.0,
            rp.float_descriptor("/swarm/markers while subscribed", "Hz", 0.1, 10.0, **ro),
        )
        self.declare_parameter(
            "label", "", rp.text_descriptor("the run's name in the status line", **ro)
        )
        label = self.get_parameter("label").value or Path(self.get_parameter("scenario").value).stem
        self.lock = threading.Lock()
        self.view = SwarmView(scenario, label=label)
        self._requests: queue.Queue[tuple[Control, concurrent.futures.Future]] = queue.Queue()
        self._param_clients: dict[str, Any] = {}
        #: Calls whose service is not matched yet (each returns True once done with).
        self._waiting: list[Callable[[], bool]] = []

        subscribe = self._subscribe
        subscribe(PoseArray, names.POSES, self.on_poses, SENSOR, raw=True)
        for topic, name in (
            (names.ALIGNMENT, "alignment"),
            (names.HEADING_ORDER, "heading_order"),
            (names.TOTAL_FORCE, "total_force"),
        ):
            subscribe(
                Float64,
                topic,
                lambda msg, name=name: self._locked(self.view.on_metric, name, msg.data),
                LATCHED,
            )
        subscribe(TwistStamped, names.DESIRED_VELOCITY, self.on_desired_velocity, LATCHED)
        subscribe(PointStamped, names.ROTATION_CENTER, self.on_center, LATCHED)
        subscribe(Bool, names.ENABLED, self.on_enabled, LATCHED)
        subscribe(ClockMsg, names.CLOCK, self.on_clock, SENSOR)
        subscribe(DiagnosticArray, names.DIAGNOSTICS, self.on_diagnostics, LATCHED)

        self.markers_pub = self.create_publisher(MarkerArray, names.MARKERS, DISPLAY_WRITER)
        self.markers_published = 0
        self.frames_made = 0
        self._markers_period = 1.0 / self.get_parameter("markers_rate").value
        self._markers_due = 0.0
        self.drive_client = self.create_client(
            SetParametersAtomically, f"/{names.SUPERVISOR_NODE}/set_parameters_atomically"
        )
        self.enable_client = self.create_client(SetBool, names.ENABLE)
        self.pause_client = self.create_client(SetBool, names.SIM_PAUSE)
        self.reset_client = self.create_client(Trigger, names.SIM_RESET)
        # Wall-clock timers: with use_sim_time a paused world stops /clock, and the
        # request that would resume it must still be served. (The EventsExecutor has
        # no guard conditions to wake it; 20 Hz polling is quick enough for a click.)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(0.05, self._guarded("requests", self.on_requests), clock=steady)

    # --- the swarm ------------------------------------------------------------------

    def _guarded(self, what: str, callback: Callable[..., None]) -> Callable[..., None]:
        """``callback``, its exceptions logged (throttled) instead of raised: in the
        executor they would end the node's thread, and the page would show a frozen swarm."""

        def run(*args: Any) -> None:
            try:
                callback(*args)
            except Exception as exc:
                self._warn(f"{what}: {type(exc).__name__}: {exc}")

        return run

    def _subscribe(self, kind: type, topic: str, callback: Callable, qos: Any, **kw: Any) -> Any:
        return self.create_subscription(
            kind, topic, self._guarded(f"dropped {topic}", callback), qos, **kw
        )

    def _locked(self, action: Callable[..., None], *args: Any) -> None:
        with self.lock:
            action(*args)

    def on_diagnostics(self, msg: DiagnosticArray) -> None:
        """The bridge's list of silent robots (:mod:`aes_ros.ros.diagnostics`)."""
        silent = silent_robots(msg)
        if silent is not None:
            self._locked(self.view.on_silent, silent)

    def on_poses(self, data: bytes) -> None:
        """Poses in the world frame, 1 to MAX_ROBOTS of them; anything else is dropped
        with a throttled warning and the last good poses stay on the page."""
        try:
            sec, nanosec, xy, yaw = decode_pose_array(data, frame_id=names.WORLD_FRAME)
            with self.lock:
                self.view.on_poses(sec + nanosec * 1e-9, xy, yaw)
        except BadMessageError as exc:
            self._warn(f"dropped /swarm/poses: {exc}")
        except PosesError as exc:  # "no poses", "too many poses": each throttled on its own
            self._warn(f"dropped /swarm/poses, {exc}")

    def on_desired_velocity(self, msg: TwistStamped) -> None:
        try:
            direction, omega = twist_to_drive(msg.twist)
        except BadMessageError as exc:
            self._warn(f"dropped /swarm/desired_velocity: {exc}")
            return
        self._locked(self.view.on_command, direction, omega)

    def on_center(self, msg: PointStamped) -> None:
        try:
            point = point_to_array(msg.point)
        except BadMessageError as exc:
            self._warn(f"dropped /swarm/rotation_center: {exc}")
            return
        self._locked(self.view.on_center, (float(point[0]), float(point[1])))

    def on_enabled(self, msg: Bool) -> None:
        with self.lock:
            self.view.enabled = bool(msg.data)

    def on_clock(self, msg: ClockMsg) -> None:
        self._locked(self.view.on_clock, stamp_to_ns(msg.clock) * 1e-9, time.monotonic())

    def frame_tick(self, viewers: bool, now: float) -> dict[str, Any] | None:
        """One frame for everyone who wants one this tick, made once: the page's
        viewers (``viewers``) and ``/swarm/markers`` (only while someone subscribes,
        RViz2, Foxglove or a bag, at most ``markers_rate``). None when nobody does.
        Called by the web server at ``frame_rate`` (steady time ``now`` [s])."""
        markers = now >= self._markers_due and self.markers_pub.get_subscription_count() > 0
        if not (viewers or markers):
            return None
        with self.lock:
            frame = self.view.frame()
            springs = self.view.pairs.tolist() if markers else []
        self.frames_made += 1
        if markers and "x" in frame:
            # the next one a period after this one was due, so that a 15 Hz tick
            # keeps 10 Hz on average instead of falling back to 7.5 Hz
            due = self._markers_due + self._markers_period
            self._markers_due = due if due > now else now + self._markers_period
            stamp = self.get_clock().now().to_msg()
            self.markers_pub.publish(swarm_markers(frame, springs, stamp, self.view.arena))
            self.markers_published += 1
        return frame


def main(args: list[str] | None = None, *, print_url: bool = False) -> int:
    """``aes-dashboard``: the node spins in a thread, the web server in the main one,
    until SIGINT or SIGTERM. Exit code 0 then; 1 if it cannot start (a bad
    parameter or token, the port taken) or its node fails. The token comes from the
    environment (:func:`aes_ros.ros.dashboard_token.given_token`) or is made up; the URL
    with it goes to stdout if made up or ``print_url``."""
    import asyncio
    import os
    import signal

    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.experimental import EventsExecutor
    from rclpy.signals import SignalHandlerOptions

    from aes_ros.ros.dashboard_token import TokenError, given_token
    from aes_ros.ros.spin import STARTUP_ERRORS, node_help, wants_help
    from dashboard_node.server import Dashboard

    if wants_help(args):
        # rclpy ignores --help: without this, `aes-dashboard --help` served a dashboard
        print(node_help(DashboardNode))
        return 0
    node = None
    done = threading.Event()
    threads: list[threading.Thread] = []
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        node = DashboardNode()
        executor = EventsExecutor()
        executor.add_node(node)
        get = node.get_parameter
        token = given_token(os.environ)
        host, port = get("host").value, get("port").value
        dashboard = Dashboard(node, host, port, token, print_url=print_url or token is None)

        async def serve() -> int:
            stop = asyncio.Event()
            loop = asyncio.get_running_loop()
            for sig in (signal.SIGINT, signal.SIGTERM):
                loop.add_signal_handler(sig, stop.set)
            failed: list[BaseException] = []

            def spin() -> None:
                try:
                    while not done.is_set() and rclpy.ok():
                        executor.spin_once(timeout_sec=0.1)
                except ExternalShutdownException:
                    pass
                except Exception as exc:  # without its node the page would show a frozen swarm
                    failed.append(exc)
                    node.get_logger().fatal(f"the node's thread failed: {exc!r}")
                finally:
                    if not done.is_set():  # else the server stopped first and closed its loop
                        loop.call_soon_threadsafe(stop.set)

            threads.append(threading.Thread(target=spin, name="dashboard-ros", daemon=True))
            threads[0].start()
            await dashboard.serve(stop)
            return 1 if failed else 0

        return asyncio.run(serve())
    except (*STARTUP_ERRORS, OSError, TokenError) as exc:
        rclpy.logging.get_logger(names.DASHBOARD_NODE).fatal(f"cannot start: {exc}")
        return 1
    finally:
        done.set()
        for thread in threads:
            thread.join(timeout=5)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
