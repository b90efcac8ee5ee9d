"""How robust are the gains? The paper's and the TCACS gains under noise, size and failures.

The cost J (E10, the paper's weights) and the force alignment ψ̄ of the paper's
gains (α, β, k) = (0.066, 0.97, 1.28) and of the TCACS gains of the tuning study
(weights (1/N, −1)) on the combined setup (30 s), with both noises scaled by
×0.5 … ×2, for 25 and 400 robots, intact and with 10 % of the robots failing
(stopped where they are, the same ones in every run) at t = 15 s. Common random
numbers throughout: every cell runs the same seeds.

Outputs (``--out``): ``robustness.png``, ``robustness.csv`` and ``robustness.json``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from aes_ros import scenario
from aes_ros.studies.common import Where, study_gain_sets, sweep_points, write_csv

SCALES = (0.5, 0.71, 1.0, 1.41, 2.0)
FAIL = (0.1, 15.0)


def run(out: Path, where: Where, quick: bool = False) -> dict[str, Any]:
    sets = study_gain_sets()
    chosen = [
        next(g for g in sets if g.label.startswith("paper")),
        next(g for g in sets if g.label.startswith("TCACS, weights (1/N, −1)")),
    ]
    base = scenario.load("combined")
    if quick:
        base = base.with_overrides({"duration": 10.0})
    fail = (FAIL[0], base.duration / 2)
    sizes = (25, 100) if quick else (25, 400)
    mc = 2 if quick else 10
    names = ["alpha", "beta", "k", "d_r", "d_theta"]
    table = [[g.alpha, g.beta, g.k, s * base.d_r, s * base.d_theta] for g in chosen for s in SCALES]
    rows = []
    for n in sizes:
        sc = base.with_robots(n)
        for failing in (None, fail):
            tag = "failing" if failing else "intact"
            summary = sweep_points(
                f"robustness_{n}_{tag}", sc, names, np.array(table), where, mc=mc, fail=failing
            )
            for k, r in enumerate(summary):
                rows.append(
                    {
                        "gains": chosen[k // len(SCALES)].label,
                        "robots": n,
                        "noise_scale": SCALES[k % len(SCALES)],
                        "robots_failing": tag,
                        "J": r["J_mean"],
                        "J_std": r["J_std"],
                        "psi": r["psi_mean"],
                        "psi_std": r["psi_std"],
                        "strain": r["strain_mean"],
                    }
                )
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "robustness.csv", rows)
    result = {"cells": len(rows), "verdict": _verdict(rows, chosen, sizes)}
    (out / "robustness.json").write_text(json.dumps(result, indent=1))
    _figure(out / "robustness.png", rows, chosen, sizes)
    return result


def _verdict(rows: list[dict], chosen, sizes) -> dict[str, Any]:
    """Per robot count and failure case: in how many noise cells the TCACS gains have
    the lower J and the higher ψ̄ than the paper's."""
    out = {}
    paper, tcacs = chosen[0].label, chosen[1].label
    for n in sizes:
        for tag in ("intact", "failing"):
            cell = [r for r in rows if r["robots"] == n and r["robots_failing"] == tag]
            p = {r["noise_scale"]: r for r in cell if r["gains"] == paper}
            t = {r["noise_scale"]: r for r in cell if r["gains"] == tcacs}
            out[f"N={n} {tag}"] = {
                "tcacs_lower_J": sum(t[s]["J"] < p[s]["J"] for s in SCALES),
                "tcacs_higher_psi": sum(t[s]["psi"] > p[s]["psi"] for s in SCALES),
                "of": len(SCALES),
            }
    return out


def _figure(path: Path, rows: list[dict], chosen, sizes) -> None:
    fig, axes = plt.subplots(2, len(sizes), figsize=(5.5 * len(sizes), 7), squeeze=False)
    for col, n in enumerate(sizes):
        for row, (metric, label) in enumerate((("J", "cost J (E10)"), ("psi", "ψ̄ (E8)"))):
            ax = axes[row, col]
            for g, color in zip(chosen, ("C0", "C3"), strict=False):
                for tag, style in (("intact", "-"), ("failing", "--")):
                    cell = [
                        r
                        for r in rows
                        if (r["gains"], r["robots"], r["robots_failing"]) == (g.label, n, tag)
                    ]
                    ax.errorbar(
                        [r["noise_scale"] for r in cell],
                        [r[metric] for r in cell],
                        yerr=[r[f"{metric}_std"] for r in cell],
                        color=color,
                        ls=style,
                        marker="o",
                        ms=4,
                        capsize=2,
                        label=f"{g.label}, {tag}",
                    )
            ax.set_xscale("log")
            ax.set_xticks(SCALES, [f"×{s:g}" for s in SCALES])
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.set(xlabel="both noises scaled", ylabel=label, title=f"{n} robots")
            if row == 0 and col == 0:
                ax.legend(fontsize=7)
    fig.suptitle("solid: intact; dashed: 10 % of the robots stop at half time", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
