"""A pybullet world of N Mona robots, free of ROS (docs/design.md#mona, #ros-interface).

The scenario's walls and obstacles are static bodies (:mod:`sim_bridge.arena`). Two modes:

``kinematic``
    The body follows its command exactly, as the paper's Webots supervisor did:
    one explicit Euler step per control period with
    :func:`aes_ros.model.unicycle_step` (the offline simulator's model), the
    result written into pybullet (every step with the GUI, else when pybullet is
    queried). With ``contacts`` on, each step ends with
    :func:`aes_ros.contacts.resolve_contacts` (bodies, walls and obstacles as discs,
    rectangles and circles, in the offline simulator's order, so a lockstep run equals
    the offline one); with it off, robots pass through each other and everything.
``dynamic``
    Wheel motors with velocity control (saturated at the Mona's top wheel
    speed), tyre friction on the floor, a frictionless caster ball and
    collisions between the body cylinders, walls and obstacles, whatever
    ``contacts`` says (wheels and caster touch only the floor, which keeps 100 robots
    at 240 Hz faster than real time); pybullet steps ``substeps`` times per control
    period.

Either way :attr:`World.last_contacts` gives the contacts of the last step and the
smallest robot-robot centre distance after it (resolved, or measured as
:func:`aes_ros.contact_measures.measure_contacts` counts them).

A robot's pose is that of its ``base_link`` (:mod:`sim_bridge.mona`): the
ground point under the axle midpoint, ``(x, y)`` [m; odom] and yaw θ [rad].

Commands carry the control step at which they arrived; a command older than
``cmd_timeout`` seconds of sim time counts as zero, so a silent robot stops.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import numpy as np
import pybullet as pb

from aes_ros.contact_measures import TOUCH_TOLERANCE, measure_contacts
from aes_ros.contacts import ITERATIONS, contact_geometry, resolve_contacts
from aes_ros.frames import yaw_from_quaternion
from aes_ros.model import clip_commands, unicycle_step, wrap_angle
from aes_ros.ros.interface import MODES
from sim_bridge.arena import add_arena
from sim_bridge.mona import MonaGeometry, urdf

# pybullet collision groups (a pair collides if each one's group is in the other's mask)
_BODY, _FLOOR, _WHEEL, _ALL = 1, 2, 4, 0xFFFF
#: Dynamic mode: bodies closer than this [m] count as touching (pybullet's resting
#: contacts sit a fraction of a millimetre in or out).
DYNAMIC_TOUCH = 5e-4


class World:
    """N Mona robots in pybullet.

    Parameters
    ----------
    positions : (N, 2) initial positions [m; odom].
    headings : (N,) initial headings [rad].
    mode : "kinematic" or "dynamic".
    dt : control period [s]: one :meth:`step` advances the sim time by ``dt``.
    physics_rate : pybullet rate [Hz] in dynamic mode; rounded to a whole
        number ``substeps`` of physics steps per control period (at least 1).
    cmd_timeout : [s] of sim time; an older command counts as zero.
    limits : (max_linear_speed [m/s], max_angular_speed [rad/s]) to clip
        commands to, or None for no clipping (dynamic mode still saturates the
        wheels at ``geometry.max_wheel_speed``).
    geometry : the robot (docs/design.md#mona defaults).
    gui : open the pybullet GUI instead of a headless (DIRECT) server.
    solver_iterations : pybullet constraint-solver iterations per physics step
        (pybullet's default is 50; 10 is ~3x faster and ample for these
        contacts — the world tests check driving, turning and collisions).
    contacts : kinematic mode: resolve contacts after every step (the offline
        simulator's rule); dynamic mode always collides.
    walls : (4,) x_min, x_max, y_min, y_max [m] of the arena's walls, or None / empty.
    circles : (M, 3) obstacles x, y, r [m]. boxes : (L, 4) obstacles x_min, x_max,
        y_min, y_max [m].
    contact_iterations : sweeps of :func:`aes_ros.contacts.resolve_contacts`.
    """

    def __init__(
        self,
        positions: np.ndarray,
        headings: np.ndarray,
        *,
        mode: str = "kinematic",
        dt: float = 0.05,
        physics_rate: float = 240.0,
        cmd_timeout: float = 0.5,
        limits: tuple[float, float] | None = None,
        geometry: MonaGeometry | None = None,
        gui: bool = False,
        solver_iterations: int = 10,
        contacts: bool = False,
        walls: np.ndarray | None = None,
        circles: np.ndarray | None = None,
        boxes: np.ndarray | None = None,
        contact_iterations: int = ITERATIONS,
    ) -> None:
        if mode not in MODES:
            raise ValueError(f"mode: {mode!r} is not allowed; use one of {', '.join(MODES)}")
        if dt <= 0.0 or physics_rate <= 0.0:
            raise ValueError("dt and physics_rate must be positive")
        self.initial = (
            np.array(positions, dtype=float).reshape(-1, 2),
            np.array(headings, dtype=float).reshape(-1),
        )
        self.n = len(self.initial[1])
        if len(self.initial[0]) != self.n:
            raise ValueError("positions and headings differ in length")
        self.mode, self.dt = mode, float(dt)
        self.substeps = max(1, round(physics_rate * dt))
        self.cmd_timeout, self.limits = float(cmd_timeout), limits
        self.geometry = geometry or MonaGeometry()
        self.solver_iterations = int(solver_iterations)
        self.contacts, self.contact_iterations = bool(contacts), int(contact_iterations)
        #: walls (4,) or (0,), circles (M, 3), boxes (L, 4) [m]
        self.arena = contact_geometry(walls, circles, boxes)
        #: contacts of the last step and the smallest centre distance [m] after it
        self.last_contacts: tuple[int, float] = (0, np.inf)
        self.step_count = 0
        self.commands = np.zeros((self.n, 2))  #: last (u, turn rate) per robot
        self.command_step = np.full(self.n, np.iinfo(np.int64).min // 2)  #: when it arrived
        self.applied = np.zeros((self.n, 2))  #: commands used by the last step
        self._positions, self._headings = self.initial[0].copy(), self.initial[1].copy()
        self._bodies_stale = False  #: kinematic: pybullet's bodies lag the state
        if gui and sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
            raise RuntimeError("gui: no DISPLAY to open the pybullet window on")
        self._client = pb.connect(pb.GUI if gui else pb.DIRECT)
        if self._client < 0:
            raise RuntimeError("cannot connect to a pybullet physics server")
        self.gui = gui
        try:
            self._build()
        except Exception:
            self.close()
            raise

    # --- construction -------------------------------------------------------
    def _build(self) -> None:
        c, g = self._client, self.geometry
        if self.mode == "dynamic":  # kinematic bodies are only placed, never simulated
            pb.setGravity(0.0, 0.0, -9.81, physicsClientId=c)
        pb.setTimeStep(self.dt / self.substeps, physicsClientId=c)
        pb.setPhysicsEngineParameter(numSolverIterations=self.solver_iterations, physicsClientId=c)
        plane = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=c)
        self._ground = pb.createMultiBody(0.0, plane, physicsClientId=c)
        pb.changeDynamics(self._ground, -1, lateralFriction=1.0, physicsClientId=c)
        with tempfile.TemporaryDirectory(prefix="aes_mona_") as tmp:
            path = Path(tmp) / "mona.urdf"
            path.write_text(urdf(g))
            flags = pb.URDF_USE_IMPLICIT_CYLINDER | pb.URDF_ENABLE_CACHED_GRAPHICS_SHAPES
            # Each body at its start pose right away: bodies piled up at the origin make
            # pybullet's broadphase test every later change against all the others.
            self.bodies = [
                pb.loadURDF(
                    str(path),
                    basePosition=centre,
                    baseOrientation=orientation,
                    flags=flags,
                    physicsClientId=c,
                )
                for centre, orientation in self._base_poses(*self.initial)
            ]
        # Robot-robot contacts only between bodies; wheels and caster touch only the
        # floor. The body rides ground_clearance above the floor on wheels and caster,
        # so it is not tested against the floor at all (100 fewer contact pairs).
        pb.setCollisionFilterGroupMask(self._ground, -1, _FLOOR, _ALL, physicsClientId=c)
        names = {
            pb.getJointInfo(self.bodies[0], j, physicsClientId=c)[1].decode(): j
            for j in range(pb.getNumJoints(self.bodies[0], physicsClientId=c))
        }
        self._wheels = [names["left_wheel_joint"], names["right_wheel_joint"]]
        caster = names["caster_joint"]
        for body in self.bodies:
            pb.changeDynamics(body, -1, lateralFriction=g.body_friction, physicsClientId=c)
            pb.setCollisionFilterGroupMask(body, -1, _BODY, _BODY, physicsClientId=c)
            for j in (*self._wheels, caster):
                pb.setCollisionFilterGroupMask(body, j, _WHEEL, _FLOOR, physicsClientId=c)
            for j in self._wheels:
                pb.changeDynamics(
                    body,
                    j,
                    lateralFriction=g.wheel_friction,
                    rollingFriction=0.0,
                    spinningFriction=0.0,
                    physicsClientId=c,
                )
            pb.changeDynamics(
                body,
                caster,
                lateralFriction=0.0,
                rollingFriction=0.0,
                spinningFriction=0.0,
                physicsClientId=c,
            )
        self.arena_bodies = add_arena(c, *self.arena, _BODY, _BODY)
        self._place(*self.initial)
        if self.gui:
            pb.configureDebugVisualizer(pb.COV_ENABLE_GUI, 0, physicsClientId=c)
            pos = self.initial[0]
            span = float(np.ptp(pos, axis=0).max()) if self.n > 1 else 0.0
            x, y = pos.mean(axis=0).tolist()
            pb.resetDebugVisualizerCamera(
                max(0.3, 1.2 * span), 0.0, -60.0, (x, y, 0.0), physicsClientId=c
            )

    def _place(self, positions: np.ndarray, headings: np.ndarray) -> None:
        """Put every body at its pose (at rest, on the ground)."""
        c = self._client
        for body, (centre, orientation) in zip(
            self.bodies, self._base_poses(positions, headings), strict=True
        ):
            pb.resetBasePositionAndOrientation(body, centre, orientation, physicsClientId=c)
            if self.mode == "dynamic":
                pb.resetBaseVelocity(body, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), physicsClientId=c)
                for j in self._wheels:
                    pb.resetJointState(body, j, 0.0, 0.0, physicsClientId=c)

    def _base_poses(
        self, positions: np.ndarray, headings: np.ndarray
    ) -> list[tuple[list[float], tuple[float, float, float, float]]]:
        """pybullet base pose of every body: (centre, quaternion x, y, z, w)."""
        half = 0.5 * headings
        return [
            (centre, (0.0, 0.0, qz, qw))
            for centre, qz, qw in zip(
                self._body_centres(positions, headings).tolist(),
                np.sin(half).tolist(),
                np.cos(half).tolist(),
                strict=True,
            )
        ]

    def _body_centres(self, positions: np.ndarray, headings: np.ndarray) -> np.ndarray:
        """pybullet base positions (N, 3): body centre, ``axle_offset`` ahead of base_link."""
        a = self.geometry.axle_offset
        out = np.empty((len(headings), 3))
        out[:, 0] = positions[:, 0] + a * np.cos(headings)
        out[:, 1] = positions[:, 1] + a * np.sin(headings)
        out[:, 2] = self.geometry.body_z + 1e-4  # just clear of the floor
        return out

    # --- commands -----------------------------------------------------------
    @property
    def time(self) -> float:
        """Sim time [s] since the start (not reset by :meth:`reset`)."""
        return self.step_count * self.dt

    def set_command(self, i: int, linear: float, angular: float) -> None:
        """Robot ``i``'s command (u [m/s], turn rate [rad/s]), arriving now."""
        self.commands[i] = linear, angular
        self.command_step[i] = self.step_count

    def set_commands(self, linear: np.ndarray, angular: np.ndarray) -> None:
        """Every robot's command, (N,) each, arriving now."""
        self.commands[:, 0], self.commands[:, 1] = linear, angular
        self.command_step[:] = self.step_count

    def active_commands(self) -> tuple[np.ndarray, np.ndarray]:
        """Commands for the next step: zero where stale, clipped to ``limits`` if set."""
        age = (self.step_count - self.command_step) * self.dt
        live = age <= self.cmd_timeout + 1e-9
        u = np.where(live, self.commands[:, 0], 0.0)
        turn = np.where(live, self.commands[:, 1], 0.0)
        if self.limits is not None:
            u, turn = clip_commands(u, turn, *self.limits)
        return u, turn

    # --- stepping -----------------------------------------------------------
    def step(self, commands: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """Advance one control period ``dt``.

        ``commands`` = (u (N,), turn rate (N,)) sets every robot's command first;
        otherwise the commands given by :meth:`set_command` are used.
        """
        if commands is not None:
            self.set_commands(*commands)
        u, turn = self.active_commands()
        self.applied[:, 0], self.applied[:, 1] = u, turn
        if self.mode == "kinematic":
            self._positions, self._headings = unicycle_step(
                self._positions, self._headings, u, turn, self.dt
            )
            if self.contacts:  # after the Euler step, as the offline simulator
                self.last_contacts = resolve_contacts(
                    self._positions, self._headings, *self._disc, *self.arena,
                    self.contact_iterations,
                )  # fmt: skip
            else:
                self.last_contacts = measure_contacts(
                    self._positions, self._headings, *self._disc, *self.arena, TOUCH_TOLERANCE
                )
            # pybullet only mirrors the state here: place the bodies when something
            # looks at them (the GUI every step, else _base_states), not 100 calls a step.
            self._bodies_stale = True
            if self.gui:
                self._sync_bodies()
        else:
            c = self._client
            left, right = self.geometry.wheel_speeds(u, turn)
            torque = [self.geometry.max_wheel_torque] * 2
            for body, wl, wr in zip(self.bodies, left.tolist(), right.tolist(), strict=True):
                pb.setJointMotorControlArray(
                    body,
                    self._wheels,
                    pb.VELOCITY_CONTROL,
                    targetVelocities=[wl, wr],
                    forces=torque,
                    physicsClientId=c,
                )
            for _ in range(self.substeps):
                pb.stepSimulation(physicsClientId=c)
            positions, headings = self.poses()
            self.last_contacts = measure_contacts(
                positions, headings, *self._disc, *self.arena, DYNAMIC_TOUCH
            )
        self.step_count += 1

    @property
    def _disc(self) -> tuple[float, float]:
        """The bodies of :mod:`aes_ros.contacts`: radius and axle offset [m]."""
        return self.geometry.body_radius, self.geometry.axle_offset

    def poses(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions (N, 2) [m] and headings (N,) [rad, in [-π, π)] of ``base_link``."""
        if self.mode == "kinematic":
            return self._positions.copy(), self._headings.copy()
        centres, quats = self._base_states()
        yaw = yaw_from_quaternion(quats)
        a = self.geometry.axle_offset
        pos = np.stack([centres[:, 0] - a * np.cos(yaw), centres[:, 1] - a * np.sin(yaw)], -1)
        return pos, wrap_angle(yaw)

    def velocities(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Body-frame twist of ``base_link``: forward, sideways [m/s] and turn rate [rad/s], (N,).

        Kinematic mode: the commands of the last step (sideways is 0).
        """
        if self.mode == "kinematic":
            return self.applied[:, 0].copy(), np.zeros(self.n), self.applied[:, 1].copy()
        c = self._client
        vel = np.array(
            [sum(pb.getBaseVelocity(b, physicsClientId=c), ()) for b in self.bodies]
        ).reshape(self.n, 6)
        _, quats = self._base_states()
        yaw = yaw_from_quaternion(quats)
        cs, sn = np.cos(yaw), np.sin(yaw)
        turn = vel[:, 5]
        forward = vel[:, 0] * cs + vel[:, 1] * sn
        # The body centre is axle_offset ahead: remove its share of the rotation.
        sideways = -vel[:, 0] * sn + vel[:, 1] * cs - turn * self.geometry.axle_offset
        return forward, sideways, turn

    def _sync_bodies(self) -> None:
        """Kinematic mode: move pybullet's bodies to the current state if it changed."""
        if self._bodies_stale:
            self._bodies_stale = False
            self._place(self._positions, self._headings)

    def _base_states(self) -> tuple[np.ndarray, np.ndarray]:
        if self.mode == "kinematic":
            self._sync_bodies()
        c = self._client
        states = [pb.getBasePositionAndOrientation(b, physicsClientId=c) for b in self.bodies]
        centres = np.array([s[0] for s in states]).reshape(self.n, 3)
        quats = np.array([s[1] for s in states]).reshape(self.n, 4)
        return centres, quats

    def reset(
        self, positions: np.ndarray | None = None, headings: np.ndarray | None = None
    ) -> None:
        """Put every robot back at the initial poses (or the given ones), at rest.

        Commands are cleared (every robot stops until it sends a new one). The
        sim time keeps running, so clocks downstream never jump back.
        """
        pos = self.initial[0] if positions is None else np.asarray(positions, float)
        head = self.initial[1] if headings is None else np.asarray(headings, float)
        self._positions, self._headings = pos.reshape(self.n, 2).copy(), head.reshape(-1).copy()
        self.commands[:] = 0.0
        self.command_step[:] = np.iinfo(np.int64).min // 2
        self.applied[:] = 0.0
        self._place(self._positions, self._headings)
        self._bodies_stale = False

    def restore(self, positions: np.ndarray, headings: np.ndarray, step_count: int) -> None:
        """Continue from a saved state: the robots at these poses, at rest, and the sim
        time at ``step_count`` control periods (a restarted bridge resuming a run)."""
        self.reset(positions, headings)
        self.step_count = int(step_count)

    def stop(self, i: int) -> None:
        """Forget robot ``i``'s command: it stands still until it sends a new one."""
        self.command_step[i] = np.iinfo(np.int64).min // 2

    def close(self) -> None:
        """Disconnect from pybullet (idempotent)."""
        if self._client is not None and pb.isConnected(self._client):
            pb.disconnect(self._client)
        self._client = None

    def __enter__(self) -> World:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
