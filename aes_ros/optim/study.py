"""The paper's tuning study in one call (``aes-swarm study``; Raoufi et al. 2019).

See docs/design.md#tuning.

:func:`run_study` compares untuned gains, the paper's tuned gains and
TCACS-tuned gains (:func:`aes_ros.optim.tuning.tune`) for the paper's weights
(w_1, w_2) = (1/N, −1) and the two variants (10/N, −1) and (1/N, −10), each
restarted with independent seeds; then every gain set is re-simulated on
held-out seeds for ψ(t) and F(t) figures and a table of J (mean ± sd). A run in
the wide box (k down to 0) and slices of J through the paper's point show why
the default box stops at k = 0.5 (see :mod:`aes_ros.optim.tuning`).
"""

from __future__ import annotations

import csv
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aes_ros import simulator
from aes_ros.metrics import spring_strain
from aes_ros.optim import figures
from aes_ros.optim.cost import TUNED_GAINS, MonteCarloCost, run_costs
from aes_ros.optim.tcacs import DEFAULT_MAX_EVALS
from aes_ros.optim.tuning import (
    DEFAULT_BOUNDS,
    PAPER_GAINS,
    WIDE_BOUNDS,
    mc_seeds,
    scenario_record,
    summary_line,
    tune,
)
from aes_ros.scenario import Scenario

#: "Default" (untuned) gains of the study: every gain 1 (see :func:`run_study`).
UNTUNED_GAINS = {"alpha": 1.0, "beta": 1.0, "k": 1.0}
#: The paper's weight settings (w_1 in units of 1/N, w_2), docs/design.md#cost
WEIGHTS = {"paper": (1.0, -1.0), "force×10": (10.0, -1.0), "alignment×10": (1.0, -10.0)}

#: Seeds of the held-out evaluation runs (disjoint from any tuning run's seeds).
HELD_OUT_SEED0 = 1_000_000
#: Held-out runs per gain set whose final formation is recorded for the strain column.
STRAIN_RUNS = 10


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


def run_study(
    out: Path,
    scenario: Scenario,
    *,
    evals: int = DEFAULT_MAX_EVALS,
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

    Each TCACS setting runs ``restarts`` times: restart i seeds TCACS with i and its
    Monte-Carlo run r with i·mc + r (the study's tuning runs numbered from 0, disjoint
    sets, the one seed rule of ``--seed``); restart 0 (fixed in advance, no
    selection) gives the gains of the figures and the J table, all restarts
    are listed in runs.csv. J is reported under all three weightings as mean ±
    standard deviation over the ``eval_runs`` held-out runs of the per-run
    cost Σ_t [w_1 F + w_2 ψ]. Robots pass through each other, as in the paper:
    ``contacts`` is set false in ``scenario``.
    """
    # The paper's robots have no bodies: its figures (docs/study) hold whatever the
    # default of ``contacts`` is.
    scenario = scenario.with_overrides({"contacts": False})
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
                seed=restart, mc_seed=restart * mc,
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

    figures.effect_of_optimisation(
        out / "effect_of_optimisation.png",
        ev["times"],
        ev["psi"],
        ev["force"],
        [g.label for g in gain_sets],
        n_robots,
    )
    figures.study_convergence(out / "convergence.png", histories)
    figures.j_slices(out / "j_slices.png", slices, PAPER_GAINS, DEFAULT_BOUNDS["k"][0])
    _write_csv(out / "table.csv", rows)
    _write_csv(out / "runs.csv", runs)
    study = {
        "scenario": scenario_record(scenario),
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
    """One row per gain set: gains, J (mean, sd) under each of :data:`WEIGHTS`, ψ̄, strain, F̄/N."""
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


def _write_csv(path: Path, rows: list[dict[str, Any]]) -> None:
    """Rows as CSV, floats with 6 significant digits."""
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        for row in rows:
            writer.writerow({k: f"{v:.6g}" if isinstance(v, float) else v for k, v in row.items()})
