"""The dashboard's control requests, carried out in its node's thread through the swarm's
public interface (docs/design.md#ros-interface): ``/swarm/enable``, ``/sim/pause``,
``/sim/reset``, the robots' and the supervisor's ``set_parameters`` (gains) and the supervisor's
``set_parameters_atomically`` (the swarm command).

The web server hands a request over with :meth:`ControlRequests.submit` and waits
CALL_TIMEOUT s for its (ok, message); an answer that comes later (a hung node) is
logged, and nothing a service answers, or fails to, raises in the node's thread.
"""

from __future__ import annotations

import concurrent.futures
import queue
import re
import threading
import time
from collections.abc import Callable
from typing import Any

from rcl_interfaces.srv import SetParameters, SetParametersAtomically
from rclpy.parameter import Parameter
from std_srvs.srv import SetBool, Trigger

from aes_ros.ros import interface as names
from dashboard_node.controls import Control, Drive, Enable, SetGain, SimAction

#: Wall seconds a service or parameter call may take before it counts as unanswered.
CALL_TIMEOUT = 5.0
#: Wall seconds a call waits for its service to be matched before "nobody offers it":
#: discovery of a service can lag behind the node's topics by a few seconds on a
#: loaded machine (1 click in 20 came too early, under CI load), and a click is not
#: lost for that.
SERVICE_WAIT = 4.0


class ControlRequests:
    """The request half of :class:`dashboard_node.node.DashboardNode` (a mixin of it).

    It uses what the node makes in ``__init__``: the clients ``drive_client``,
    ``enable_client``, ``pause_client`` and ``reset_client``, the queue ``_requests``,
    the list ``_waiting`` of calls whose service is not matched yet, ``_param_clients``,
    ``_warn``, ``_locked`` and ``view``; and the Node's ``create_client`` and
    ``get_node_names_and_namespaces``."""

    def submit(self, control: Control) -> concurrent.futures.Future:
        """Run ``control`` in the node's thread; the future's result is (ok, message)."""
        future: concurrent.futures.Future = concurrent.futures.Future()
        self._requests.put((control, future))
        return future

    def on_requests(self) -> None:
        self._waiting = [attempt for attempt in self._waiting if not attempt()]
        while True:
            try:
                control, future = self._requests.get_nowait()
            except queue.Empty:
                return
            try:
                self._run(control, future)
            except Exception as exc:  # a request must never take the node down
                self._settle(future, (False, f"{type(exc).__name__}: {exc}"))

    def _settle(self, future: concurrent.futures.Future, result: tuple[bool, str]) -> None:
        """Give a request its (ok, message), unless the viewer stopped waiting (the web
        server cancels it after CALL_TIMEOUT): then the late answer is only logged."""
        try:
            future.set_result(result)
        except concurrent.futures.InvalidStateError:
            self._warn(f"late answer: after the viewer's {CALL_TIMEOUT:g} s: {result[1]}")

    def _run(self, control: Control, future: concurrent.futures.Future) -> None:
        if isinstance(control, Drive):
            self._drive(control, future)
        elif isinstance(control, Enable):
            self._call(self.enable_client, SetBool.Request(data=control.enabled), future)
        elif isinstance(control, SimAction) and control.action == "reset":
            self._call(self.reset_client, Trigger.Request(), future)
        elif isinstance(control, SimAction):
            self._call(self.pause_client, SetBool.Request(data=control.action == "pause"), future)
        elif isinstance(control, SetGain):
            self._set_everywhere(control, future)

    def _drive(self, control: Drive, future: concurrent.futures.Future) -> None:
        """Set only the parts of the swarm command the viewer changed, as the
        supervisor's parameters in one atomic set (``ros2 param set`` would do the
        same): the other part stays whatever the swarm has now, whoever set it."""
        parameters = []
        if control.direction is not None:
            parameters.append(Parameter("desired_direction", value=list(control.direction)))
        if control.omega is not None:
            parameters.append(Parameter("rotation_rate", value=control.omega))
        said = ", ".join(f"{p.name} = {p.value}" for p in parameters)
        request = SetParametersAtomically.Request(
            parameters=[p.to_parameter_msg() for p in parameters]
        )

        def answer(response: Any) -> tuple[bool, str]:
            ok, reason = response.result.successful, response.result.reason
            return ok, f"supervisor: {said}" if ok else f"supervisor refused {said}: {reason}"

        self._call(self.drive_client, request, future, answer)

    def _call(
        self,
        client: Any,
        request: Any,
        future: concurrent.futures.Future,
        answer: Callable[[Any], tuple[bool, str]] = lambda r: (r.success, r.message),
    ) -> None:
        """Call ``client`` with ``request`` once its service is matched (at most
        SERVICE_WAIT s from now); ``answer`` turns its response into the future's (ok,
        message)."""
        deadline = time.monotonic() + SERVICE_WAIT

        def on_answer(call: Any) -> None:
            try:
                result = answer(call.result())
            except Exception as exc:  # no answer or a malformed one: say so, keep running
                result = (False, f"{client.srv_name}: {type(exc).__name__}: {exc}")
            self._settle(future, result)

        def attempt() -> bool:  # True: done with it
            try:
                if not client.service_is_ready():
                    if time.monotonic() < deadline:
                        return False
                    self._settle(future, (False, f"{client.srv_name}: nobody offers it"))
                    return True
                client.call_async(request).add_done_callback(on_answer)
            except Exception as exc:
                self._settle(future, (False, f"{client.srv_name}: {type(exc).__name__}: {exc}"))
            return True

        if not attempt():
            self._waiting.append(attempt)

    def _set_everywhere(self, control: SetGain, future: concurrent.futures.Future) -> None:
        """Set a gain on every robot node and the supervisor; the result counts the
        nodes that accepted it and quotes the reasons of those that did not."""
        targets = [
            f"{namespace.rstrip('/')}/{name}"
            for name, namespace in self.get_node_names_and_namespaces()
            if (name == names.ROBOT_NODE and re.fullmatch(names.ROBOT_NAMESPACE_PATTERN, namespace))
            or (name == names.SUPERVISOR_NODE and namespace == "/")
        ]
        if not targets:
            self._settle(future, (False, f"{control.name}: no robot node or supervisor found"))
            return
        request = SetParameters.Request(
            parameters=[Parameter(control.name, value=control.value).to_parameter_msg()]
        )
        results: dict[str, tuple[bool, str]] = {}
        lock = threading.Lock()

        def done(target: str, call: Any) -> None:
            with lock:
                try:
                    result = call.result().results[0]
                    results[target] = (result.successful, result.reason)
                except Exception as exc:  # no answer or a malformed one
                    results[target] = (False, f"{type(exc).__name__}: {exc}")
                if len(results) == len(targets):
                    self._settle(future, _summary(control, results))

        for target in targets:
            client = self._param_clients.get(target)
            if client is None:
                client = self.create_client(SetParameters, f"{target}/set_parameters")
                self._param_clients[target] = client
            call = client.call_async(request)
            call.add_done_callback(lambda c, t=target: done(t, c))

    def accepted(self, control: SetGain) -> None:
        """A gain the nodes took: the forces the page draws use it too."""
        self._locked(self.view.set_gain, control.name, control.value)


def _summary(control: SetGain, results: dict[str, tuple[bool, str]]) -> tuple[bool, str]:
    refused = {target: reason for target, (ok, reason) in results.items() if not ok}
    took = len(results) - len(refused)
    text = f"{control.name} = {control.value:g}: accepted by {took} of {len(results)} nodes"
    if refused:
        reasons = sorted(set(refused.values()))
        text += f"; refused by {', '.join(sorted(refused)[:3])}"
        text += f"{' …' if len(refused) > 3 else ''}: {' / '.join(reasons[:2])}"
    return not refused, text
