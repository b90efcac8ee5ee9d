"""Spinning nodes on rclpy's EventsExecutor until SIGINT or SIGTERM.

Shared by every node process (robot node, robot host, supervisor, bridge). The
EventsExecutor is 2–3x cheaper per callback than the SingleThreadedExecutor
(docs/design.md#ros-interface). Its ``spin()`` of this rclpy (7.1) busy-loops once the context is
shut down, and rclpy's own signal handler shuts the context down under a
running callback, which then fails ("Unable to convert call argument", a
publish on a dead context) and turns a clean Ctrl-C into exit code 1. So
processes call ``rclpy.init(..., signal_handler_options=SignalHandlerOptions.NO)``
and :func:`spin` handles the signals itself: they only set a flag, checked
between bounded ``spin_once`` slices; the caller then destroys its nodes and
shuts rclpy down in order.
"""

from __future__ import annotations

import contextlib
import gc
import inspect
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import rclpy
from rclpy.duration import Duration
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.node import Node
from rclpy.qos import ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future

from aes_ros.params import ParameterError

#: Longest a spin call blocks before the stop check [s] (the shutdown latency).
SPIN_SLICE = 0.25
#: Longest the whole process waits at exit for reliable readers to acknowledge [s]
#: (on a loaded machine acknowledgements can take a second; a dead reader never sends one).
FLUSH_TIMEOUT = 3.0
#: Errors that mean a node cannot start with what it was given: logged, exit code 1.
STARTUP_ERRORS = (
    ParameterError,
    InvalidParameterValueException,
    InvalidParameterTypeException,
    rclpy_implementation.RCLError,  # e.g. a --params-file that is missing or not valid YAML
)
#: How long one publisher is waited for in a round of :func:`flush_publishers` [ns].
FLUSH_POLL_NS = 2_000_000


@contextlib.contextmanager
def stop_signals(handler: Callable[[str], None]) -> Iterator[None]:
    """While active, SIGINT and SIGTERM call ``handler`` with the signal's name instead
    of ending the process (in the main thread only, as :func:`signal.signal`)."""

    def on_signal(signum: int, _frame: object) -> None:
        handler(signal.Signals(signum).name)

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def spin(nodes: list[Node], executor: Executor | None = None) -> str:
    """Spin ``nodes`` on one EventsExecutor (or ``executor``) until SIGINT or SIGTERM (or
    rclpy shuts down).

    Must run in the main thread. Before returning it waits (at most
    FLUSH_TIMEOUT s in all) until the reliable readers of every publisher have
    acknowledged what was published, so that the last messages before a stop
    reach a recorder instead of dying with the node. Returns the name of the
    signal that ended it ("" if rclpy was shut down otherwise).
    """
    received: list[str] = []
    stop = threading.Event()
    # The current slice's future: a signal during a callback ends the slice at once.
    # One per slice: rclpy's own executors add a done-callback per call.
    slice_done = [Future()]

    def on_signal(name: str) -> None:
        received.append(name)
        stop.set()
        if not slice_done[0].done():
            slice_done[0].set_result(received[0])

    with stop_signals(on_signal):
        executor = EventsExecutor() if executor is None else executor
        for node in nodes:
            executor.add_node(node)
        try:
            while not stop.is_set() and rclpy.ok():
                # A slice handles every event that comes within SPIN_SLICE in C++;
                # spin_once returned to Python after each one (18 % more CPU per message).
                slice_done[0] = Future()
                executor.spin_until_future_complete(slice_done[0], timeout_sec=SPIN_SLICE)
        finally:
            executor.shutdown()
    if rclpy.ok() and not flush_publishers(nodes, FLUSH_TIMEOUT) and nodes:
        nodes[0].get_logger().warning(
            f"stopping with messages not acknowledged by every reader after {FLUSH_TIMEOUT} s"
        )
    return received[0] if received else ""


def flush_publishers(nodes: list[Node], timeout: float) -> bool:
    """Wait until every reliable publisher of ``nodes`` is acknowledged by its readers.

    ``timeout`` [s] bounds the whole wait (a dead reader never acknowledges). The
    publishers are polled in turn rather than waited for one by one, so that one
    slow reader (a neighbour process that is stopping too) does not use up the
    time of all the others. Returns True if everything was acknowledged in time.
    """
    deadline = time.monotonic() + timeout
    poll = Duration(nanoseconds=FLUSH_POLL_NS)
    pending = [
        pub
        for node in nodes
        for pub in node.publishers
        if pub.qos_profile.reliability == ReliabilityPolicy.RELIABLE
    ]
    while pending:
        pending = [pub for pub in pending if not pub.wait_for_all_acked(poll)]
        if pending and time.monotonic() > deadline:
            return False
    return True


def run_node_process(
    name: str,
    args: Sequence[str] | None,
    make: Callable[[], Node],
    spun: Callable[[Node], list[Node]] = lambda node: [node],
) -> int:
    """The ``main()`` of a node process: init rclpy without its signal handler,
    build the node with ``make()``, :func:`spin` ``spun(node)`` until SIGINT or
    SIGTERM, then destroy the node and shut down.

    Returns the exit code: 0 after a signal, 1 if the node cannot start (a
    :data:`STARTUP_ERRORS` error, logged as ``cannot start: <reason>`` under
    ``name``; no traceback).
    """
    if wants_help(args):
        # rclpy ignores --help: without this, `aes-robot-host --help` started a swarm
        print(node_help(make))
        return 0
    node = None
    try:
        # Inside the try: a bad --params-file is a startup error, not a traceback.
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        node = make()
        # The nodes' objects live as long as the process: leave them out of every
        # garbage collection (full collections over them were 2-3 % of the bridge).
        gc.freeze()
        spin(spun(node))
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except STARTUP_ERRORS as exc:
        rclpy.logging.get_logger(name).fatal(f"cannot start: {exc}")
        return 1
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


def wants_help(args: Sequence[str] | None) -> bool:
    """True when ``-h`` or ``--help`` comes before ``--ros-args`` in the command line
    (``args``, or ``sys.argv`` when None)."""
    argv = list(sys.argv[1:] if args is None else args[1:])
    own = argv[: argv.index("--ros-args")] if "--ros-args" in argv else argv
    return "-h" in own or "--help" in own


def node_help(make: Callable[[], Node]) -> str:
    """The help of a node process: how to start it (its module's docstring) and its
    parameters (its class's docstring)."""
    make = getattr(make, "func", make)  # a functools.partial: its function's help
    module = sys.modules.get(getattr(make, "__module__", ""), None)
    parts = [
        f"usage: {Path(sys.argv[0]).name} [--ros-args -p NAME:=VALUE ... "
        "| --params-file FILE | -r FROM:=TO]",
        inspect.getdoc(module) if module is not None else None,
        inspect.getdoc(make),
    ]
    return "\n\n".join(part for part in parts if part)
