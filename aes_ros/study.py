"""Tuning the gains with TCACS, and the paper's tuning study (SPEC §3; Raoufi et al. 2019).

:func:`tune` runs TCACS (:mod:`aes_ros.optim.tcacs`) on the Monte-Carlo cost J (E10,
:mod:`aes_ros.optim.cost`) and :func:`write_tune_outputs` writes what
``aes-swarm optimize`` promises (result.json, history.csv, convergence.png).

:func:`run_study` is the paper's study in one call (``aes-swarm study``):
untuned gains, the paper's tuned gains and TCACS-tuned gains for the paper's
weights (w_1, w_2) = (1/N, −1) and the two variants (10/N, −1) and (1/N, −10),
each restarted with independent seeds; then every gain set is re-simulated on
held-out seeds for ψ(t) and F(t) figures and a table of J (mean ± sd).

Default search box (:data:`DEFAULT_BOUNDS`): α ∈ [0.001, 0.5], β ∈ [0.01, 5],
k ∈ [0.5, 5]. It holds the paper's α* = 0.066, β* = 0.97, k* = 1.28 well inside
on α and β. The lower bound on k is deliberate: J rewards a weak sheet (F
counts the spring forces, and with k → 0 the robots simply follow the drives),
so a box reaching k = 0 returns k ≈ 0, a "swarm" whose formation is gone (in the
study: mean spring strain 108 % at t_f for the wide-box optimum k ≈ 0.003,
against 27 % for the optimum at k = 0.5 and 15 % for the paper's gains). The
study shows this with a run in the wide box :data:`WIDE_BOUNDS` and with
slices of J through the paper's point.
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

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from scipy.optimize import OptimizeResult
from tqdm import tqdm

from aes_ros import simulator
from aes_ros.metrics import spring_strain
from aes_ros.optim import tcacs
from aes_ros.optim.cost import TUNED_GAINS, MonteCarloCost, run_costs
from aes_ros.params import PARAMS, ParameterError
from aes_ros.scenario import Scenario

Bounds = dict[str, tuple[float, float]]

#: Default search box of ``aes-swarm optimize`` (see the module docstring for why k >= 0.5).
DEFAULT_BOUNDS: Bounds = {"alpha": (0.001, 0.5), "beta": (0.01, 5.0), "k": (0.5, 5.0)}
#: The same box with k free down to 0, to show where J leads without the k bound.
WIDE_BOUNDS: Bounds = {"alpha": (0.0, 0.5), "beta": (0.0, 5.0), "k": (0.0, 5.0)}
#: The paper's TCACS result (SPEC §3.2, Table 1).
PAPER_GAINS = {"alpha": 0.066, "beta": 0.97, "k": 1.28}
#: "Default" (untuned) gains of the study: every gain 1 (see :func:`run_study`).
UNTUNED_GAINS = {"alpha": 1.0, "beta": 1.0, "k": 1.0}
#: The paper's weight settings (w_1 in units of 1/N, w_2), SPEC §3.1.
WEIGHTS = {"paper": (1.0, -1.0), "force×10": (10.0, -1.0), "alignment×10": (1.0, -10.0)}


def mc_seeds(seed: int, n_mc: int) -> list[int]:
    """The common random numbers of a tuning run with ``seed``: seeds seed·n_mc … seed·n_mc+n_mc−1.

    Different ``seed`` s give disjoint seed sets (independent repetitions).
    """
    return [seed * n_mc + i for i in range(n_mc)]


#: Seeds of the held-out evaluation runs (disjoint from any tuning run's seeds).
HELD_OUT_SEED0 = 1_000_000


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
    evals: int = 300,
    mc: int = 10,
    w1: float | None = None,
    w2: float = -1.0,
    seed: int = 0,
    n_ants: int = 15,
    weighting: str = "roulette",
    gamma: float = 0.5,
    m: float = 2,
    tol: float = 1e-4,
    progress: bool = False,
) -> TuneOutcome:
    """Tune the gains named in ``bounds`` with TCACS on J (E10); the paper's options by default.

    The other gains stay at the scenario's values. ``seed`` seeds TCACS and
    picks the Monte-Carlo seeds (:func:`mc_seeds`). The numba kernel is warmed
    up before the timer starts. With ``progress`` a tqdm bar shows the
    evaluations and the best-so-far J.
    """
    names = tuple(bounds)
    cost = MonteCarloCost(scenario, w1=w1, w2=w2, seeds=mc_seeds(seed, mc), names=names)
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
        "scenario": {k: _jsonable(v) for k, v in scenario.values.items()},
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
    fig, ax = plt.subplots(figsize=(7, 4))
    _convergence_axes(ax, res.history_fun, label="best so far")
    ax.set_title(f"TCACS on J (E10), {label}: best J = {res.fun:.4g}")
    fig.tight_layout()
    fig.savefig(out / "convergence.png", dpi=110)
    plt.close(fig)


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


def _convergence_axes(ax, history_fun: np.ndarray, label: str, color=None, scatter=True) -> None:
    evals = np.arange(1, len(history_fun) + 1)
    best = np.minimum.accumulate(history_fun)
    finite = np.isfinite(history_fun)
    if scatter and finite.any():
        ax.scatter(evals[finite], history_fun[finite], s=6, alpha=0.35, color="0.5", label="J")
        hi = np.percentile(history_fun[finite], 90)
        lo = best[np.isfinite(best)].min()
        ax.set_ylim(lo - 0.05 * (hi - lo + 1e-9), hi + 0.05 * (hi - lo + 1e-9))
    ax.plot(evals, best, color=color, label=label, lw=1.8)
    ax.set_xlabel("evaluations")
    ax.set_ylabel("J (E10)")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right")


def _jsonable(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value


def _json_number(value: float) -> float | str:
    return float(value) if math.isfinite(value) else str(value)


# --- the study -------------------------------------------------------------------------


@dataclass
class GainSet:
    """A row of the study: a label, the gains and where they came from."""

    label: str
    gains: dict[str, float]
    source: str


def evaluate(scenario: Scenario, gain_sets: list[GainSet], seeds: list[int]) -> dict[str, Any]:
    """Simulate every gain set on the same held-out ``seeds`` (one batch).

    Returns per gain set: ψ(t) and F(t) (runs × T+1) and the per-run sums Σψ and ΣF.
    """
    cost = MonteCarloCost(scenario, seeds=seeds, names=TUNED_GAINS)
    per_set = [cost.gains([g.gains[n] for n in TUNED_GAINS]) for g in gain_sets]
    few = seeds[:STRAIN_RUNS]  # cohesion at t_f from a few runs (recording all needs GBs)
    with np.errstate(all="ignore"):
        res = simulator.simulate(
            scenario, seeds * len(gain_sets), gains=[g for g in per_set for _ in seeds],
            record=False,
        )  # fmt: skip
        rec = simulator.simulate(
            scenario, few * len(gain_sets), gains=[g for g in per_set for _ in few], record=True
        )
    shape = (len(gain_sets), len(seeds), -1)
    strain = spring_strain(rec.positions[:, -1], rec.neighbors, rec.rest_lengths)
    return {
        "times": res.times,
        "psi": res.metric("alignment").reshape(shape),
        "force": res.metric("total_force").reshape(shape),
        "sum_psi": run_costs(res, 0.0, 1.0).reshape(shape[:2]),
        "sum_force": run_costs(res, 1.0, 0.0).reshape(shape[:2]),
        "strain": strain.reshape(len(gain_sets), len(few)),
    }


#: Held-out runs per gain set whose final formation is recorded for the strain column.
STRAIN_RUNS = 10


def run_study(
    out: Path,
    scenario: Scenario,
    *,
    evals: int = 300,
    mc: int = 10,
    restarts: int = 3,
    eval_runs: int = 50,
    progress: bool = False,
) -> dict[str, Any]:
    """The paper's tuning study; writes figures, tables and study.json into ``out``.

    Gain sets compared (all on the same held-out seeds, disjoint from tuning):

    * untuned: α = β = k = 1. The paper does not print the gains it started
      from; every gain at 1 is what one runs before any tuning (and what the
      paper's "before optimisation" stands for here). It is stable but poor.
    * paper: α = 0.066, β = 0.97, k = 1.28 (the paper's TCACS result).
    * TCACS with the paper's weights (1/N, −1) in :data:`DEFAULT_BOUNDS`, and
      with the variants (10/N, −1) and (1/N, −10); plus (1/N, −1) in
      :data:`WIDE_BOUNDS` (k down to 0) to show where J leads without the k bound.

    Each TCACS setting runs ``restarts`` times with seeds 0, 1, … (independent
    TCACS draws and Monte-Carlo seed sets); restart 0 (fixed in advance, no
    selection) gives the gains of the figures and the J table, all restarts
    are listed in runs.csv. J is reported under all three weightings as mean ±
    standard deviation over the ``eval_runs`` held-out runs of the per-run
    cost Σ_t [w_1 F + w_2 ψ].
    """
    out.mkdir(parents=True, exist_ok=True)
    n_robots = len(scenario.nominal_positions())
    settings = [
        ("TCACS, weights (1/N, −1)", "paper", DEFAULT_BOUNDS),
        ("TCACS, weights (10/N, −1)", "force×10", DEFAULT_BOUNDS),
        ("TCACS, weights (1/N, −10)", "alignment×10", DEFAULT_BOUNDS),
        ("TCACS, (1/N, −1), k from 0", "paper", WIDE_BOUNDS),
    ]
    started = time.perf_counter()
    runs: list[dict[str, Any]] = []
    histories: dict[str, list[np.ndarray]] = {}
    tuned: list[GainSet] = []
    for label, weights, bounds in settings:
        w1n, w2 = WEIGHTS[weights]
        for restart in range(restarts):
            outcome = tune(
                scenario, bounds=bounds, evals=evals, mc=mc, w1=w1n / n_robots, w2=w2,
                seed=restart,
            )  # fmt: skip
            runs.append(
                {
                    "setting": label,
                    "restart": restart,
                    **{n: outcome.best[n] for n in TUNED_GAINS},
                    "J_tuning": float(outcome.result.fun),
                    "evaluations": int(outcome.result.nfev),
                    "wall_time_s": round(outcome.wall_time_s, 2),
                    "nonfinite": outcome.cost.n_nonfinite,
                }
            )
            histories.setdefault(label, []).append(outcome.result.history_fun)
            if restart == 0:
                tuned.append(GainSet(label, outcome.best, f"restart 0, {weights} weights"))
            if progress:
                print(f"  {label}, restart {restart}: {summary_line(outcome)}", flush=True)
    tuning_s = time.perf_counter() - started

    gain_sets = [
        GainSet("untuned (α=β=k=1)", UNTUNED_GAINS, "every gain 1"),
        GainSet("paper (0.066, 0.97, 1.28)", PAPER_GAINS, "Raoufi et al. 2019, TCACS"),
        *tuned,
    ]
    seeds = [HELD_OUT_SEED0 + i for i in range(eval_runs)]
    ev = evaluate(scenario, gain_sets, seeds)
    slices = _slices(scenario, mc)
    rows = _table_rows(gain_sets, ev, n_robots, len(ev["times"]))

    _plot_psi_force(out / "effect_of_optimisation.png", scenario, gain_sets, ev, eval_runs)
    _plot_convergence(out / "convergence.png", histories)
    _plot_slices(out / "j_slices.png", slices)
    _write_csv(out / "table.csv", rows)
    _write_csv(out / "runs.csv", runs)
    study = {
        "scenario": {k: _jsonable(v) for k, v in scenario.values.items()},
        "evals": evals,
        "mc": mc,
        "restarts": restarts,
        "eval_runs": eval_runs,
        "held_out_seeds": [seeds[0], seeds[-1]],
        "strain_runs": min(STRAIN_RUNS, eval_runs),
        "default_bounds": DEFAULT_BOUNDS,
        "wide_bounds": WIDE_BOUNDS,
        "table": rows,
        "runs": runs,
        "slices": {k: {"x": v[0].tolist(), "J": v[1].tolist()} for k, v in slices.items()},
        "tuning_time_s": round(tuning_s, 1),
        "total_time_s": round(time.perf_counter() - started, 1),
    }
    (out / "study.json").write_text(json.dumps(study, indent=2, ensure_ascii=False) + "\n")
    (out / "study.md").write_text(study_markdown(study))
    return study


def _table_rows(
    gain_sets: list[GainSet], ev: dict[str, Any], n_robots: int, n_samples: int
) -> list[dict[str, Any]]:
    rows = []
    for i, g in enumerate(gain_sets):
        row: dict[str, Any] = {"gains": g.label, **{n: g.gains[n] for n in TUNED_GAINS}}
        for wname, (w1n, w2) in WEIGHTS.items():
            J = w1n / n_robots * ev["sum_force"][i] + w2 * ev["sum_psi"][i]
            row[f"J_{wname}_mean"] = float(np.mean(J))
            row[f"J_{wname}_sd"] = float(np.std(J, ddof=1)) if len(J) > 1 else 0.0
        row["psi_mean"] = float(np.mean(ev["sum_psi"][i]) / n_samples)
        row["strain_end"] = float(np.mean(ev["strain"][i]))
        row["F_per_robot_mean"] = float(np.mean(ev["sum_force"][i]) / n_samples / n_robots)
        row["source"] = g.source
        rows.append(row)
    return rows


def study_markdown(study: dict[str, Any]) -> str:
    """The study's tables as markdown (generated; the README quotes them)."""
    lines = [
        f"J on {study['eval_runs']} held-out runs (seeds {study['held_out_seeds'][0]}…"
        f"{study['held_out_seeds'][1]}), mean ± sd of the per-run cost Σ_t[w_1 F + w_2 ψ]; "
        "lower is better. ψ̄ and F̄/N are time averages; strain is the mean relative spring "
        f"deformation |‖r_ij‖ − l_ij|/l_ij at t_f (first {study['strain_runs']} runs; 0 = nominal "
        "sheet).",
        "",
        "| gains | α | β | k | J (1/N, −1) | J (10/N, −1) | J (1/N, −10) | ψ̄ | F̄/N | strain |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in study["table"]:
        js = " | ".join(
            f"{r[f'J_{w}_mean']:.1f} ± {r[f'J_{w}_sd']:.1f}"
            for w in ("paper", "force×10", "alignment×10")
        )
        lines.append(
            f"| {r['gains']} | {r['alpha']:.3g} | {r['beta']:.3g} | {r['k']:.3g} | {js} | "
            f"{r['psi_mean']:.3f} | {r['F_per_robot_mean']:.3f} | {r['strain_end']:.0%} |"
        )
    lines += [
        "",
        f"Every TCACS run ({study['evals']} evaluations × {study['mc']} Monte-Carlo runs; "
        "J_tuning is on that run's own seeds):",
        "",
        "| setting | restart | α | β | k | J_tuning | evaluations | wall time [s] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in study["runs"]:
        lines.append(
            f"| {r['setting']} | {r['restart']} | {r['alpha']:.4g} | {r['beta']:.4g} | "
            f"{r['k']:.4g} | {r['J_tuning']:.2f} | {r['evaluations']} | {r['wall_time_s']:.1f} |"
        )
    return "\n".join(lines) + "\n"


def _slices(scenario: Scenario, mc: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """J (paper weights, seeds of restart 0) along each gain through the paper's point."""
    grids = {
        "alpha": np.geomspace(0.005, 0.5, 11),
        "beta": np.geomspace(0.05, 5.0, 11),
        "k": np.concatenate([[0.0], np.geomspace(0.05, 5.0, 11)]),
    }
    cost = MonteCarloCost(scenario, seeds=mc_seeds(0, mc))
    X, where = [], []
    for name, grid in grids.items():
        for v in grid:
            X.append([v if n == name else PAPER_GAINS[n] for n in TUNED_GAINS])
            where.append(name)
    J = cost(np.array(X))
    where_arr = np.array(where)
    return {name: (grid, J[where_arr == name]) for name, grid in grids.items()}


def _plot_psi_force(
    path: Path, scenario: Scenario, gain_sets: list[GainSet], ev: dict[str, Any], runs: int
) -> None:
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    t = ev["times"]
    for i, g in enumerate(gain_sets):
        style = {"lw": 1.6, "ls": "--" if i < 2 else "-"}
        for ax, key in ((top, "psi"), (bottom, "force")):
            mean, sd = ev[key][i].mean(axis=0), ev[key][i].std(axis=0)
            (line,) = ax.plot(t, mean, label=f"{g.label}", **style)
            ax.fill_between(t, mean - sd, mean + sd, color=line.get_color(), alpha=0.12)
    top.set_ylabel("force alignment ψ (E8)")
    top.set_ylim(0, 1.02)
    top.legend(loc="lower right", fontsize=8)
    bottom.set_ylabel("total force F (E9)")
    bottom.set_xlabel("t [s]")
    bottom.set_yscale("log")
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
    n_robots = len(scenario.nominal_positions())
    fig.suptitle(f"Effect of optimisation: N = {n_robots}, mean ± sd of {runs} held-out runs")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _plot_convergence(path: Path, histories: dict[str, list[np.ndarray]]) -> None:
    fig, axes = plt.subplots(1, len(histories), figsize=(4 * len(histories), 3.6))
    for ax, (label, hs) in zip(np.atleast_1d(axes), histories.items(), strict=True):
        for r, h in enumerate(hs):
            best = np.minimum.accumulate(h)
            ax.plot(np.arange(1, len(h) + 1), best, lw=1.4, label=f"restart {r}")
        finite = np.concatenate([np.minimum.accumulate(h) for h in hs])
        finite = finite[np.isfinite(finite)]
        if finite.size:
            lo, hi = finite.min(), np.percentile(finite, 95)
            ax.set_ylim(lo - 0.05 * (hi - lo + 1e-9), hi + 0.05 * (hi - lo + 1e-9))
        ax.set_title(label, fontsize=9)
        ax.set_xlabel("evaluations")
        ax.grid(alpha=0.3)
    np.atleast_1d(axes)[0].set_ylabel("best-so-far J")
    np.atleast_1d(axes)[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _plot_slices(path: Path, slices: dict[str, tuple[np.ndarray, np.ndarray]]) -> None:
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.4), sharey=True)
    symbols = {"alpha": "α", "beta": "β", "k": "k"}
    for ax, (name, (x, J)) in zip(axes, slices.items(), strict=True):
        ax.plot(x, J, "o-", ms=4)
        ax.axvline(PAPER_GAINS[name], color="k", ls=":", lw=1, label="paper's value")
        if name == "k":  # linear axis: the grid starts at k = 0
            ax.axvline(DEFAULT_BOUNDS["k"][0], color="tab:red", ls="--", lw=1, label="lower bound")
        else:
            ax.set_xscale("log")
        ax.set_xlabel(symbols[name] + " (others at the paper's values)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_ylabel("J (E10), weights (1/N, −1)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _write_csv(path: Path, rows: list[dict[str, Any]]) -> None:
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        for row in rows:
            writer.writerow({k: f"{v:.6g}" if isinstance(v, float) else v for k, v in row.items()})
