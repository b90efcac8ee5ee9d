"""The ``sim_bridge`` node: a pybullet world of Mona robots on ROS 2 (docs/design.md#ros-interface).

Start it (headless, the combined scenario's 10 x 10 formation)::

    aes-sim-bridge
    aes-sim-bridge --ros-args -p scenario:=linear -p num_robots:=16 -p seed:=3 \
        -p mode:=dynamic -p gui:=true
    aes-sim-bridge --ros-args -p lockstep:=true -p real_time_factor:=0.0 -p clip:=false

Every control period (1 / ``publish_rate`` of sim time) it steps the world with
the robots' latest ``cmd_vel`` and publishes ``/clock``, ``/swarm/poses`` and
``/mona_<i>/odom``. The world is stepped from a timer of the executor, not from
a thread of its own.
"""

from __future__ import annotations

import json
import math
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Twist
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock as ClockMsg
from std_srvs.srv import SetBool, Trigger

from aes_ros.obstacles import contact_arrays
from aes_ros.params import ParameterError
from aes_ros.perception import PerceptionSettings
from aes_ros.ros import interface as names
from aes_ros.ros import parameters as rp
from aes_ros.ros.cdr import decode_twist
from aes_ros.ros.conversions import BadMessageError, stamp_to_ns
from aes_ros.ros.diagnostics import SILENT_AFTER, robots_status
from aes_ros.ros.node_tools import ThrottledWarnings
from aes_ros.ros.qos import LATCHED, LATEST_COMMAND
from aes_ros.ros.spin import run_node_process
from aes_ros.world_state import WorldState
from sim_bridge.ir_sensors import IrSensors
from sim_bridge.lockstep import LockstepBarrier
from sim_bridge.loop_stats import ControlLoopStats
from sim_bridge.parameters import declare_bridge_parameters
from sim_bridge.state_output import StateOutput
from sim_bridge.world import World

#: Wall-clock time [s] after which a lockstep bridge still waiting for commands
#: publishes the same state again (a pose message may have been lost).
REPUBLISH_AFTER = 1.0
#: While a resumed bridge waits for the swarm, it publishes its state this often [s].
RESUME_REPUBLISH = 0.2


class SimBridgeNode(Node):
    """A pybullet world of N Mona robots behind ROS topics.

    Parameters (ROS): ``scenario`` and ``num_robots`` as every node declares them
    (:func:`aes_ros.ros.parameters.declare_scenario`), the rest in
    :func:`sim_bridge.parameters.declare_bridge_parameters`, each once with its default,
    range and description (listed in docs/interface.md). What some of them do beyond
    their one line: the initial state is ``Scenario.initial_state(seed)``, the offline
    simulator's start with that seed; with ``resume_from`` the bridge carries on from a
    world state file (:class:`aes_ros.world_state.WorldState`), its clock too, and
    publishes that state until every robot has answered it (at most
    ``lockstep_timeout`` wall seconds) before it steps on, so that no robot stands still
    while it finds the new bridge; in ``lockstep`` a robot silent for longer than
    ``lockstep_timeout`` leaves the barrier (its body stopped, logged) until it answers
    again, so a dead robot does not stall the swarm (:mod:`sim_bridge.lockstep`), and
    with ``wait_for_recorder`` each step also waits until the recorder has written the
    state published last: a lossless recording at any load.

    The scenario's ``contacts``, ``walls`` and ``obstacles`` go to the world
    (:class:`sim_bridge.world.World`).

    Topics: publishes ``/clock``, ``/swarm/poses`` (PoseArray, frame odom,
    index = robot id), ``/mona_<i>/odom`` (:class:`sim_bridge.state_output.StateOutput`),
    ``/mona_<i>/ir_<k>`` (IR sensors; their ``ir_*`` parameters:
    :class:`sim_bridge.ir_sensors.IrSensors`); subscribes ``/mona_<i>/cmd_vel``. With
    the scenario's perception error on (``perception_*``, :mod:`aes_ros.perception`),
    ``/swarm/poses`` is what a tracker would show the robots
    (:mod:`sim_bridge.perceived_poses`) and the exact poses go to
    ``/sim/ground_truth/poses``; odometry stays exact.
    Services: ``/sim/reset`` (Trigger: back to the initial state, every robot
    stopped; the clock keeps running), ``/sim/pause`` (SetBool: true pauses),
    ``/sim/stats`` (Trigger: JSON of the control loop since the previous call, see
    :meth:`on_stats`; ``bench/bench_ros.py`` uses it).
    """

    def __init__(self, **kwargs) -> None:
        super().__init__(names.SIM_BRIDGE_NODE, **kwargs)
        self._warn = ThrottledWarnings(self.get_logger())
        scenario = rp.declare_scenario(self)
        declare_bridge_parameters(self, scenario.ir_rate)
        get = self.get_parameter
        self.scenario = scenario
        positions, headings = scenario.initial_state(get("seed").value)
        self.n = len(headings)
        self.rate = get("publish_rate").value
        self.dt = 1.0 / self.rate
        self.limits = (scenario.max_linear_speed, scenario.max_angular_speed)
        self.lockstep = get("lockstep").value
        self.real_time_factor = get("real_time_factor").value
        try:
            walls, circles, boxes = contact_arrays(scenario.values)
            self.world = World(
                positions,
                headings,
                mode=get("mode").value,
                dt=self.dt,
                physics_rate=get("physics_rate").value,
                cmd_timeout=get("cmd_timeout").value,
                limits=self.limits if get("clip").value else None,
                gui=get("gui").value,
                contacts=scenario.contacts,
                walls=walls,
                circles=circles,
                boxes=boxes,
            )
            if get("resume_from").value:
                state = WorldState.load(get("resume_from").value, self.n)
                self.world.restore(state.positions, state.headings, round(state.t / self.dt))
        except (ValueError, RuntimeError) as exc:  # a world that cannot be built
            raise ParameterError(str(exc)) from None
        self.paused = False
        #: Sim time [s] at which the world holds (0: never); held: paused by it.
        self.pause_at = get("pause_at").value
        self.held = False
        #: Wall time since when a resumed bridge waits for the swarm (None: not waiting).
        self.resuming_since = time.monotonic() if get("resume_from").value else None
        # Members 0..n-1 are the robots; member n the recorder, with wait_for_recorder.
        self.recorder_member = self.n if get("wait_for_recorder").value else None
        self.barrier = LockstepBarrier(
            self.n + (self.recorder_member is not None), get("lockstep_timeout").value
        )
        self.waiting = False  # lockstep at full speed: step timer parked until all arrived
        self.steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.last_publish = time.monotonic()
        self.publish_wall = self.last_publish  # when the newest state went out [s, monotonic]
        self.stats = ControlLoopStats(self.n, self.last_publish, self.world.step_count, self.dt)

        self.output = StateOutput(
            self, self.world, PerceptionSettings.from_mapping(scenario.values), self.rate,
            get("seed").value,
        )  # fmt: skip
        # Every QoS event handler is one more entity in each wait of the executor;
        # robot 0's report incompatible QoS (all robots are alike), the others none.
        quiet_sub = SubscriptionEventCallbacks(use_default_callbacks=False)
        self.cmd_subs = [
            self.create_subscription(
                Twist,
                names.robot_topic(i, names.CMD_VEL),
                self._cmd_callback(i),
                LATEST_COMMAND,
                event_callbacks=quiet_sub if i else None,
                raw=True,  # decoded by struct: no Twist object per command
            )
            for i in range(self.n)
        ]
        if self.recorder_member is not None:
            self.create_subscription(
                ClockMsg, names.RECORDER_PROGRESS, self.on_recorder_progress, LATCHED
            )
        self.create_service(Trigger, names.SIM_RESET, self.on_reset)
        self.create_service(SetBool, names.SIM_PAUSE, self.on_pause)
        self.create_service(Trigger, names.SIM_STATS, self.on_stats)
        self.ir = IrSensors(self, self.world, get("seed").value)  # /mona_<i>/ir_<k>
        self.add_post_set_parameters_callback(self.on_parameters_set)

        self.step_timer = self.create_timer(self._step_period(), self.on_step, clock=self.steady)
        self.watchdog = self.create_timer(0.25, self.on_watchdog, clock=self.steady)
        self.diagnostics_pub = self.create_publisher(DiagnosticArray, names.DIAGNOSTICS, LATCHED)
        self.create_timer(1.0, self.on_diagnostics, clock=self.steady)
        if abs(scenario.dt - self.dt) > 1e-12:
            self.get_logger().warning(
                f"publish_rate {self.rate:g} Hz differs from the scenario's dt = "
                f"{scenario.dt:g} s; robots should use dt = {self.dt:g} s"
            )
        # Said before the first state goes out: whoever sees the state can find the line.
        self.get_logger().info(
            f"{names.BRIDGE_READY} {self.n} robots, {self.world.mode} mode, {self.rate:g} Hz "
            f"control, {self.world.substeps} physics steps per period, lockstep={self.lockstep}"
            f", real_time_factor={self.real_time_factor:g}, t={self.world.time:g} s"
        )
        self.publish_state()

    def _cmd_callback(self, robot_id: int):
        def on_cmd_vel(data: bytes) -> None:
            self.on_cmd_vel(robot_id, data)

        return on_cmd_vel

    def on_diagnostics(self) -> None:
        """Once a wall second: which robots have gone silent (/diagnostics)."""
        silent = self.barrier.silent(time.monotonic(), SILENT_AFTER)
        silent = silent[silent < self.n]  # the recorder's place is not a robot
        self.diagnostics_pub.publish(robots_status(self.n, silent, self.get_clock().now().to_msg()))

    def _step_period(self) -> float:
        """Wall period [s] of the step timer."""
        return self.dt / self.real_time_factor if self.real_time_factor > 0.0 else 0.0

    # --- callbacks ---------------------------------------------------------------
    def on_cmd_vel(self, robot_id: int, data: bytes) -> None:
        """Store robot ``robot_id``'s command (raw ``Twist``: linear.x, angular.z); in
        lockstep, step once all are in."""
        try:
            u, turn = decode_twist(data)
        except BadMessageError as exc:
            self._warn(f"dropped a cmd_vel of robot {robot_id}: {exc}")
            return
        if not (math.isfinite(u) and math.isfinite(turn)):
            self._warn(f"dropped a non-finite cmd_vel: robot {robot_id}")
            return
        self.world.set_command(robot_id, u, turn)
        now = time.monotonic()
        self.stats.command(robot_id, now - self.publish_wall)
        self._arrived(robot_id, now, f"robot {robot_id}")

    def on_recorder_progress(self, msg: ClockMsg) -> None:
        """The recorder has written the poses up to its stamp: it answered this step
        if that is the state published last."""
        if stamp_to_ns(msg.clock) >= stamp_to_ns(self.output.stamp):
            self._arrived(self.recorder_member, time.monotonic(), "the recorder")

    def _arrived(self, member: int, now: float, who: str) -> None:
        if self.barrier.arrived(member, now) and self.lockstep:
            self.get_logger().info(f"lockstep: {who} answered again: back in the barrier")
        if self.waiting and self.barrier.complete:
            self._restart_stepping()

    def _drop_silent(self) -> None:
        """Lockstep: members silent for longer than lockstep_timeout leave the barrier;
        a robot that leaves is stopped."""
        for member in self.barrier.drop_silent(time.monotonic()).tolist():
            if member == self.recorder_member:
                who = "the recorder"
            else:
                who = f"robot {member}"
                self.world.stop(member)
            self.get_logger().warning(
                f"lockstep: {who} silent for {self.barrier.timeout:g} s at t={self.world.time:g}"
                f" s: left the barrier{'' if member == self.recorder_member else ', stopped'}"
            )

    def _restart_stepping(self) -> None:
        """(Re)start the step timer unless paused; :meth:`on_step` parks it again if need be."""
        self.waiting = False
        if not self.paused:
            self.step_timer.reset()

    def on_step(self) -> None:
        """Timer: one control step of the world, then publish the new state."""
        if self.paused or not self._resumed():
            return
        if self.pause_at > 0.0 and self.world.time >= self.pause_at:
            self._hold()
            return
        if self.lockstep and not self.barrier.complete:
            self._drop_silent()
        if self.lockstep and not self.barrier.complete:
            if self.real_time_factor == 0.0:
                # Park the busy timer; on_cmd_vel restarts it when the last command is in.
                self.step_timer.cancel()
                self.waiting = True
            return
        self.world.step()
        self.stats.bodies(*self.world.last_contacts)
        self.publish_state()
        # the members' time to answer starts when this state is out and the bridge listens
        # again: a slow step (a busy machine, the first step's cache loads) is not their
        # silence (it dropped healthy robots in CI, their answers queued behind the step)
        self.barrier.next_step(time.monotonic())

    def _hold(self) -> None:
        """Pause at ``pause_at``: the state published last is the one at that time."""
        self.paused = self.held = True
        self.step_timer.cancel()
        self.get_logger().info(f"paused at t={self.world.time:g} s (pause_at)")

    def _resumed(self) -> bool:
        """A resumed bridge steps on once every robot answered its state, or after
        lockstep_timeout; until then it publishes the state again now and then."""
        if self.resuming_since is None:
            return True
        now = time.monotonic()
        waited = now - self.resuming_since
        if self.barrier.complete or waited > self.barrier.timeout:
            missing = len(self.barrier.missing())
            how = (
                "every robot answered" if not missing else f"{missing} silent after {waited:.1f} s"
            )
            self.get_logger().info(f"resumed at t={self.world.time:g} s: {how}")
            self.resuming_since = None
            return True
        if now - self.last_publish > RESUME_REPUBLISH:
            self.publish_state()
        return False

    def on_watchdog(self) -> None:
        """Refresh the odometry listeners; in lockstep, re-publish the state if some
        robot has not answered for a while."""
        self.output.update_listeners()
        if not self.lockstep or self.paused or self.barrier.complete:
            return
        self._drop_silent()
        if self.barrier.complete:
            self._restart_stepping()
            return
        waited = time.monotonic() - self.last_publish
        if waited > REPUBLISH_AFTER:
            missing = self.barrier.missing()
            self.get_logger().info(
                f"lockstep: re-publishing t={self.world.time:g} s; no answer yet from "
                f"{len(missing)} members (first: {missing[:5].tolist()})",
                throttle_duration_sec=5.0,
            )
            self.publish_state()

    def on_reset(self, request: Trigger.Request, response: Trigger.Response):
        """Back to the initial state; every robot stopped; the clock keeps running."""
        self.world.reset()
        self.publish_state()
        self.barrier.next_step(time.monotonic())
        response.success = True
        response.message = f"reset {self.n} robots to the initial state at t={self.world.time:g} s"
        return response

    def on_pause(self, request: SetBool.Request, response: SetBool.Response):
        """``data`` true pauses the world (and the clock), false resumes it."""
        self.paused = bool(request.data)
        self.held = False
        if self.paused:
            self.step_timer.cancel()  # no busy timer while paused at real_time_factor 0
        else:
            self._restart_stepping()
        response.success = True
        response.message = "paused" if self.paused else "running"
        return response

    def on_stats(self, request: Trigger.Request, response: Trigger.Response):
        """Control-loop figures since the previous call (or the start), as JSON
        (:meth:`sim_bridge.loop_stats.ControlLoopStats.snapshot`): the real-time
        factor, per-robot ``cmd_vel`` rates, the latency from publishing a state to
        each ``cmd_vel`` arriving here, contacts per second and the smallest centre
        distance between bodies. Resets the counters."""
        stats = self.stats.snapshot(time.monotonic(), self.world.step_count)
        response.success = True
        response.message = json.dumps(stats)
        return response

    def on_parameters_set(self, params: list[Parameter]) -> None:
        """Apply runtime changes of real_time_factor, lockstep, lockstep_timeout,
        cmd_timeout, clip and pause_at."""
        for p in params:
            if p.name == "real_time_factor":
                self.real_time_factor = p.value
                self.step_timer.timer_period_ns = round(self._step_period() * 1e9)
                self._restart_stepping()
            elif p.name == "lockstep":
                self.lockstep = p.value
                self._restart_stepping()
            elif p.name == "lockstep_timeout":
                self.barrier.timeout = p.value
            elif p.name == "cmd_timeout":
                self.world.cmd_timeout = p.value
            elif p.name == "clip":
                self.world.limits = self.limits if p.value else None
            elif p.name == "pause_at":
                self.pause_at = p.value
                if self.held and (p.value == 0.0 or p.value > self.world.time):
                    self.paused = self.held = False
                    self._restart_stepping()

    # --- output ------------------------------------------------------------------
    def publish_state(self) -> None:
        """Publish the current step's state (:class:`sim_bridge.state_output.StateOutput`)
        and its IR readings."""
        self.publish_wall = time.monotonic()
        self.ir.publish(self.output.publish())
        self.last_publish = time.monotonic()

    def destroy_node(self) -> None:
        self.world.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """``aes-sim-bridge``: exit code 0 on SIGINT/SIGTERM, 1 when it cannot start
    (a bad parameter, a world that cannot be built)."""
    return run_node_process(names.SIM_BRIDGE_NODE, args, SimBridgeNode)


if __name__ == "__main__":
    sys.exit(main())
