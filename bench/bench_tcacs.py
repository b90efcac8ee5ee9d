"""TCACS against the reference behaviour of its authors' implementation (docs/design.md#tcacs).

Runs every function of :data:`aes_ros.optim.benchmarks.BENCHMARKS` ``--runs`` times (100
by default) with the dimension's default options (n < 4: 10 ants, rank, γ = 1,
m = 1; n >= 4: 15 ants, roulette, γ = 0.5, m = 2), tol = 1e-4 and at most
10,000 evaluations, and prints success rate and mean evaluations next to the
reference numbers (success = |f − f*| < 1e-4·|f*| + 1e-6). Shekel-5 and
Hartmann-6 have no reference numbers; they exercise the n >= 4 defaults.

Usage: ``python bench/bench_tcacs.py [--runs 100] [--markdown docs/study/bench_tcacs.md]``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from aes_ros.optim.benchmarks import BENCHMARKS
from aes_ros.optim.tcacs import minimize
from aes_ros.optim.tcacs_options import default_options


def run(runs: int, max_evals: int) -> list[dict]:
    rows = []
    for name, b in BENCHMARKS.items():
        n = len(b.bounds)
        start = time.perf_counter()
        results = [
            minimize(b.f, b.bounds, **default_options(n), max_evals=max_evals, tol=1e-4, seed=s)
            for s in range(runs)
        ]
        success = np.array([b.success(r.fun) for r in results])
        evals = np.array([r.nfev for r in results])
        rows.append(
            {
                "function": name,
                "n": n,
                "success": success.mean(),
                "success_se": np.sqrt(success.mean() * (1 - success.mean()) / runs),
                "evals": evals.mean(),
                "evals_se": evals.std(ddof=1) / np.sqrt(runs),
                "ref_success": b.ref_success,
                "ref_evals": b.ref_evals,
                "seconds": time.perf_counter() - start,
            }
        )
    return rows


def markdown(rows: list[dict], runs: int) -> str:
    lines = [
        f"TCACS, {runs} runs per function (seeds 0…{runs - 1}), default options for the "
        "dimension, tol = 1e-4, at most 10,000 evaluations; ± is one standard error.",
        "",
        "| function | n | success | reference | mean evaluations | reference | ratio |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        ref_s = f"{r['ref_success']:.0%}" if r["ref_success"] is not None else "–"
        ref_e = f"≈ {r['ref_evals']}" if r["ref_evals"] is not None else "–"
        ratio = f"{r['evals'] / r['ref_evals']:.2f}" if r["ref_evals"] else "–"
        lines.append(
            f"| {r['function']} | {r['n']} | {r['success']:.0%} ± {r['success_se']:.0%} | "
            f"{ref_s} | {r['evals']:.0f} ± {r['evals_se']:.0f} | {ref_e} | {ratio} |"
        )
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100)
    parser.add_argument("--max-evals", type=int, default=10_000)
    parser.add_argument("--markdown", type=Path, default=None, help="also write the table here")
    args = parser.parse_args()
    start = time.perf_counter()
    rows = run(args.runs, args.max_evals)
    table = markdown(rows, args.runs)
    print(table)
    print(f"[{time.perf_counter() - start:.1f} s]")
    if args.markdown is not None:
        args.markdown.parent.mkdir(parents=True, exist_ok=True)
        args.markdown.write_text(table)


if __name__ == "__main__":
    main()
