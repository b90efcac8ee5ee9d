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

Two backends compute the same thing (:mod:`aes_ros.steppers`): ``"numba"`` (default;
the fused kernel in :mod:`aes_ros.kernel`, runs spread over the cores) and ``"numpy"``
(the plain reference path built from :mod:`aes_ros.model` and :mod:`aes_ros.metrics`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from aes_ros import formations
from aes_ros.contact_measures import contacts_over_time
from aes_ros.model import Gains
from aes_ros.obstacles import contact_arrays
from aes_ros.perception import PerceptionSettings
from aes_ros.scenario import Scenario
from aes_ros.steppers import (
    BODY,
    CHUNK,
    Camera,
    NoiseChunks,
    NumbaStepper,
    NumpyStepper,
    final_metrics,
)

METRIC_NAMES = ("alignment", "heading_order", "total_force", "centroid_x", "centroid_y")


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
        (:func:`aes_ros.contact_measures.measure_contacts`; at 0 and T only when not recorded,
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
            (np.arange(B), NumbaStepper(scenario, run_gains, neighbors, rest, noise, record))
        ]
    else:
        batches = [
            (idx, NumpyStepper(scenario, g, neighbors, rest, noise, record))
            for idx, g in _group_by_gains(run_gains)
        ]
    perception = PerceptionSettings.from_mapping(scenario.values)
    perceiving = perception.enabled(scenario.dt)
    bar = tqdm(total=T * len(batches), unit="step", disable=not progress, leave=False)
    start_state = (pos.copy(), head.copy())
    for idx, sim in batches:
        p, h = pos[idx], head[idx]
        camera = Camera(perception, scenario.dt, N, [seeds[i] for i in idx]) if perceiving else None
        chunks = NoiseChunks([rngs[i] for i in idx], N, noise)
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
        out_metrics[idx, T] = final_metrics(
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
