"""The launcher's own rclpy node: samples ``/swarm/poses`` and ``/clock``, calls services.

It runs in its own rclpy context, spun by the launcher between its other duties
(:meth:`Monitor.spin_once`), and reads the poses raw with numpy
(:mod:`aes_ros.ros.cdr`: building N ``Pose`` objects per step was half of its CPU).
Its DDS participant talks over UDP only: Fast DDS removes a participant's
shared-memory files when it shuts down, so a launcher killed with SIGKILL would
otherwise leave them behind (its children shut down cleanly when it dies). With a
discovery server it is a plain client: what it asks of the graph (node names, the
publishers of the poses it reads) a plain client learns (:mod:`aes_ros.ros.discovery`).
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np
import rclpy
from geometry_msgs.msg import PoseArray, TwistStamped
from rcl_interfaces.srv import SetParameters
from rclpy.experimental import EventsExecutor
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool
from std_srvs.srv import SetBool, Trigger

from aes_ros.ros import interface as names
from aes_ros.ros.cdr import decode_pose_array
from aes_ros.ros.conversions import BadMessageError
from aes_ros.ros.discovery import Discovery, set_environ
from aes_ros.ros.launch.processes import fastdds_environment
from aes_ros.ros.programs import LaunchError
from aes_ros.ros.qos import LATCHED, OUTPUT_DEPTH

#: Tolerance on sim-time comparisons [s].
TIME_EPS = 1e-6
#: A robot has moved once its position changed by more than this [m] or its heading [rad].
MOVE_EPS = 1e-6
#: Wall seconds of discovery before deciding that no other swarm is in the domain.
DISCOVERY_WAIT = 1.0
#: Wall seconds from the start during which the launcher keeps looking for another
#: swarm: a participant without this launch's Fast DDS profile announces itself only
#: every 3 s, and its answer to a newcomer can go astray.
OTHER_SWARM_WINDOW = 6.0
#: Wall seconds more to learn the node name of another swarm's poses publisher, once
#: discovery showed the publisher: the name comes in the node's graph update, which can
#: come seconds after the endpoint on a loaded machine. Spent only when refusing.
NAME_WAIT = 5.0
#: What a waiting loop calls after every spin (each raises to end the wait).
Checks = Sequence[Callable[[], None]]


class Monitor:
    """Samples of the swarm's poses as the bridge publishes them.

    ``times`` (sim time [s]), ``positions`` ((N, 2) each) and ``headings`` ((N,)
    each) grow with every new ``/swarm/poses`` message; a message with an older
    stamp (the bridge was restarted or reset its clock) starts them over. They hold
    a window of the samples: sample ``k`` (counted from the first, :attr:`count` in
    all) is ``times[k - offset]``, and :meth:`release` drops the ones the caller
    is done with (written to disk), so that a run of hours keeps its memory flat.
    ``clock`` is the latest ``/clock`` [s]. ``desired`` and ``enabled`` are the
    supervisor's latest ``/swarm/desired_velocity`` and ``/swarm/enabled`` (what a
    restarted supervisor is told to carry on with). ``moved`` says which robots have
    moved from their first sampled pose (:meth:`all_moving`).
    """

    def __init__(
        self,
        n_robots: int,
        poses_topic: str = names.POSES,
        wall_clock: bool = False,
        discovery: Discovery | None = None,
    ) -> None:
        self.n = n_robots
        #: With wall-clock stamps (a real arena) times count from the first pose's
        #: stamp, ``origin`` [s since the epoch], so that they keep their digits in the
        #: outputs; sim time counts from 0.
        self.origin: float | None = None if wall_clock else 0.0
        self.context = rclpy.Context()
        with udp_only(discovery):
            # The launcher handles SIGINT/SIGTERM itself (it must stop the children first).
            rclpy.init(
                args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO
            )
            self.node = rclpy.create_node(names.LAUNCHER_NODE, context=self.context)
        # Reliable and deep, as the recorder's: the samples are the run's outputs. In
        # lockstep at full speed the bridge goes on at ~200 steps/s while the launcher is
        # descheduled, and a queue of 100 dropped the samples before a run's end, so the
        # next one was past it and the outputs ended early (test_perception_ros).
        stream = QoSProfile(depth=OUTPUT_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
        self.node.create_subscription(PoseArray, poses_topic, self.on_poses, stream, raw=True)
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
        #: The number of the sample in ``times[0]``.
        self.offset = 0
        #: The first sample's positions and headings (what :meth:`all_moving` compares with).
        self.first: tuple[np.ndarray, np.ndarray] | None = None
        self.clock = 0.0
        self.bad = 0
        #: How many times the samples started over (a bridge's clock went back).
        self.restarts = 0
        self.desired: TwistStamped | None = None
        self.enabled: bool | None = None
        self.moved = np.zeros(n_robots, dtype=bool)
        #: The last sample in which a robot had not moved yet (the run's start).
        self.last_unmoved = 0
        self._move_checked = 0
        self._swarm_checked_at = 0.0
        self._clients: dict[tuple[Any, str], Any] = {}
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
        if self.origin is None:
            self.origin = float(sec)
        t = (sec - self.origin) + nanosec * 1e-9
        if self.times and t <= self.times[-1] + TIME_EPS * 1e-3:
            if t < self.times[-1] - TIME_EPS:  # the bridge was reset: start over
                self.times.clear()
                self.positions.clear()
                self.headings.clear()
                self.offset, self.first = 0, None
                self.restarts += 1
            else:
                return
        if self.first is None:
            self.first = (pos, head)
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
        of ``/swarm/poses``, named once discovery tells its node (up to ``NAME_WAIT``
        s more)."""
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
            if not publishing and self.node.count_publishers(names.POSES) > 0:
                publishing = True  # refused whatever comes next: wait for its name
                deadline = max(deadline, time.monotonic() + NAME_WAIT)
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

    @property
    def count(self) -> int:
        """Samples taken since the first (or since the last start-over)."""
        return self.offset + len(self.times)

    def sample(self, k: int) -> tuple[float, np.ndarray, np.ndarray]:
        """Sample ``k``: (sim time [s], positions (N, 2), headings (N,)); it must not
        have been released."""
        i = k - self.offset
        if not 0 <= i < len(self.times):
            raise IndexError(f"sample {k} is not held (samples {self.offset}..{self.count - 1})")
        return self.times[i], self.positions[i], self.headings[i]

    def release(self, before: int) -> None:
        """Forget the samples before sample ``before`` (the newest one is always kept:
        progress lines and a restarted bridge read it)."""
        drop = min(before - self.offset, len(self.times) - 1)
        if not self.moved.all():  # all_moving has yet to look at them
            drop = min(drop, self._move_checked - self.offset)
        if drop > 0:
            del self.times[:drop], self.positions[:drop], self.headings[:drop]
            self.offset += drop

    def sim_time(self) -> float | None:
        """The sim time [s] of the latest sample (None before the first)."""
        return self.times[-1] if self.times else None

    def late_second_swarm(self, elapsed: float) -> list[str]:
        """:meth:`second_swarm`, looked for at most every 0.5 s while ``elapsed`` (wall
        seconds since the launch began) is within OTHER_SWARM_WINDOW; else empty."""
        now = time.monotonic()
        if elapsed > OTHER_SWARM_WINDOW or now - self._swarm_checked_at <= 0.5:
            return []
        self._swarm_checked_at = now
        return self.second_swarm()

    def all_moving(self) -> int | None:
        """The sample in which every robot had moved from its first sampled pose (by
        more than MOVE_EPS), looking at the samples that came since the last call;
        None until then (:attr:`last_unmoved` is the sample before it)."""
        while self._move_checked < self.count:
            k = self._move_checked
            self._move_checked += 1
            _, pos, head = self.sample(k)
            pos0, head0 = self.first
            dp = np.linalg.norm(pos - pos0, axis=-1)
            dh = np.abs(np.angle(np.exp(1j * (head - head0))))
            self.moved |= (dp > MOVE_EPS) | (dh > MOVE_EPS)
            if not self.moved.all():
                self.last_unmoved = k
            else:
                return k
        return None

    def wait_first_poses(
        self, source: str, timeout: float, checks: Checks, stopping: Callable[[], bool]
    ) -> None:
        """Spin until the first sample or ``stopping()``, calling ``checks`` after every
        spin (the caller's look at its processes: they raise to end the wait); LaunchError
        when ``timeout`` s pass without poses from ``source`` (the process that sends them)."""
        deadline = time.monotonic() + timeout
        while not self.times and not stopping():
            self._spin_and_check(checks)
            if time.monotonic() > deadline:
                raise LaunchError(f"no poses from {source} within {timeout:.0f} s")

    def wait_all_moving(
        self, timeout: float, checks: Checks, stopping: Callable[[], bool]
    ) -> int | None:
        """Spin until every robot has moved (returns :meth:`all_moving`'s sample) or
        ``stopping()`` (returns None), with ``checks`` as in :meth:`wait_first_poses`;
        LaunchError after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while not stopping():
            self._spin_and_check(checks)
            if (moved_at := self.all_moving()) is not None:
                return moved_at
            if time.monotonic() > deadline:
                stuck = np.flatnonzero(~self.moved).tolist()
                raise LaunchError(
                    f"not every robot moved within {timeout:.0f} s "
                    f"({self.count} pose samples; still at rest: {stuck[:20]})"
                )
        return None

    def run_until(
        self, t_end: float, stall_timeout: float, checks: Checks, stopping: Callable[[], bool]
    ) -> None:
        """Spin until a sample at sim time ``t_end`` [s] or ``stopping()``, with ``checks``
        as in :meth:`wait_first_poses`; LaunchError when no new sample has come for
        ``stall_timeout`` wall seconds."""
        last_count, last_new = self.count, time.monotonic()
        while not stopping():
            self._spin_and_check(checks)
            if self.count != last_count:
                last_count, last_new = self.count, time.monotonic()
            elif time.monotonic() - last_new > stall_timeout:
                raise LaunchError(
                    f"no /swarm/poses for {stall_timeout:.0f} s (sim time {self.clock:.2f} s)"
                )
            if (self.times[-1] if self.times else 0.0) >= t_end - TIME_EPS:
                return

    def _spin_and_check(self, checks: Checks) -> None:
        self.spin_once(0.05)
        for check in checks:
            check()

    def spin_once(self, timeout: float) -> None:
        """Handle what has arrived, waiting at most ``timeout`` s for it."""
        self.executor.spin_once(timeout_sec=timeout)

    def spin_for(self, seconds: float) -> None:
        """Handle everything that arrives for ``seconds`` s (one ``spin_once`` handles
        one message: a caller that sleeps between them lets the poses queue overflow)."""
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            self.spin_once(min(0.05, left))

    def call(self, srv_type: Any, name: str, request: Any, timeout: float) -> Any:
        """Call service ``name`` and return its response; LaunchError if nobody offers
        it or it does not answer within ``timeout`` s (spinning meanwhile).

        One client per service, kept: through a discovery server, a client destroyed and
        made again for the same service in one participant got no answer to one call
        in three to ten (Fast DDS 2.14: the server never matched the new client's reply
        reader; the launch's unpause of the bridge hung so), a kept client to none."""
        client = self._clients.get((srv_type, name))
        if client is None:
            client = self._clients[(srv_type, name)] = self.node.create_client(srv_type, name)
        deadline = time.monotonic() + timeout
        while not client.service_is_ready():
            if time.monotonic() > deadline:
                raise LaunchError(f"nobody offers {name} within {timeout:.0f} s")
            self.spin_once(0.05)
        future = client.call_async(request)
        while not future.done():
            if time.monotonic() > deadline:
                client.remove_pending_request(future)
                raise LaunchError(f"{name} did not answer within {timeout:.0f} s")
            self.spin_once(0.05)
        return future.result()

    def pause_bridge(self, paused: bool, timeout: float) -> None:
        """Call the bridge's ``/sim/pause``."""
        self.call(SetBool, names.SIM_PAUSE, SetBool.Request(data=paused), timeout)

    def pause_bridge_at(self, t: float, timeout: float) -> None:
        """Set the bridge's ``pause_at`` to sim time ``t`` [s]; LaunchError if it refuses."""
        pause_at = Parameter("pause_at", value=float(t)).to_parameter_msg()
        request = SetParameters.Request(parameters=[pause_at])
        service = f"/{names.SIM_BRIDGE_NODE}/set_parameters"
        result = self.call(SetParameters, service, request, timeout).results[0]
        if not result.successful:
            raise LaunchError(f"the bridge refused pause_at = {t:g} s: {result.reason}")

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
def udp_only(discovery: Discovery | None = None) -> Iterator[None]:
    """While a participant is made, for it only (the children were given their
    environment before): Fast DDS's built-in transports set to UDPv4, the launch's
    Fast DDS profile (:func:`aes_ros.ros.launch.processes.fastdds_environment`) and the
    variables of ``discovery`` (None: simple discovery). The launcher's monitor and the
    benchmarks' observers make their participants so: one killed with SIGKILL leaves
    no shared-memory files."""
    settings: dict[str, str | None] = {"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}
    settings.update(
        (k, v) for k, v in fastdds_environment(dict(os.environ)).items() if k not in os.environ
    )
    settings.update((discovery or Discovery()).participant_variables())
    old = {key: os.environ.get(key) for key in settings}
    set_environ(settings)
    try:
        yield
    finally:
        set_environ(old)
