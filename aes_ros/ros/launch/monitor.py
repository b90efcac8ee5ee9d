"""The launcher's own rclpy node: samples ``/swarm/poses`` and ``/clock``, calls services.

It runs in its own rclpy context, spun by the launcher between its other duties
(:meth:`Monitor.spin_once`), and reads the poses raw with numpy
(:mod:`aes_ros.ros.cdr`: building N ``Pose`` objects per step was half of its CPU).
Its DDS participant talks over UDP only: Fast DDS removes a participant's
shared-memory files when it shuts down, so a launcher killed with SIGKILL would
otherwise leave them behind (its children shut down cleanly when it dies).
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from typing import Any

import numpy as np
import rclpy
from geometry_msgs.msg import PoseArray, TwistStamped
from rclpy.experimental import EventsExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool
from std_srvs.srv import SetBool, Trigger

from aes_ros.ros import interface as names
from aes_ros.ros.cdr import decode_pose_array
from aes_ros.ros.conversions import BadMessageError
from aes_ros.ros.launch.plan import LaunchError
from aes_ros.ros.launch.processes import fastdds_environment
from aes_ros.ros.qos import LATCHED

#: Tolerance on sim-time comparisons [s].
TIME_EPS = 1e-6


class Monitor:
    """Samples of the swarm's poses as the bridge publishes them.

    ``times`` (sim time [s]), ``positions`` ((N, 2) each) and ``headings`` ((N,)
    each) grow with every new ``/swarm/poses`` message; a message with an older
    stamp (the bridge was restarted or reset its clock) starts them over.
    ``clock`` is the latest ``/clock`` [s]. ``desired`` and ``enabled`` are the
    supervisor's latest ``/swarm/desired_velocity`` and ``/swarm/enabled`` (what a
    restarted supervisor is told to carry on with).
    """

    def __init__(self, n_robots: int) -> None:
        self.n = n_robots
        self.context = rclpy.Context()
        with _udp_only():
            # The launcher handles SIGINT/SIGTERM itself (it must stop the children first).
            rclpy.init(
                args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO
            )
            self.node = rclpy.create_node(names.LAUNCHER_NODE, context=self.context)
        stream = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
        self.node.create_subscription(PoseArray, names.POSES, self.on_poses, stream, raw=True)
        self.node.create_subscription(
            Clock,
            names.CLOCK,
            self.on_clock,
            QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT),
        )
        self.node.create_subscription(
            TwistStamped, names.DESIRED_VELOCITY, self.on_desired_velocity, LATCHED
        )
        self.node.create_subscription(Bool, names.ENABLED, self.on_enabled, LATCHED)
        self.times: list[float] = []
        self.positions: list[np.ndarray] = []
        self.headings: list[np.ndarray] = []
        self.clock = 0.0
        self.bad = 0
        #: How many times the samples started over (a bridge's clock went back).
        self.restarts = 0
        self.desired: TwistStamped | None = None
        self.enabled: bool | None = None
        # rclpy's EventsExecutor, as in every node: the SingleThreadedExecutor rebuilt its
        # wait set in Python at each spin_once, two thirds of a launcher's samples in
        # py-spy; launcher at 100 robots, 50 Hz: 11-13 % -> 5-6 % of a core (bench_ros).
        self.executor = EventsExecutor(context=self.context)
        self.executor.add_node(self.node)

    def on_poses(self, data: bytes) -> None:
        try:
            sec, nanosec, pos, head = decode_pose_array(data, self.n)
        except BadMessageError:
            self.bad += 1
            return
        t = sec + nanosec * 1e-9
        if self.times and t <= self.times[-1] + TIME_EPS * 1e-3:
            if t < self.times[-1] - TIME_EPS:  # the bridge was reset: start over
                self.times.clear()
                self.positions.clear()
                self.headings.clear()
                self.restarts += 1
            else:
                return
        self.times.append(t)
        self.positions.append(pos)
        self.headings.append(head)

    def on_clock(self, msg: Clock) -> None:
        self.clock = msg.clock.sec + msg.clock.nanosec * 1e-9

    def on_desired_velocity(self, msg: TwistStamped) -> None:
        self.desired = msg

    def on_enabled(self, msg: Bool) -> None:
        self.enabled = bool(msg.data)

    def other_swarm(self, wait: float) -> list[str]:
        """The nodes of another swarm in this ROS domain (empty if none was seen
        within ``wait`` s of discovery): a bridge, a supervisor, robots or a publisher
        of ``/swarm/poses``."""
        ours = {names.SIM_BRIDGE_NODE, names.SUPERVISOR_NODE, names.ROBOT_NODE, names.RECORDER_NODE}
        deadline = time.monotonic() + wait
        publishing = False
        while time.monotonic() < deadline:
            self.spin_once(0.05)
            found = [
                f"{namespace.rstrip('/')}/{name}"
                for name, namespace in self.node.get_node_names_and_namespaces()
                if name in ours or name.startswith(names.ROBOT_HOST_NODE)
            ]
            found += _publishers(self.node, names.POSES)
            if found:
                return sorted(set(found))
            publishing = publishing or self.node.count_publishers(names.POSES) > 0
        return [f"a publisher of {names.POSES}"] if publishing else []

    def second_swarm(self) -> list[str]:
        """With this launch's own processes running: the bridges publishing
        ``/swarm/poses`` and the supervisors, when there is more than one of either
        (another swarm in the domain that discovery showed only now)."""
        bridges = _publishers(self.node, names.POSES)
        supervisors = [
            f"{namespace.rstrip('/')}/{name}"
            for name, namespace in self.node.get_node_names_and_namespaces()
            if name == names.SUPERVISOR_NODE
        ]
        if len(bridges) > 1:
            return bridges
        return supervisors if len(supervisors) > 1 else []

    def spin_once(self, timeout: float) -> None:
        """Handle what has arrived, waiting at most ``timeout`` s for it."""
        self.executor.spin_once(timeout_sec=timeout)

    def call(self, srv_type: Any, name: str, request: Any, timeout: float) -> Any:
        """Call service ``name`` and return its response; LaunchError if nobody offers
        it or it does not answer within ``timeout`` s (spinning meanwhile)."""
        client = self.node.create_client(srv_type, name)
        try:
            deadline = time.monotonic() + timeout
            while not client.service_is_ready():
                if time.monotonic() > deadline:
                    raise LaunchError(f"nobody offers {name} within {timeout:.0f} s")
                self.spin_once(0.05)
            future = client.call_async(request)
            while not future.done():
                if time.monotonic() > deadline:
                    raise LaunchError(f"{name} did not answer within {timeout:.0f} s")
                self.spin_once(0.05)
            return future.result()
        finally:
            self.node.destroy_client(client)

    def pause_bridge(self, paused: bool, timeout: float) -> None:
        """Call the bridge's ``/sim/pause``."""
        self.call(SetBool, names.SIM_PAUSE, SetBool.Request(data=paused), timeout)

    def bridge_stats(self, timeout: float = 30.0) -> dict[str, Any]:
        """The bridge's ``/sim/stats`` (control-loop figures since the last call)."""
        return json.loads(self.call(Trigger, names.SIM_STATS, Trigger.Request(), timeout).message)

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.executor.shutdown()
            self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def _publishers(node: Any, topic: str) -> list[str]:
    """The nodes publishing ``topic`` whose names discovery has told already."""
    return [
        f"{i.node_namespace.rstrip('/')}/{i.node_name}"
        for i in node.get_publishers_info_by_topic(topic)
        if "_UNKNOWN_" not in i.node_name
    ]


@contextlib.contextmanager
def _udp_only():
    """While a participant is made, for it only (the children were given their
    environment before): Fast DDS's built-in transports set to UDPv4, and the launch's
    Fast DDS profile (:func:`aes_ros.ros.launch.processes.fastdds_environment`)."""
    settings = {"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}
    settings.update(
        (k, v) for k, v in fastdds_environment(dict(os.environ)).items() if k not in os.environ
    )
    old = {key: os.environ.get(key) for key in settings}
    os.environ.update(settings)
    try:
        yield
    finally:
        for key, value in old.items():
            if value is None:
                del os.environ[key]
            else:
                os.environ[key] = value
