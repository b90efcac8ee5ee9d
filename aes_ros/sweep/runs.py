"""Simulating a sweep's points: tasks of points that share a sheet, one batched run each (pure).

Every point runs the same Monte-Carlo seeds (common random numbers: the same
initial states and noise streams), so that two points differ by their parameters,
not by luck. The gains and noise strengths (α, β, k, v_0, w_l, w_r, D_r, D_θ) are
per-run inputs of the numba kernel: the points of a task differ only in those and
go through one :func:`aes_ros.simulator.simulate` call. Points that change the
sheet or the run itself (N, spacing, Δt, duration, the command, …) are in tasks of
their own. A run's numbers do not depend on its batch, so a point's rows are the
same however the sweep is split, run locally or on a cluster.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from aes_ros import metrics
from aes_ros.model import Gains
from aes_ros.optim.cost import default_weights, run_costs
from aes_ros.params import PARAMS
from aes_ros.scenario import Scenario
from aes_ros.simulator import failure_steps, simulate
from aes_ros.sweep.spec import ROBOTS

#: Per-run columns of the tidy table, after point, run, seed and the swept parameters.
RUN_COLUMNS = ("psi", "psi_heading", "force_per_robot", "strain", "J")
#: Parameters that are per-run inputs of the kernel (points differing in them batch together).
PER_RUN = frozenset(f.name for f in dataclasses.fields(Gains))


def point_scenario(base: Scenario, names: Sequence[str], values: Sequence[float]) -> Scenario:
    """The base scenario with the swept parameters set to ``values``."""
    overrides: dict[str, Any] = {}
    robots = None
    for name, value in zip(names, values, strict=True):
        if name == ROBOTS:
            robots = int(np.rint(value))
        else:
            overrides[name] = value
    sc = base.with_robots(robots) if robots is not None else base
    if overrides:
        cast = {
            n: int(np.rint(v)) if PARAMS[n].kind == "int" else float(v)
            for n, v in overrides.items()
        }
        sc = sc.with_overrides(cast, source="--param")
    return sc


def structure_key(names: Sequence[str], values: Sequence[float]) -> tuple:
    """What a point's run shares with others of its task: every swept value that is
    not a per-run kernel input."""
    return tuple((n, float(v)) for n, v in zip(names, values, strict=True) if n not in PER_RUN)


@dataclass(frozen=True)
class Task:
    """Points ``indices`` (rows of the sweep's point table) simulated in one batch."""

    indices: tuple[int, ...]


def make_tasks(
    names: Sequence[str], points: np.ndarray, skip: set[int], points_per_task: int
) -> list[Task]:
    """The tasks covering every point not in ``skip``: points grouped by
    :func:`structure_key`, at most ``points_per_task`` in a task, in point order."""
    groups: dict[tuple, list[int]] = {}
    for i, values in enumerate(points):
        if i not in skip:
            groups.setdefault(structure_key(names, values), []).append(i)
    tasks = []
    for members in groups.values():
        for start in range(0, len(members), points_per_task):
            tasks.append(Task(tuple(members[start : start + points_per_task])))
    return sorted(tasks, key=lambda t: t.indices[0])


def run_task(
    base: Scenario,
    names: Sequence[str],
    indices: Sequence[int],
    values: np.ndarray,
    seeds: Sequence[int],
    transient: float,
    fail: tuple[float, float] | None = None,
) -> list[dict[str, Any]]:
    """Simulate points ``indices`` (their swept ``values``, one row each) with every
    seed; one row per (point, run). ``fail`` = (fraction, time [s]): that fraction of
    the robots (the same ones in every run, chosen by the first seed) stops moving at
    that time.

    Row: ``point``, ``run``, ``seed``, the swept values, then ψ̄ (E8) and ψ̄_heading
    (E7) averaged over t ≥ ``transient`` [s], F̄/N (E9 per robot, same span), the
    final mean spring strain, and the run's cost J (the summand of E10 with the
    paper's weights 1/N and −1, over the whole run).
    """
    scenarios = [point_scenario(base, names, v) for v in values]
    sc = scenarios[0]
    seeds = [int(s) for s in seeds]
    gains = [s.gains for s in scenarios for _ in seeds]
    n = len(sc.nominal_positions())
    stop_at = None
    if fail is not None:
        stop_at = failure_steps(len(gains), n, fail[0], fail[1], sc.dt, seed=seeds[0])
    with np.errstate(all="ignore"):
        result = simulate(sc, seeds * len(scenarios), gains=gains, record=False, stop_at=stop_at)
        w1, w2 = default_weights(n)
        cost = run_costs(result, w1, w2)
        after = result.times >= transient - 1e-9
        psi = result.metric("alignment")[:, after].mean(axis=1)
        order = result.metric("heading_order")[:, after].mean(axis=1)
        force = result.metric("total_force")[:, after].mean(axis=1) / n
        strain = metrics.spring_strain(
            result.final_positions, result.neighbors, result.rest_lengths
        )
    rows = []
    for k, i in enumerate(indices):
        for r, seed in enumerate(seeds):
            b = k * len(seeds) + r
            row: dict[str, Any] = {"point": int(i), "run": r, "seed": seed}
            row.update({name: float(v) for name, v in zip(names, values[k], strict=True)})
            measured = (psi[b], order[b], force[b], strain[b], cost[b])
            row.update({c: float(v) for c, v in zip(RUN_COLUMNS, measured, strict=True)})
            rows.append(row)
    return rows
