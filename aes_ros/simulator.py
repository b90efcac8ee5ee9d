"""Batched offline simulator of the AES model (docs/design.md#motion): B independent runs at once.

Each run b has its own ``numpy.random.Generator`` (seeded with ``seeds[b]``):
it draws the initial state first (:func:`aes_ros.formations.perturbed_start`),
then the noise in chunks of :data:`CHUNK` steps. A run's numbers therefore do
not depend on which other runs share its batch: a batch of B runs equals B
single runs with the same seeds.

With perception error on (``perception_*`` parameters, :mod:`aes_ros.perception`)
the robots' commands come from a perceived frame; its draws come from a second
pair of generators per run (:func:`aes_ros.perception.perception_state`), so the
first one draws exactly what it drew before perception existed and batching still
changes nothing.

With ``contacts`` on, every Euler step ends with :func:`aes_ros.contacts.resolve_contacts`
(bodies, walls and obstacles) in both backends; off, the robots pass through everything
and the outputs are those of the simulator before contacts existed.

Two backends compute the same thing: ``"numba"`` (default; the fused kernel in
:mod:`aes_ros.kernel`, runs spread over the cores) and ``"numpy"`` (the plain
reference path built from :mod:`aes_ros.model` and :mod:`aes_ros.metrics`).
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass

import numpy as np
from tqdm import tqdm

from aes_ros import formations, metrics
from aes_ros.avoidance import AVOIDANCE_RANGE, N_IR, avoidance_force, ir_period_steps
from aes_ros.contacts import ITERATIONS, contacts_over_time, resolve_contacts
from aes_ros.ir import ir_ranges
from aes_ros.kernel import PARAM_ORDER, advance, spring_list
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

#: Noise is drawn per run in chunks of this many steps (part of what a seed means).
CHUNK = 32

METRIC_NAMES = ("alignment", "heading_order", "total_force", "centroid_x", "centroid_y")

#: The bodies of :mod:`aes_ros.contacts`: Mona's body radius and axle offset [m].
BODY = MonaGeometry()


@dataclass
class SimResult:
    """Output of :func:`simulate`.

    times : (T+1,) [s], the sampled instants 0, Δt, …, T·Δt.
    metrics : (B, T+1, 5) alignment ψ (E8), heading order (E7), total force F (E9),
        centroid x, y [m] at each instant (noise-free force).
    positions : (B, T+1, N, 2) [m] and headings : (B, T+1, N) [rad], or None when
        not recorded.
    neighbors, rest_lengths : the sheet, (N, K).
    final_positions : (B, N, 2) [m] and final_headings : (B, N) [rad], the state at
        T·Δt (kept also when not recorded).
    contacts : (B, T+1) bodies in contact at each instant: with ``contacts`` on, the
        overlaps resolved by the step that led to it; off, the overlaps in the state
        (:func:`aes_ros.contacts.measure_contacts`; at 0 and T only when not recorded,
        NaN elsewhere).
    min_distance : (B, T+1) smallest centre distance between two bodies [m], the
        same way: inf when no two are within 3 body radii, NaN where not known.
    """

    times: np.ndarray
    metrics: np.ndarray
    positions: np.ndarray | None
    headings: np.ndarray | None
    neighbors: np.ndarray
    rest_lengths: np.ndarray
    final_positions: np.ndarray | None = None
    final_headings: np.ndarray | None = None
    contacts: np.ndarray | None = None
    min_distance: np.ndarray | None = None

    def metric(self, name: str) -> np.ndarray:
        """One metric, (B, T+1)."""
        return self.metrics[..., METRIC_NAMES.index(name)]

    @property
    def contacts_per_s(self) -> np.ndarray:
        """Contacts per second of sim time over the run, (B,) [1/s]."""
        duration = self.times[-1]
        return self.contacts[:, 1:].sum(axis=-1) / duration if duration > 0 else self.contacts[:, 0]

    @property
    def centroid(self) -> np.ndarray:
        """Centroid path (B, T+1, 2) [m]."""
        return self.metrics[..., 3:5]


def initial_states(
    nominal: np.ndarray, spacing: float, perturbation: float, rngs: Sequence[np.random.Generator]
) -> tuple[np.ndarray, np.ndarray]:
    """Perturbed starts for every run: positions (B, N, 2), headings (B, N)."""
    starts = [formations.perturbed_start(nominal, spacing, perturbation, r) for r in rngs]
    return np.stack([p for p, _ in starts]), np.stack([h for _, h in starts])


def simulate(
    scenario: Scenario,
    seeds: Sequence[int] | int = 0,
    *,
    noise: bool = True,
    record: bool = True,
    backend: str = "numba",
    progress: bool = False,
    gains: Sequence[Gains] | None = None,
    initial: tuple[np.ndarray, np.ndarray] | None = None,
    stop_at: np.ndarray | None = None,
) -> SimResult:
    """Simulate B runs of a scenario.

    Parameters
    ----------
    scenario : formation, gains, command, Δt and duration.
    seeds : one seed per run (B = len(seeds)), or an int for a single run.
    noise : False switches both noise terms off (the initial state is still drawn);
        perception error (the scenario's ``perception_*``) stays as set.
    record : keep every step's positions and headings (memory B·T·N·3 floats).
    backend : "numba" (fused kernel) or "numpy" (reference path).
    progress : show a tqdm bar over the steps.
    gains : optional per-run gains (len B), e.g. one TCACS candidate per run;
        defaults to the scenario's gains for every run. Runs with equal gains
        share one kernel call (the numpy backend groups runs with equal gains).
    initial : optional (positions (B, N, 2), headings (B, N)) replacing the
        random start (the generators still draw it, so noise streams are unchanged).
    stop_at : optional (B, N) step index from which each robot stops moving (a failed
        robot: u = ω = 0, its springs still act; :func:`failure_steps` makes one);
        default: never.
    """
    seeds = [seeds] if isinstance(seeds, int | np.integer) else list(seeds)
    rngs = [np.random.default_rng(s) for s in seeds]
    nominal, neighbors, rest = scenario.sheet()
    pos, head = initial_states(nominal, scenario.spacing, scenario.perturbation, rngs)
    if initial is not None:
        pos = np.array(initial[0], dtype=float).reshape(pos.shape)
        head = np.array(initial[1], dtype=float).reshape(head.shape)
    B, N = head.shape
    T = scenario.n_steps
    run_gains = list(gains) if gains is not None else [scenario.gains] * B
    if len(run_gains) != B:
        raise ValueError(f"gains: need one per run ({B}), got {len(run_gains)}")
    never = np.iinfo(np.int64).max
    stop_at = np.full((B, N), never, np.int64) if stop_at is None else np.asarray(stop_at)
    if stop_at.shape != (B, N):
        raise ValueError(f"stop_at: need shape {(B, N)}, got {stop_at.shape}")
    stop_at = stop_at.astype(np.int64)

    out_metrics = np.empty((B, T + 1, 5))
    out_bodies = np.full((B, T + 1, 2), np.nan)  # contacts, min centre distance
    pos_hist = np.empty((B, T + 1, N, 2)) if record else None
    head_hist = np.empty((B, T + 1, N)) if record else None
    if backend not in ("numba", "numpy"):
        raise ValueError(f"backend: {backend!r} is not allowed; use 'numba' or 'numpy'")
    # The kernel takes per-run gains, so it runs the whole batch at once; the
    # reference path runs one group of equal gains at a time.
    if backend == "numba":
        batches = [
            (np.arange(B), _NumbaStepper(scenario, run_gains, neighbors, rest, noise, record))
        ]
    else:
        batches = [
            (idx, _NumpyStepper(scenario, g, neighbors, rest, noise, record))
            for idx, g in _group_by_gains(run_gains)
        ]
    perception = PerceptionSettings.from_mapping(scenario.values)
    perceiving = perception.enabled(scenario.dt)
    bar = tqdm(total=T * len(batches), unit="step", disable=not progress, leave=False)
    start_state = (pos.copy(), head.copy())
    for idx, sim in batches:
        p, h = pos[idx], head[idx]
        camera = (
            _Camera(perception, scenario.dt, N, [seeds[i] for i in idx]) if perceiving else None
        )
        chunks = _NoiseChunks([rngs[i] for i in idx], N, noise)
        for start in range(0, T, CHUNK):
            n = min(CHUNK, T - start)
            m, ph, hh, bodies = sim.advance(
                p, h, *chunks.next(start, n), n, stop_at[idx], start, camera
            )
            out_metrics[idx, start : start + n] = m
            out_bodies[idx, start + 1 : start + n + 1] = bodies
            if record:
                pos_hist[idx, start : start + n] = ph
                head_hist[idx, start : start + n] = hh
            bar.update(n)
        pos[idx], head[idx] = p, h
    bar.close()
    for idx, g in _group_by_gains(run_gains):
        out_metrics[idx, T] = _final_metrics(
            pos[idx], head[idx], neighbors, rest, g, scenario.command
        )
    if record:
        pos_hist[:, T], head_hist[:, T] = pos, head
    contacts, closest = _body_metrics(
        scenario, out_bodies, pos_hist, head_hist, (*start_state, pos, head)
    )
    times = np.arange(T + 1) * scenario.dt
    return SimResult(
        times, out_metrics, pos_hist, head_hist, neighbors, rest, pos, head, contacts, closest
    )


def _body_metrics(
    scenario: Scenario,
    bodies: np.ndarray,
    pos_hist: np.ndarray | None,
    head_hist: np.ndarray | None,
    states: tuple[np.ndarray, ...],
) -> tuple[np.ndarray, np.ndarray]:
    """Contacts and smallest centre distance (B, T+1) of a run: from the steps with
    contacts on, else measured in the recorded states (or the first and last)."""
    geometry = contact_arrays(scenario.values)
    measure = BODY.body_radius, BODY.axle_offset, *geometry
    contacts, closest = bodies[..., 0], bodies[..., 1]
    if scenario.contacts:
        contacts[:, 0], closest[:, 0] = contacts_over_time(*states[:2], *measure)
        contacts[:, 0] = 0  # no step led to the first instant
    elif pos_hist is not None:
        contacts[...], closest[...] = contacts_over_time(pos_hist, head_hist, *measure)
    else:
        for t, (p, h) in ((0, states[:2]), (-1, states[2:])):
            contacts[:, t], closest[:, t] = contacts_over_time(p, h, *measure)
    return contacts, closest


def failure_steps(
    n_runs: int, n_robots: int, fraction: float, at: float, dt: float, seed: int = 0
) -> np.ndarray:
    """``stop_at`` for :func:`simulate`: in every run the same ``fraction`` of the robots
    (chosen with ``seed``) stop moving at sim time ``at`` [s]; (n_runs, n_robots)."""
    never = np.iinfo(np.int64).max
    out = np.full((n_runs, n_robots), never, np.int64)
    failed = np.random.default_rng(seed).choice(
        n_robots, size=round(fraction * n_robots), replace=False
    )
    out[:, failed] = round(at / dt)
    return out


def _group_by_gains(run_gains: list[Gains]) -> list[tuple[np.ndarray, Gains]]:
    order: dict[Gains, list[int]] = {}
    for i, g in enumerate(run_gains):
        order.setdefault(g, []).append(i)
    return [(np.array(ix), g) for g, ix in order.items()]


_POOL = ThreadPoolExecutor(max_workers=2)


class _Camera:
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


class _NoiseChunks:
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


def _final_metrics(
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


class _NumpyStepper:
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
        camera: _Camera | None = None,
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
            m[:, s] = _final_metrics(pos, head, self.neighbors, self.rest, self.gains, sc.command)
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
        self, camera: _Camera, pos: np.ndarray, head: np.ndarray, step: int, refresh: int
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


class _NumbaStepper:
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
        camera: _Camera | None = None,
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
