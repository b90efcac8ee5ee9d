"""The rclpy node of the system tests: records topics, publishes, calls services and
parameters, and samples the swarm's poses.

:class:`Probe` runs in its own rclpy context, spun by a background thread: a test
never spins by hand, it waits (:meth:`Probe.wait`, :meth:`Probe.wait_sim`) and reads
what has arrived. Callbacks only append (in the spin thread); the test thread only
reads and waits, so plain lists are enough. An exception in a callback is kept and
raised in the test thread by the next wait and by :meth:`Probe.close`.

``/swarm/poses`` is taken raw and decoded with :func:`aes_ros.ros.cdr.decode_pose_array`,
which keeps up with the bridge in lockstep at full speed.
"""

from __future__ import annotations

import struct
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import PoseArray, TwistStamped
from rcl_interfaces.srv import GetParameters, SetParameters, SetParametersAtomically
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

from aes_ros.ros import interface as names
from aes_ros.ros.cdr import decode_pose_array
from aes_ros.ros.qos import LATCHED

#: Default wait [s] for a service, an answer or a subscriber.
TIMEOUT = 20.0
#: Best-effort stream with room for bursts (the launcher's monitor uses the same).
STREAM = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)


class Probe:
    """A node in the test process, spun in a background thread.

    After :meth:`sample_poses`, ``times`` (sim time [s]), ``positions`` ((N, 2)
    each) and ``headings`` ((N,) each) grow with every ``/swarm/poses`` message of
    N poses whose stamp is newer than the last one (a re-published state, or one
    of another size, is skipped; poses not in the world frame or with bad values
    fail the test), and ``desired`` holds the ``/swarm/desired_velocity`` messages.
    ``on_poses(t, positions, headings)``, if set, is called (in the spin thread)
    for every valid message of N poses, re-published ones included, once it is
    sampled.
    """

    def __init__(self, name: str = "test_probe", keep_clients: bool = False) -> None:
        #: One service client per service, kept (else one per call): through a discovery
        #: server a client made again for the same service sometimes got no answer
        #: (:meth:`aes_ros.ros.launch.monitor.Monitor.call`).
        self.keep_clients = keep_clients
        self._clients: dict[tuple[type, str], Any] = {}
        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.errors: list[BaseException] = []
        self.n: int | None = None
        self.times: list[float] = []
        self.positions: list[np.ndarray] = []
        self.headings: list[np.ndarray] = []
        self.desired: list[TwistStamped] = []
        self.on_poses: Callable[[float, np.ndarray, np.ndarray], None] | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name=f"{name}-spin", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while not self._stop.is_set():
            try:
                self.executor.spin_once(timeout_sec=0.05)
            except ExternalShutdownException:
                return
            except Exception as exc:  # a callback failed: the test thread raises it
                self.errors.append(exc)

    def check(self) -> None:
        """Raise the first exception a callback raised, if any."""
        if self.errors:
            raise self.errors[0]

    # --------------------------------------------------------------------- topics

    def record(
        self, msg_type: type, topic: str, qos: Any, convert: Callable[[Any], Any] | None = None
    ) -> list:
        """Messages received on ``topic`` (or ``convert(message)``), appended as they arrive."""
        received: list = []
        callback = received.append if convert is None else (lambda m: received.append(convert(m)))
        self.node.create_subscription(msg_type, topic, callback, qos)
        return received

    def publisher(
        self, msg_type: type, topic: str, qos: Any, wait: bool = True, subscribers: int = 1
    ):
        """A publisher on ``topic``; with ``wait``, once ``subscribers`` have matched."""
        pub = self.node.create_publisher(msg_type, topic, qos)
        if wait:
            self.wait(
                lambda: pub.get_subscription_count() >= subscribers,
                TIMEOUT,
                f"{subscribers} subscriber(s) of {topic}",
            )
        return pub

    def every(self, period: float, callback: Callable[[], None]) -> None:
        """Call ``callback`` every ``period`` s (wall time) in the spin thread."""
        self.node.create_timer(period, callback)

    # --------------------------------------------------------------------- waiting

    def wait(self, predicate: Callable[[], object], timeout: float, what: str) -> None:
        """Wait until ``predicate()`` is true; fail the test naming ``what`` after
        ``timeout`` s (wall time)."""
        __tracebackhide__ = True  # the failure points at the test's line
        deadline = time.monotonic() + timeout
        while True:
            self.check()
            if predicate():
                return
            if time.monotonic() > deadline:
                pytest.fail(f"timed out after {timeout} s waiting for {what} (sim t={self.now})")
            time.sleep(0.02)

    def exchange(self, send: Callable[[], object], received: list, timeout: float = TIMEOUT,
                 resend: float = 0.5) -> Any:  # fmt: skip
        """Call ``send()`` (again every ``resend`` s: best-effort input) until a new
        message arrives in ``received``; return it."""
        count = len(received)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            send()
            end = time.monotonic() + resend
            while time.monotonic() < end:
                self.check()
                if len(received) > count:
                    return received[-1]
                time.sleep(0.02)
        raise AssertionError("no reply")

    def until(self, send: Callable[[], object], check: Callable[[], object],
              timeout: float = TIMEOUT) -> None:  # fmt: skip
        """Call ``send()`` until ``check()`` is true (for inputs that may arrive late)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            send()
            end = time.monotonic() + 0.3
            while time.monotonic() < end:
                self.check()
                if check():
                    return
                time.sleep(0.02)
        assert check()

    # --------------------------------------------------------------------- services

    def call(self, srv_type: type, name: str, request: Any, timeout: float = TIMEOUT) -> Any:
        """Call service ``name``; fail the test if it is not offered or does not
        answer within ``timeout`` s."""
        client = self._clients.get((srv_type, name)) or self.node.create_client(srv_type, name)
        if self.keep_clients:
            self._clients[(srv_type, name)] = client
        try:
            self.wait(client.service_is_ready, timeout, f"service {name}")
            future = client.call_async(request)
            self.wait(future.done, timeout, f"answer of {name}")
            return future.result()
        finally:
            if not self.keep_clients:
                self.node.destroy_client(client)

    def set_parameters(self, node: str, params: Sequence[Parameter]) -> list:
        """SetParameters on ``node``: one result (``successful``, ``reason``) each."""
        request = SetParameters.Request(parameters=[p.to_parameter_msg() for p in params])
        return self.call(SetParameters, f"{node}/set_parameters", request).results

    def set_parameters_atomically(self, node: str, params: Sequence[Parameter]) -> Any:
        """SetParametersAtomically on ``node``: the one result."""
        request = SetParametersAtomically.Request(parameters=[p.to_parameter_msg() for p in params])
        return self.call(
            SetParametersAtomically, f"{node}/set_parameters_atomically", request
        ).result

    def get_parameters(self, node: str, names_: Sequence[str]) -> list:
        """The values of ``names_`` on ``node``, as Python values."""
        request = GetParameters.Request(names=list(names_))
        response = self.call(GetParameters, f"{node}/get_parameters", request)
        return [parameter_value_to_python(v) for v in response.values]

    # --------------------------------------------------------------------- the swarm

    def sample_poses(self, n: int) -> Probe:
        """Start sampling ``/swarm/poses`` of ``n`` robots and ``/swarm/desired_velocity``."""
        self.n = n
        self.node.create_subscription(PoseArray, names.POSES, self._on_poses, STREAM, raw=True)
        self.node.create_subscription(
            TwistStamped, names.DESIRED_VELOCITY, self.desired.append, LATCHED
        )
        return self

    def _on_poses(self, data: bytes) -> None:
        frame = frame_id(data)
        assert frame == names.WORLD_FRAME, f"{names.POSES} in frame {frame!r}"
        sec, nanosec, pos, head = decode_pose_array(data)
        if len(pos) != self.n:
            return
        t = sec + nanosec * 1e-9
        if not self.times or t > self.times[-1]:
            # The time last: an index valid in ``times`` is valid in the others.
            self.positions.append(pos)
            self.headings.append(head)
            self.times.append(t)
        if self.on_poses is not None:  # after the append: what it saw is sampled
            self.on_poses(t, pos, head)

    def forget_poses(self) -> None:
        """Drop the samples (a new bridge starts its clock at 0 again)."""
        self.times.clear()
        self.positions.clear()
        self.headings.clear()

    def sample(self, k: int = -1) -> tuple[float, np.ndarray, np.ndarray]:
        """Sample ``k`` (negative: counted from the newest) as (t, positions, headings)."""
        k = k if k >= 0 else len(self.times) + k
        return self.times[k], self.positions[k], self.headings[k]

    @property
    def now(self) -> float:
        """Sim time [s] of the newest sample (-1 before the first)."""
        return self.times[-1] if self.times else -1.0

    def wait_sim(self, t: float, timeout: float = 60.0) -> None:
        self.wait(lambda: self.now >= t, timeout, f"sim time {t}")

    def wait_all_moving(self, timeout: float = 120.0) -> float:
        """Wait until every robot has moved from its first sampled position; returns
        that sim time (robots start a few seconds after the bridge's clock in real time)."""

        def moving() -> bool:
            k = len(self.times) - 1
            return k > 0 and bool(
                np.all(np.linalg.norm(self.positions[k] - self.positions[0], axis=-1) > 1e-4)
            )

        self.wait(moving, timeout, "every robot moving")
        return self.now

    def index_at(self, t: float) -> int:
        """The first sample at or after sim time t (else the last one)."""
        times = self.times[:]
        k = int(np.searchsorted(np.asarray(times), t - 1e-9))
        return min(k, len(times) - 1)

    def position_at(self, t: float) -> np.ndarray:
        """Positions (N, 2) of the first sample at or after sim time t."""
        return self.positions[self.index_at(t)]

    def motion(self, t0: float, t1: float) -> np.ndarray:
        """Per robot, the larger of its displacement [m] and its turn [rad] from t0 to t1."""
        a, b = self.index_at(t0), self.index_at(t1)
        moved = np.linalg.norm(self.positions[b] - self.positions[a], axis=-1)
        turned = np.abs(np.angle(np.exp(1j * (self.headings[b] - self.headings[a]))))
        return np.maximum(moved, turned)

    # --------------------------------------------------------------------- end

    def close(self) -> None:
        """Stop spinning, destroy the node, shut the context down; raise a callback's
        exception if there was one."""
        self._stop.set()
        self._thread.join(timeout=5)
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self.check()


def frame_id(data: bytes) -> str:
    """The ``header.frame_id`` of a raw (CDR) message that starts with a Header."""
    order = "<" if data[1] == 1 else ">"
    (length,) = struct.unpack_from(order + "I", data, 4 + 8)
    return data[16 : 16 + length - 1].decode()
