"""TCACS against CMA-ES, differential evolution and random search on the tuning cost J.

Same problem for all: J (E10) of the paper's combined setup (100 robots, 30 s,
Δt = 0.05 s), weights (1/N, −1), 10 Monte-Carlo runs per candidate, the
default box of ``aes-swarm optimize`` (:data:`aes_ros.optim.tuning.DEFAULT_BOUNDS`),
and the same budget of 300 evaluations, always asked for in batches of 15
(one simulator call per batch). Seed s of every optimiser uses the same
Monte-Carlo seed set (run r of seed s uses s·runs + r: the runs numbered from 0,
disjoint per seed), so within a seed the optimisers face exactly the same function.

* TCACS: the paper's options (15 ants, roulette, γ = 0.5, m = 2).
* CMA-ES (``cma`` package): population 15, 20 generations, in box coordinates
  scaled to [0, 1]³ with σ₀ = 0.3 from the box centre, bounds handled by cma.
* Differential evolution (SciPy): population 15 (popsize = 5 × 3 variables),
  Latin-hypercube start, ``updating="deferred"`` and ``vectorized=True`` (one
  generation = one batch), 19 generations, no polishing, tol = 0 (no early stop).
* Random search: 300 uniform points in the box.

Reports, per optimiser, the best J found (on the run's own Monte-Carlo seeds)
and the J of the returned gains re-simulated on ``--held-out`` fresh seeds
(the same for all), each as mean ± sd over the seeds; writes a markdown table
and a figure of the mean best-so-far curves.

Usage: ``python bench/compare_optimizers.py [--seeds 10] [--out docs/study]``
(``--from-json`` rebuilds the table from a previous run's optimizers.json)
(about 4 × seeds × 10 s on a quiet 2-core machine). Needs ``cma``: the ``bench``
extra, which ``scripts/setup.sh`` installs.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from scipy.optimize import differential_evolution

from aes_ros import scenario
from aes_ros.cli.deprecated import add_deprecated
from aes_ros.cli.options import MAX_RUNS, number_type
from aes_ros.optim import study, tcacs, tuning
from aes_ros.optim.cost import MonteCarloCost

BUDGET = 300
BATCH = 15


class Budget:
    """Counts evaluations, records them, and never spends more than BUDGET."""

    def __init__(self, cost: MonteCarloCost) -> None:
        self.cost = cost
        self.X: list[np.ndarray] = []
        self.J: list[np.ndarray] = []
        self.calls = 0

    @property
    def used(self) -> int:
        return sum(len(j) for j in self.J)

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X = np.atleast_2d(X)
        room = BUDGET - self.used
        J = np.full(len(X), np.inf)
        if room > 0:
            J[:room] = self.cost(X[:room])
            self.X.append(X[:room].copy())
            self.J.append(J[:room].copy())
            self.calls += 1
        return J

    def best(self) -> tuple[np.ndarray, float, np.ndarray]:
        X, J = np.vstack(self.X), np.concatenate(self.J)
        i = int(np.argmin(J))
        return X[i], float(J[i]), np.minimum.accumulate(J)


def run_tcacs(f: Budget, lo: np.ndarray, hi: np.ndarray, seed: int) -> None:
    tcacs.minimize(f, list(zip(lo, hi, strict=True)), max_evals=BUDGET, seed=seed)


def run_cma(f: Budget, lo: np.ndarray, hi: np.ndarray, seed: int) -> None:
    import cma

    opts = {
        "bounds": [0.0, 1.0],
        "popsize": BATCH,
        "seed": seed + 1,  # cma treats seed 0 as "random"
        "maxfevals": BUDGET,
        "verbose": -9,
        "tolfun": 0,
        "tolx": 0,
    }
    es = cma.CMAEvolutionStrategy(np.full(len(lo), 0.5), 0.3, opts)
    while f.used < BUDGET:
        U = np.array(es.ask())
        J = f(lo + U * (hi - lo))
        es.tell(list(U), list(np.where(np.isfinite(J), J, 1e300)))


def run_de(f: Budget, lo: np.ndarray, hi: np.ndarray, seed: int) -> None:
    popsize = BATCH // len(lo)  # SciPy's popsize multiplies the dimension
    differential_evolution(
        lambda x: f(x.T),
        list(zip(lo, hi, strict=True)),
        popsize=popsize,
        maxiter=BUDGET // BATCH - 1,
        init="latinhypercube",
        updating="deferred",
        vectorized=True,
        polish=False,
        tol=0,
        atol=0,
        rng=seed,
    )


def run_random(f: Budget, lo: np.ndarray, hi: np.ndarray, seed: int) -> None:
    rng = np.random.default_rng(seed)
    while f.used < BUDGET:
        f(rng.uniform(lo, hi, size=(BATCH, len(lo))))


OPTIMIZERS: dict[str, Callable[[Budget, np.ndarray, np.ndarray, int], None]] = {
    "TCACS": run_tcacs,
    "CMA-ES": run_cma,
    "differential evolution": run_de,
    "random search": run_random,
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10, help="optimiser seeds 0 … N-1")
    parser.add_argument(
        "--runs", type=number_type(int, 1, MAX_RUNS), default=10, metavar="N",
        help="Monte-Carlo runs per candidate (default 10)",
    )  # fmt: skip
    add_deprecated(parser, "--mc", "--runs")
    parser.add_argument("--held-out", type=int, default=20, help="fresh runs per returned x")
    parser.add_argument(
        "--out", type=Path, default=Path("out/compare_optimizers"), metavar="DIR",
        help="the directory this command writes (default out/compare_optimizers; "
        "docs/study holds the published one)",
    )  # fmt: skip
    parser.add_argument("--only", nargs="*", default=list(OPTIMIZERS))
    parser.add_argument(
        "--from-json", action="store_true", help="only rebuild the table from OUT/optimizers.json"
    )
    args = parser.parse_args()
    if args.from_json:
        records = json.loads((args.out / "optimizers.json").read_text())
        table = markdown(records, tuple(tuning.DEFAULT_BOUNDS), args)
        (args.out / "optimizers.md").write_text(table)
        print(table)
        return
    sc = scenario.load("combined")
    names = tuple(tuning.DEFAULT_BOUNDS)
    lo, hi = np.array([tuning.DEFAULT_BOUNDS[n] for n in names]).T
    tuning.warm_up(sc)
    records: dict[str, list[dict]] = {name: [] for name in args.only}
    for seed in range(args.seeds):
        for name in args.only:
            seeds = tuning.mc_seeds(seed * args.runs, args.runs)
            cost = MonteCarloCost(sc, seeds=seeds, names=names)
            f = Budget(cost)
            start = time.perf_counter()
            OPTIMIZERS[name](f, lo, hi, seed)
            x, J, curve = f.best()
            records[name].append(
                {
                    "seed": seed,
                    "x": x.tolist(),
                    "J": J,
                    "evals": f.used,
                    "calls": f.calls,
                    "seconds": time.perf_counter() - start,
                    "curve": np.round(curve, 4).tolist(),
                }
            )
            print(
                f"seed {seed} {name:>22}: J={J:8.3f} at "
                + ", ".join(f"{n}={v:.4g}" for n, v in zip(names, x, strict=True))
                + f"  ({f.used} evals in {f.calls} batches, {time.perf_counter() - start:.1f} s)",
                flush=True,
            )
    # Held-out check: every returned x on the same fresh seeds, one batch.
    held = MonteCarloCost(
        sc, seeds=[study.HELD_OUT_SEED0 + i for i in range(args.held_out)], names=names
    )
    X = np.array([r["x"] for name in args.only for r in records[name]])
    J_held = held(X).reshape(len(args.only), args.seeds)
    for i, name in enumerate(args.only):
        for r, j in zip(records[name], J_held[i], strict=True):
            r["J_held_out"] = float(j)
    table = markdown(records, names, args)
    print(table)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "optimizers.md").write_text(table)
    (args.out / "optimizers.json").write_text(json.dumps(records) + "\n")
    plot(args.out / "optimizers.png", records)


def markdown(records: dict[str, list[dict]], names: tuple[str, ...], args) -> str:
    lines = [
        f"Budget {BUDGET} evaluations (batches of {BATCH}), {args.runs} Monte-Carlo runs per "
        f"candidate, {args.seeds} seeds per optimiser; mean ± sd over the seeds. "
        f"'J found' is on the run's own seeds, 'J held-out' re-simulates the returned gains "
        f"on {args.held_out} fresh seeds (the same for all).",
        "",
        "'vs TCACS' is the paired difference of J found (same seed, same function) and the "
        "number of seeds on which the optimiser did better than TCACS.",
        "",
        "| optimiser | J found | J held-out | vs TCACS | α | β | k | time per run [s] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    ref = np.array([r["J"] for r in records["TCACS"]]) if "TCACS" in records else None
    for name, rs in records.items():
        J = np.array([r["J"] for r in rs])
        paired = "–"
        if ref is not None and name != "TCACS":
            d = J - ref
            paired = f"{d.mean():+.2f} ± {d.std(ddof=1):.2f} ({int(np.sum(d < 0))}/{len(d)})"
        H = np.array([r["J_held_out"] for r in rs])
        X = np.array([r["x"] for r in rs])
        T = np.array([r["seconds"] for r in rs])
        gains = " | ".join(
            f"{X[:, i].mean():.3g} ± {X[:, i].std(ddof=1):.2g}" for i in range(len(names))
        )
        lines.append(
            f"| {name} | {J.mean():.2f} ± {J.std(ddof=1):.2f} | {H.mean():.2f} ± "
            f"{H.std(ddof=1):.2f} | {paired} | {gains} | {T.mean():.1f} |"
        )
    return "\n".join(lines) + "\n"


def plot(path: Path, records: dict[str, list[dict]]) -> None:
    fig, ax = plt.subplots(figsize=(7, 4))
    for name, rs in records.items():
        curves = np.array([r["curve"] for r in rs])
        evals = np.arange(1, curves.shape[1] + 1)
        med = np.median(curves, axis=0)
        (line,) = ax.plot(evals, med, label=name)
        q1, q3 = np.percentile(curves, [25, 75], axis=0)
        ax.fill_between(evals, q1, q3, color=line.get_color(), alpha=0.15)
    finite = np.concatenate(
        [np.array([r["curve"] for r in rs])[:, 30:].ravel() for rs in records.values()]
    )
    finite = finite[np.isfinite(finite)]
    if finite.size:
        ax.set_ylim(finite.min() - 1, np.percentile(finite, 99) + 1)
    ax.set_xlabel("evaluations")
    ax.set_ylabel("best-so-far J (median, quartiles)")
    ax.set_title("Optimisers on J (E10), combined setup, N = 100")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
