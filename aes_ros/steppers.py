"""How the offline simulator advances a batch of runs: its two backends.

:class:`NumbaStepper` calls the fused kernel (:func:`aes_ros.kernel.advance`), runs spread
over the cores; :class:`NumpyStepper` is the plain reference path built from
:mod:`aes_ros.model`, :mod:`aes_ros.metrics`, :mod:`aes_ros.contacts` and :mod:`aes_ros.ir`,
which the tests compare the kernel with, bit for bit. Both take the noise of
:class:`NoiseChunks` (each run's own generator, :data:`CHUNK` steps at a time) and the camera
draws of :class:`Camera`; :func:`aes_ros.simulator.simulate` drives them.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict

import numpy as np

from aes_ros import metrics
from aes_ros.avoidance import AVOIDANCE_RANGE, N_IR, avoidance_force, ir_period_steps
from aes_ros.contacts import ITERATIONS, resolve_contacts
from aes_ros.ir_readings import ir_ranges
from aes_ros.kernel import PARAM_ORDER, advance
from aes_ros.model import (
    Gains,
    Noise,
    SwarmCommand,
    clip_commands,
    draw_noise,
    motion_commands,
    noise_dt,
    total_forces,
    unicycle_step,
)
from aes_ros.mona.geometry import MonaGeometry
from aes_ros.obstacles import contact_arrays
from aes_ros.perception import (
    PerceptionSettings,
    camera_period_steps,
    delay_steps,
    draw_camera,
    missed_robots,
    perceived_frame,
    perception_state,
    refresh_steps,
    ring_slots,
)
from aes_ros.scenario import Scenario
from aes_ros.springs import spring_list

#: Noise is drawn per run in chunks of this many steps (part of what a seed means).
CHUNK = 32

#: The bodies of :mod:`aes_ros.contacts`: Mona's body radius and axle offset [m].
BODY = MonaGeometry()

_POOL = ThreadPoolExecutor(max_workers=2)


class Camera:
    """The camera of a batch of runs (:mod:`aes_ros.perception`): its settings and
    each run's generators, ``states`` (B, 2, 4) uint64, which the numba kernel
    draws from at each update. For the numpy path, :meth:`draw` keeps the draws
    of a chunk's updates, noise (B, R, N, 2) and uniforms (B, R, N). The steppers
    keep the perceived frame and the delay ring.
    """

    def __init__(
        self, settings: PerceptionSettings, dt: float, n_robots: int, seeds: list[int]
    ) -> None:
        self.settings, self.n_robots = settings, n_robots
        self.period = camera_period_steps(settings.rate, dt)
        self.delay = delay_steps(settings.delay, dt)
        self.states = np.stack([perception_state(s) for s in seeds])

    def draw(self, first_step: int, n: int) -> None:
        """Every run's draws of the updates among steps ``first_step`` … + n - 1."""
        R = len(refresh_steps(first_step, n, self.period))
        draws = [draw_camera(state, self.settings, R, self.n_robots) for state in self.states]
        self.noise = np.stack([noise for noise, _ in draws])
        self.uniforms = np.stack([uniforms for _, uniforms in draws])


class NoiseChunks:
    """Noise of every run, CHUNK steps at a time, into reused (B, CHUNK, N) buffers.

    Drawn on two threads (numpy releases the GIL while filling); each run's
    stream depends only on its own generator, so batching never changes a run.
    """

    def __init__(self, rngs: list[np.random.Generator], n_robots: int, noise: bool) -> None:
        shape = (len(rngs), CHUNK, n_robots)
        self.rngs, self.noise = rngs, noise
        self.buffers = (np.zeros(shape), np.zeros(shape), np.zeros(shape))

    def next(self, start: int, n: int) -> Noise:
        """(xi_x, xi_y, xi_theta), each (B, CHUNK, N), for the CHUNK steps from ``start``."""
        if self.noise:
            half = len(self.rngs) // 2
            if half < 8:
                self._fill(0, len(self.rngs))
            else:
                list(_POOL.map(lambda a: self._fill(*a), [(0, half), (half, len(self.rngs))]))
        return self.buffers

    def _fill(self, lo: int, hi: int) -> None:
        for b in range(lo, hi):
            draw_noise(
                self.rngs[b],
                (CHUNK, self.buffers[0].shape[2]),
                out=tuple(buf[b] for buf in self.buffers),
            )


def final_metrics(
    positions: np.ndarray,
    headings: np.ndarray,
    neighbors: np.ndarray,
    rest: np.ndarray,
    gains: Gains,
    command: SwarmCommand,
) -> np.ndarray:
    forces = total_forces(positions, neighbors, rest, gains, command)
    return np.concatenate(
        [
            np.stack(
                [
                    metrics.alignment_order(forces, headings),
                    metrics.heading_order(headings),
                    metrics.total_force(forces),
                ],
                axis=-1,
            ),
            positions.mean(axis=-2),
        ],
        axis=-1,
    )


class NumpyStepper:
    """Reference path: the model's functions, vectorised over (B, N)."""

    def __init__(
        self,
        scenario: Scenario,
        gains: Gains,
        neighbors: np.ndarray,
        rest: np.ndarray,
        noise: bool,
        record: bool,
    ) -> None:
        self.scenario, self.gains = scenario, gains
        self.neighbors, self.rest = neighbors, rest
        self.noise, self.record = noise, record
        self.bodies = contact_arrays(scenario.values)
        self.ir_period = ir_period_steps(scenario.ir_rate, scenario.dt)

    def advance(
        self,
        pos: np.ndarray,
        head: np.ndarray,
        xi_x: np.ndarray,
        xi_y: np.ndarray,
        xi_theta: np.ndarray,
        n: int,
        stop_at: np.ndarray,
        first_step: int,
        camera: Camera | None = None,
    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray]:
        sc = self.scenario
        seen_pos, seen_head = pos, head
        if camera is not None:
            if first_step == 0:
                self.seen = (pos.copy(), head.copy())
                length = camera.delay + 1
                self.ring = (
                    np.repeat(pos[:, None], length, axis=1),
                    np.repeat(head[:, None], length, axis=1),
                )
            camera.draw(first_step, n)
        refresh = 0
        m = np.empty((len(head), n, 5))
        bodies = np.full((len(head), n, 2), np.nan)
        ph = np.empty((len(head), n, *pos.shape[1:])) if self.record else None
        hh = np.empty((len(head), n, head.shape[1])) if self.record else None
        for s in range(n):
            m[:, s] = final_metrics(pos, head, self.neighbors, self.rest, self.gains, sc.command)
            if self.record:
                ph[:, s], hh[:, s] = pos, head
            if camera is not None:
                step = first_step + s
                seen_pos, seen_head = self._see(camera, pos, head, step, refresh)
                if step % camera.period == 0:
                    refresh += 1
            forces = total_forces(seen_pos, self.neighbors, self.rest, self.gains, sc.command)
            if self.gains.w_o > 0.0:  # avoidance: each robot's own IR sensors, true state
                if (first_step + s) % self.ir_period == 0:
                    self.ranges = self._ranges(pos, head)
                forces = forces + avoidance_force(self.ranges, head, self.gains.w_o)
            noise = (xi_x[:, s], xi_y[:, s], xi_theta[:, s]) if self.noise else None
            u, w = motion_commands(forces, seen_head, self.gains, sc.dt, noise)
            if sc.clip:
                u, w = clip_commands(u, w, sc.max_linear_speed, sc.max_angular_speed)
            moving = first_step + s < stop_at
            u, w = np.where(moving, u, 0.0), np.where(moving, w, 0.0)
            pos[...], head[...] = unicycle_step(pos, head, u, w, sc.dt)
            if sc.contacts:
                for b in range(len(head)):
                    bodies[b, s] = resolve_contacts(
                        pos[b], head[b], BODY.body_radius, BODY.axle_offset, *self.bodies,
                        ITERATIONS,
                    )  # fmt: skip
        return m, ph, hh, bodies

    def _ranges(self, pos: np.ndarray, head: np.ndarray) -> np.ndarray:
        """Every robot's exact IR ranges (B, N, 5) [m] (held until the next reading)."""
        walls, circles, boxes = self.bodies
        return np.stack(
            [ir_ranges(p, h, geometry=BODY, walls=walls, circles=circles, boxes=boxes)
             for p, h in zip(pos, head, strict=True)]
        )  # fmt: skip

    def _see(
        self, camera: Camera, pos: np.ndarray, head: np.ndarray, step: int, refresh: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """The perceived frame at ``step``: the ring takes the true state, a camera
        update (draws ``refresh`` of the chunk) shows the one D steps ago."""
        (ring_pos, ring_head), settings = self.ring, camera.settings
        write, read = ring_slots(step, camera.delay)
        ring_pos[:, write], ring_head[:, write] = pos, head
        if step % camera.period == 0:
            self.seen = perceived_frame(
                ring_pos[:, read],
                ring_head[:, read],
                *self.seen,
                camera.noise[:, refresh],
                missed_robots(camera.uniforms[:, refresh], settings.miss, step),
                settings.sigma,
            )
        return self.seen


class NumbaStepper:
    """Fused kernel path (:func:`aes_ros.kernel.advance`)."""

    def __init__(
        self,
        scenario: Scenario,
        run_gains: list[Gains],
        neighbors: np.ndarray,
        rest: np.ndarray,
        noise: bool,
        record: bool,
    ) -> None:
        cmd = scenario.command
        center = cmd.center if cmd.center is not None else (0.0, 0.0)
        shared = {
            "dt": scenario.dt,
            "dir_x": cmd.direction[0],
            "dir_y": cmd.direction[1],
            "omega": cmd.omega,
            "center_x": center[0],
            "center_y": center[1],
            "use_centroid": float(cmd.center is None),
            "noise": float(noise),
            "clip": float(scenario.clip),
            "max_linear_speed": scenario.max_linear_speed,
            "max_angular_speed": scenario.max_angular_speed,
            "perception_sigma": scenario.perception_sigma,
            "perception_miss": scenario.perception_miss,
            "perception_delay_steps": delay_steps(scenario.perception_delay, scenario.dt),
            "perception_period_steps": camera_period_steps(scenario.perception_rate, scenario.dt),
            "noise_dt": noise_dt(scenario.dt),
            "contacts": float(scenario.contacts),
            "body_radius": BODY.body_radius,
            "axle_offset": BODY.axle_offset,
            "contact_iterations": ITERATIONS,
            "ir_period_steps": ir_period_steps(scenario.ir_rate, scenario.dt),
        }
        rows = ({**shared, **asdict(g)} for g in run_gains)  # asdict deep-copies: once a run
        self.params = np.array([[row[name] for name in PARAM_ORDER] for row in rows], dtype=float)
        self.neighbors = np.ascontiguousarray(neighbors, dtype=np.int64)
        self.rest = np.ascontiguousarray(rest, dtype=float)
        self.springs = spring_list(self.neighbors, self.rest)
        self.record = record
        B = len(run_gains)
        self.seen, self.ring = np.empty((B, 0, 4)), np.empty((B, 0, 0, 4))
        self.camera_state = np.empty((B, 0, 4), np.uint64)
        self.bodies = contact_arrays(scenario.values)
        self.contact_out = np.full((B, CHUNK, 2), np.nan)
        sensing = any(g.w_o > 0.0 for g in run_gains)  # IR ranges held between readings
        self.ranges = np.full((B, len(neighbors) if sensing else 0, N_IR), AVOIDANCE_RANGE)

    def advance(
        self,
        pos: np.ndarray,
        head: np.ndarray,
        xi_x: np.ndarray,
        xi_y: np.ndarray,
        xi_theta: np.ndarray,
        n: int,
        stop_at: np.ndarray,
        first_step: int,
        camera: Camera | None = None,
    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray]:
        B, N = head.shape
        if camera is not None:
            if first_step == 0:  # (x, y, cos θ, sin θ): the initial state everywhere
                state = np.concatenate([pos, np.cos(head)[..., None], np.sin(head)[..., None]], -1)
                self.seen = state.copy()
                self.ring = np.repeat(state[:, None], camera.delay + 1, axis=1)
            self.camera_state = camera.states
        m = np.empty((B, CHUNK, 5))
        ph = np.empty((B, CHUNK, N, 2)) if self.record else np.empty((0, 0, 0, 2))
        hh = np.empty((B, CHUNK, N)) if self.record else np.empty((0, 0, 0))
        advance(
            pos, head, self.neighbors, self.rest, self.params, xi_x, xi_y, xi_theta, n, m, ph, hh,
            np.ascontiguousarray(stop_at), first_step, self.springs, self.seen, self.ring,
            self.camera_state, self.bodies, self.contact_out, self.ranges,
        )  # fmt: skip
        bodies = self.contact_out[:, :n].copy()
        if not self.record:
            return m[:, :n], None, None, bodies
        return m[:, :n], ph[:, :n], hh[:, :n], bodies
