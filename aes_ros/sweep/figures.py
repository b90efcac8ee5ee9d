"""A sweep's figures: lines over one axis, heat maps over two, scatter for samples.

``sweep_metrics.png`` shows ψ̄, ψ̄_heading, F̄/N, the final strain and J of every
point: with one axis as lines (mean ± standard deviation over the runs); on a grid
of two or more axes as heat maps over the first two (averaged over the others); for
Latin-hypercube samples as points on the first two axes coloured by the value.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from aes_ros.sweep.runs import RUN_COLUMNS

LABELS = {
    "psi": "force alignment ψ̄",
    "psi_heading": "heading order ψ̄_heading",
    "force_per_robot": "total force F̄ / N",
    "strain": "final strain",
    "J": "cost J (E10)",
}


def plot_sweep(sweep: Any, summary: list[dict[str, Any]], out: Path) -> Path:
    """Draw ``out/sweep_metrics.png`` from the per-point ``summary``."""
    names = sweep.names
    fig, axes = plt.subplots(1, len(RUN_COLUMNS), figsize=(4.2 * len(RUN_COLUMNS), 3.6))
    x = np.array([row[names[0]] for row in summary])
    for ax, column in zip(axes, RUN_COLUMNS, strict=True):
        mean = np.array([row[f"{column}_mean"] for row in summary])
        if len(names) == 1:
            std = np.array([row[f"{column}_std"] for row in summary])
            order = np.argsort(x)
            ax.plot(x[order], mean[order], "o-", ms=3)
            ax.fill_between(x[order], (mean - std)[order], (mean + std)[order], alpha=0.25)
            ax.set_xlabel(names[0])
        else:
            y = np.array([row[names[1]] for row in summary])
            grid = sweep.lhs is None
            _two_axes(fig, ax, x, y, mean, grid, sweep.axes[0].log, sweep.axes[1].log)
            ax.set_xlabel(names[0])
            ax.set_ylabel(names[1])
            if sweep.axes[1].log:
                ax.set_yscale("log")
        if sweep.axes[0].log:
            ax.set_xscale("log")
        ax.set_title(LABELS[column], fontsize=10)
    others = f" (mean over {', '.join(names[2:])})" if len(names) > 2 else ""
    fig.suptitle(
        f"{len(summary)} points × {sweep.mc} runs{others}; N from the scenario unless swept",
        fontsize=10,
    )
    fig.tight_layout()
    path = out / "sweep_metrics.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _two_axes(
    fig, ax, x: np.ndarray, y: np.ndarray, value: np.ndarray, grid: bool, logx: bool, logy: bool
) -> None:
    finite = np.isfinite(value)
    if grid:
        xs, ys = np.unique(x), np.unique(y)
        image = np.full((len(ys), len(xs)), np.nan)
        for i, xv in enumerate(xs):
            for j, yv in enumerate(ys):
                cell = (x == xv) & (y == yv) & finite
                if cell.any():
                    image[j, i] = value[cell].mean()
        edges = (_edges(xs, logx), _edges(ys, logy))
        mesh = ax.pcolormesh(*edges, image, shading="flat", cmap="viridis")
    else:
        mesh = ax.scatter(x[finite], y[finite], c=value[finite], s=14, cmap="viridis")
    fig.colorbar(mesh, ax=ax)


def _edges(centres: np.ndarray, log: bool) -> np.ndarray:
    """Cell edges around sorted centres (halfway between them, in log space on a log axis)."""
    c = np.log(centres) if log else centres
    if len(c) == 1:
        edges = (
            np.array([c[0] - 0.5, c[0] + 0.5]) if not log else np.array([c[0] - 0.1, c[0] + 0.1])
        )
    else:
        mids = (c[:-1] + c[1:]) / 2
        edges = np.concatenate([[2 * c[0] - mids[0]], mids, [2 * c[-1] - mids[-1]]])
    return np.exp(edges) if log else edges
