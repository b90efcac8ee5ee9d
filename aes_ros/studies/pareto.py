"""The Pareto front behind the paper's gains: mean force per robot against force alignment.

The paper's cost (E10) adds w_1·F and w_2·ψ; per step and robot it weighs
F/N against ψ with the ratio r = N·w_1 / |w_2| (the paper's weights: r = 1; the
study's variants: r = 10 and 0.1). Every weighting's optimum therefore lies on
the Pareto front of (F̄/N ↓, ψ̄ ↑) over (α, β, k). This study samples that front
with a Latin hypercube over α, β, k (combined setup, 100 robots, 30 s, common
random numbers), places the untuned, the paper's and the TCACS gains of the tuning
study on it, and follows the optimum's k as r goes from 0.01 to 100: does any
weighting make k ≈ 1.28 (the paper's k*) optimal?

Outputs (``--out``): ``pareto.png``, ``pareto_points.csv`` (every sample, with
``on_front``), ``gain_sets.csv``, ``k_along_weights.csv`` and ``pareto.json`` (the
conclusion's numbers).
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
from aes_ros.sweep.spec import parse_axis, points

PAPER_K = 1.28
#: The sampled box (log axes): wider than the tuning box, k down to 0.05.
BOX = ("alpha=log:0.002:0.5", "beta=log:0.05:5", "k=log:0.05:5")
NAMES = ["alpha", "beta", "k"]


def pareto_front(cost: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """Mask of the points no other point beats in both (lower ``cost``, higher ``gain``)."""
    order = np.lexsort((-gain, cost))  # by cost, then by gain (best first)
    front = np.zeros(len(cost), dtype=bool)
    best = -np.inf
    for i in order:
        if gain[i] > best:
            front[i] = True
            best = gain[i]
    return front


def optimum_along_weights(force: np.ndarray, psi: np.ndarray, ratios: np.ndarray) -> np.ndarray:
    """For each weight ratio r: the index of the point minimising r·F̄/N − ψ̄."""
    return np.argmin(ratios[:, None] * force[None, :] - psi[None, :], axis=1)


def run(out: Path, where: Where, quick: bool = False) -> dict[str, Any]:
    """Sample, evaluate the study's gain sets with the same seeds, draw and conclude."""
    base = scenario.load("combined").with_robots(36 if quick else 100)
    if quick:
        base = base.with_overrides({"duration": 10.0})
    samples, mc = (60, 2) if quick else (600, 5)
    axes = [parse_axis(spec) for spec in BOX]
    sample = sweep_points(
        "pareto_lhs", base, NAMES, points(axes, lhs=samples, seed=0), where, mc=mc, lhs=samples
    )
    sets = study_gain_sets()
    known = sweep_points(
        "pareto_gain_sets", base, NAMES, [[g.alpha, g.beta, g.k] for g in sets], where, mc=mc
    )
    force = np.array([r["force_per_robot_mean"] for r in sample])
    psi = np.array([r["psi_mean"] for r in sample])
    finite = np.isfinite(force) & np.isfinite(psi)
    front = np.zeros(len(sample), dtype=bool)
    front[finite] = pareto_front(force[finite], psi[finite])
    ratios = np.logspace(-2, 2, 81)
    pick = np.flatnonzero(finite)[optimum_along_weights(force[finite], psi[finite], ratios)]
    k_opt = np.array([sample[i]["k"] for i in pick])

    # how far each known gain set is from the front: the ψ̄ it loses against the best
    # sampled point with no more force
    rows_sets = []
    for g, r in zip(sets, known, strict=True):
        no_more = finite & (force <= r["force_per_robot_mean"])
        best_psi = float(psi[no_more].max()) if no_more.any() else float("nan")
        rows_sets.append(
            {
                "gains": g.label,
                "alpha": g.alpha,
                "beta": g.beta,
                "k": g.k,
                "force_per_robot": r["force_per_robot_mean"],
                "psi": r["psi_mean"],
                "J": r["J_mean"],
                "psi_below_front": best_psi - r["psi_mean"],
            }
        )
    near_paper_k = np.abs(np.log(k_opt / PAPER_K)) < np.log(1.25)
    result = {
        "samples": int(finite.sum()),
        "front_points": int(front.sum()),
        "front_k_range": [
            float(np.min(_col(sample, "k")[front])),
            float(np.max(_col(sample, "k")[front])),
        ],
        "k_optimum_at_r": {
            f"{r:g}": float(k_opt[np.argmin(np.abs(ratios - r))]) for r in (0.01, 0.1, 1, 10, 100)
        },
        "any_weighting_near_paper_k": bool(near_paper_k.any()),
        "ratios_near_paper_k": [float(r) for r in ratios[near_paper_k]],
        "gain_sets": rows_sets,
    }
    out.mkdir(parents=True, exist_ok=True)
    write_csv(
        out / "pareto_points.csv",
        [{**r, "on_front": int(f)} for r, f in zip(sample, front, strict=True)],
    )
    write_csv(out / "gain_sets.csv", rows_sets)
    write_csv(
        out / "k_along_weights.csv",
        [
            {
                "ratio": float(r),
                "alpha": sample[i]["alpha"],
                "beta": sample[i]["beta"],
                "k": sample[i]["k"],
                "force_per_robot": force[i],
                "psi": psi[i],
            }
            for r, i in zip(ratios, pick, strict=True)
        ],
    )
    (out / "pareto.json").write_text(json.dumps(result, indent=1))
    _figure(out / "pareto.png", sample, force, psi, front, rows_sets, ratios, k_opt, base)
    return result


def _col(rows: list[dict[str, float]], name: str) -> np.ndarray:
    return np.array([r[name] for r in rows])


def _figure(path, sample, force, psi, front, sets, ratios, k_opt, base) -> None:
    fig, (ax, ax_zoom, ax_k) = plt.subplots(1, 3, figsize=(17, 4.8))
    k = _col(sample, "k")
    order = np.argsort(force[front])
    for panel, zoom in ((ax, False), (ax_zoom, True)):
        dots = panel.scatter(force, psi, c=np.log10(k), s=9 if not zoom else 16,
                             cmap="viridis", alpha=0.7)  # fmt: skip
        panel.plot(force[front][order], psi[front][order], "k-", lw=1.5, label="Pareto front")
        markers = iter("sD^vP*X")
        for row in sets:
            panel.plot(row["force_per_robot"], row["psi"], next(markers, "o"), ms=9, mec="k",
                       label=f"{row['gains']} (k={row['k']:.2g})")  # fmt: skip
        panel.set_xlabel("mean total force per robot F̄/N (E9)")
        panel.set_ylabel("mean force alignment ψ̄ (E8)")
    ax.set_xscale("log")
    ax.set_title(f"{len(sample)} (α, β, k) samples, {len(base.nominal_positions())} robots")
    ax.legend(fontsize=7, loc="lower left")
    f0 = float(np.nanmin(force))
    ax_zoom.set_xlim(f0 - 0.01, f0 + 0.12)
    ax_zoom.set_ylim(float(np.nanmax(psi)) - 0.15, float(np.nanmax(psi)) + 0.02)
    ax_zoom.set_title("near the front")
    fig.colorbar(dots, ax=ax_zoom, label="log10 k")
    ax_k.semilogx(ratios, k_opt, "o-", ms=3, label="k of the optimum")
    ax_k.axhline(PAPER_K, color="r", ls="--", label="paper's k* = 1.28")
    for r, name in ((0.1, "alignment×10"), (1.0, "paper"), (10.0, "force×10")):
        ax_k.axvline(r, color="grey", lw=0.8)
        ax_k.text(r, 0.03, name, fontsize=7, rotation=90, transform=ax_k.get_xaxis_transform())
    ax_k.set_yscale("log")
    ax_k.set_xlabel("weight ratio r = N·w1 / |w2| (force against alignment)")
    ax_k.set_ylabel("k of the best sample")
    ax_k.set_title("which k each weighting of E10 makes optimal")
    ax_k.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
