"""One tuning run: TCACS on the Monte-Carlo cost J (docs/design.md#tuning; Raoufi et al. 2019).

:func:`tune` runs TCACS (:mod:`aes_ros.optim.tcacs`) on J (E10,
:mod:`aes_ros.optim.cost`) and :func:`write_tune_outputs` writes what
``aes-swarm optimize`` promises (result.json, history.csv, convergence.png).

Default search box (:data:`DEFAULT_BOUNDS`): α ∈ [0.001, 0.5], β ∈ [0.01, 5],
k ∈ [0.5, 5]. It holds the paper's α* = 0.066, β* = 0.97, k* = 1.28 well inside
on α and β. The lower bound on k is deliberate: J rewards a weak sheet (F
counts the spring forces, and with k → 0 the robots simply follow the drives),
so a box reaching k = 0 returns k ≈ 0, a "swarm" whose formation is gone (in the
study: mean spring strain 108 % at t_f for the wide-box optimum k ≈ 0.003,
against 27 % for the optimum at k = 0.5 and 15 % for the paper's gains). The
study (:mod:`aes_ros.optim.study`) shows this with a run in the wide box
:data:`WIDE_BOUNDS` and with slices of J through the paper's point.
"""

from __future__ import annotations

import csv
import json
import math
import os
import platform
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import OptimizeResult
from tqdm import tqdm

from aes_ros import simulator
from aes_ros.optim import figures, tcacs
from aes_ros.optim.cost import TUNED_GAINS, MonteCarloCost
from aes_ros.params import PARAMS, ParameterError
from aes_ros.scenario import Scenario

Bounds = dict[str, tuple[float, float]]

#: Default search box of ``aes-swarm optimize`` (see the module docstring for why k >= 0.5).
DEFAULT_BOUNDS: Bounds = {"alpha": (0.001, 0.5), "beta": (0.01, 5.0), "k": (0.5, 5.0)}
#: The same box with k free down to 0, to show where J leads without the k bound.
WIDE_BOUNDS: Bounds = {"alpha": (0.0, 0.5), "beta": (0.0, 5.0), "k": (0.0, 5.0)}
#: The paper's TCACS result (docs/design.md#tcacs-options, Table 1); every result.json quotes
#: it, the study compares.
PAPER_GAINS = {"alpha": 0.066, "beta": 0.97, "k": 1.28}


def mc_seeds(seed: int, n_mc: int) -> list[int]:
    """The common random numbers of a tuning run: Monte-Carlo run r uses seed + r."""
    return [seed + r for r in range(n_mc)]


def parse_bounds(text: str, base: Mapping[str, tuple[float, float]] = DEFAULT_BOUNDS) -> Bounds:
    """Parse ``alpha=LO:HI,beta=LO:HI,k=LO:HI`` (any subset; the rest from ``base``).

    Raises ParameterError naming the field: unknown gain, malformed pair,
    reversed or empty interval, or a value outside the parameter's range.
    """
    bounds = dict(base)
    for item in [s for s in text.split(",") if s.strip()]:
        name, sep, interval = item.partition("=")
        name = name.strip()
        if not sep or name not in TUNED_GAINS:
            raise ParameterError(
                f"--bounds: {item.strip()!r} is not NAME=LO:HI with NAME one of "
                f"{', '.join(TUNED_GAINS)}"
            )
        lo_text, sep, hi_text = interval.partition(":")
        try:
            lo, hi = float(lo_text), float(hi_text)
        except ValueError:
            lo = hi = math.nan
        if not sep or not (math.isfinite(lo) and math.isfinite(hi)):
            raise ParameterError(f"--bounds: {name}: {interval!r} is not LO:HI with two numbers")
        if lo >= hi:
            raise ParameterError(
                f"--bounds: {name}: low {lo:g} >= high {hi:g} (reversed or empty interval)"
            )
        spec = PARAMS[name]
        if lo < spec.low or hi > spec.high:
            raise ParameterError(f"--bounds: {name}: [{lo:g}, {hi:g}] leaves {spec.allowed()}")
        bounds[name] = (lo, hi)
    return bounds


def warm_up(scenario: Scenario) -> float:
    """Load (or compile) the numba kernel with a tiny run; returns the time it took [s]."""
    start = time.perf_counter()
    simulator.simulate(scenario.with_overrides({"duration": 2 * scenario.dt}), [0], record=False)
    return time.perf_counter() - start


@dataclass
class TuneOutcome:
    """A finished tuning run: the TCACS result, its cost object and timings."""

    result: OptimizeResult
    cost: MonteCarloCost
    bounds: Bounds
    settings: dict[str, Any]
    wall_time_s: float  #: optimisation only (all simulations), numba warm-up excluded
    cpu_time_s: float  #: CPU time of this process (all threads) over the same span
    warmup_s: float = 0.0  #: loading/compiling the numba kernel before the timer started
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def best(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.bounds, self.result.x, strict=True)}


def tune(
    scenario: Scenario,
    *,
    bounds: Mapping[str, tuple[float, float]] = DEFAULT_BOUNDS,
    evals: int = tcacs.DEFAULT_MAX_EVALS,
    mc: int = 10,
    w1: float | None = None,
    w2: float = -1.0,
    seed: int = 0,
    mc_seed: int | None = None,
    n_ants: int = tcacs.PAPER_OPTIONS["n_ants"],
    weighting: str = tcacs.PAPER_OPTIONS["weighting"],
    gamma: float = tcacs.PAPER_OPTIONS["gamma"],
    m: float = tcacs.PAPER_OPTIONS["m"],
    tol: float = tcacs.DEFAULT_TOL,
    progress: bool = False,
) -> TuneOutcome:
    """Tune the gains named in ``bounds`` with TCACS on J (E10); the paper's options by default.

    The other gains stay at the scenario's values. ``seed`` seeds TCACS; Monte-Carlo
    run r uses seed ``mc_seed`` + r (:func:`mc_seeds`; ``mc_seed`` defaults to
    ``seed``). The numba kernel is warmed up before the timer starts. With
    ``progress`` a tqdm bar shows the evaluations and the best-so-far J.
    """
    names = tuple(bounds)
    first = seed if mc_seed is None else mc_seed
    cost = MonteCarloCost(scenario, w1=w1, w2=w2, seeds=mc_seeds(first, mc), names=names)
    warmup = warm_up(scenario)
    bar = tqdm(
        total=tcacs.n_iterations(evals, n_ants) * n_ants,
        unit="eval",
        desc="TCACS",
        disable=not progress,
        leave=False,
    )

    def callback(res: OptimizeResult) -> None:
        bar.update(res.nfev - bar.n)
        bar.set_postfix_str(f"best J={res.fun:.4g}")

    start, cpu_start = time.perf_counter(), time.process_time()
    try:
        result = tcacs.minimize(
            cost,
            [bounds[n] for n in names],
            n_ants=n_ants,
            weighting=weighting,
            gamma=gamma,
            m=m,
            max_evals=evals,
            tol=tol,
            seed=seed,
            callback=callback,
        )
    finally:
        bar.close()
    wall = time.perf_counter() - start
    cpu = time.process_time() - cpu_start
    settings = {
        "evals": evals,
        "mc": mc,
        "mc_seeds": cost.seeds,
        "w1": cost.w1,
        "w2": cost.w2,
        "bounds": {n: list(bounds[n]) for n in names},
        "seed": seed,
        "n_ants": n_ants,
        "weighting": weighting,
        "gamma": gamma,
        "m": m,
        "tol": tol,
        "num_robots": cost.n_robots,
        "dt": scenario.dt,
        "duration": scenario.duration,
    }
    return TuneOutcome(result, cost, dict(bounds), settings, wall, cpu, warmup)


def write_tune_outputs(out: Path, outcome: TuneOutcome, scenario: Scenario, label: str) -> None:
    """result.json, history.csv and convergence.png of one tuning run into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    res = outcome.result
    n_cpu = os.cpu_count()
    record = {
        "best": outcome.best,
        "best_J": _json_number(res.fun),
        "evaluations": int(res.nfev),
        "iterations": int(res.nit),
        "message": res.message,
        "nonfinite_candidates": outcome.cost.n_nonfinite,
        "wall_time_s": round(outcome.wall_time_s, 3),
        "wall_time_note": "TCACS and every simulation; excludes the numba warm-up "
        "(loading the cached kernel, or compiling it on a first run), see warmup_s",
        "cpu_time_s": round(outcome.cpu_time_s, 3),
        "warmup_s": round(outcome.warmup_s, 3),
        "paper_gains": PAPER_GAINS,
        "settings": {"setup": label, **outcome.settings},
        "scenario": scenario_record(scenario),
        "machine": {
            "cpus": n_cpu,
            "load_average_1min_at_end": round(os.getloadavg()[0], 2),
            "note": "wall_time_s grows with other load on a shared machine; cpu_time_s "
            "(all threads of this process) does not",
            "python": platform.python_version(),
        },
        **outcome.extra,
    }
    (out / "result.json").write_text(json.dumps(record, indent=2) + "\n")
    names = list(outcome.bounds)
    best_so_far = np.minimum.accumulate(res.history_fun)
    with open(out / "history.csv", "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["eval", "iteration", *names, "J", "best_J"])
        for i, (x, j, it, b) in enumerate(
            zip(res.history_x, res.history_fun, res.history_nit, best_so_far, strict=True)
        ):
            writer.writerow([i + 1, int(it), *(f"{v:.6g}" for v in x), f"{j:.6g}", f"{b:.6g}"])
    figures.tuning_convergence(
        out / "convergence.png",
        res.history_fun,
        title=f"TCACS on J (E10), {label}: best J = {res.fun:.4g}",
    )


def summary_line(outcome: TuneOutcome, out: Path | None = None) -> str:
    """One line: best gains, best J, evaluations and time."""
    gains = ", ".join(f"{n}={v:.4g}" for n, v in outcome.best.items())
    where = f"; outputs in {out}" if out is not None else ""
    bad = outcome.cost.n_nonfinite
    blown = f", {bad} candidates blew up (J=+inf)" if bad else ""
    return (
        f"best J = {outcome.result.fun:.5g} at {gains} after {outcome.result.nfev} evaluations "
        f"({outcome.cost.n_mc} MC runs each{blown}) in {outcome.wall_time_s:.1f} s{where}"
    )


def scenario_record(scenario: Scenario) -> dict[str, Any]:
    """The scenario's values as JSON-ready data (tuples become lists)."""
    return {k: list(v) if isinstance(v, tuple) else v for k, v in scenario.values.items()}


def _json_number(value: float) -> float | str:
    return float(value) if math.isfinite(value) else str(value)
