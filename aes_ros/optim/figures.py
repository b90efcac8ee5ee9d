"""Figures of a tuning run and of the tuning study: plain matplotlib (Agg) from arrays, to PNG.

* :func:`tuning_convergence` — every J of one TCACS run and the best so far;
* :func:`study_convergence` — best-so-far J of every restart, one panel per setting;
* :func:`effect_of_optimisation` — ψ(t) (E8) and F(t) (E9) of several gain sets;
* :func:`j_slices` — J (E10) along each gain through the paper's point.

Each takes the numbers (no scenario, no simulator) and writes one PNG at 110 dpi.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes

DPI = 110


def tuning_convergence(path: Path, history_fun: np.ndarray, title: str) -> None:
    """One TCACS run: J of every evaluation (grey dots) and the best so far.

    history_fun : (nfev,) J in evaluation order (+inf for a blown-up candidate).
    The y range runs from the best J to the 90th percentile, so the early bad
    candidates do not flatten the curve.
    """
    fig, ax = plt.subplots(figsize=(7, 4))
    _convergence_axes(ax, history_fun, label="best so far")
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def _convergence_axes(ax: Axes, history_fun: np.ndarray, label: str) -> None:
    evals = np.arange(1, len(history_fun) + 1)
    best = np.minimum.accumulate(history_fun)
    finite = np.isfinite(history_fun)
    if finite.any():
        ax.scatter(evals[finite], history_fun[finite], s=6, alpha=0.35, color="0.5", label="J")
        hi = np.percentile(history_fun[finite], 90)
        lo = best[np.isfinite(best)].min()
        ax.set_ylim(lo - 0.05 * (hi - lo + 1e-9), hi + 0.05 * (hi - lo + 1e-9))
    ax.plot(evals, best, label=label, lw=1.8)
    ax.set_xlabel("evaluations")
    ax.set_ylabel("J (E10)")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right")


def study_convergence(path: Path, histories: Mapping[str, Sequence[np.ndarray]]) -> None:
    """Best-so-far J of every restart, one panel per tuning setting.

    histories : setting label -> one (nfev,) J history per restart.
    """
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
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def effect_of_optimisation(
    path: Path,
    times: np.ndarray,
    psi: np.ndarray,
    force: np.ndarray,
    labels: Sequence[str],
    n_robots: int,
    dashed: int = 2,
) -> None:
    """ψ(t) (E8, top) and F(t) (E9, bottom, log scale) of each gain set, mean ± sd over runs.

    times : (T+1,) [s]; psi, force : (G, runs, T+1) for the G gain sets named
    by ``labels``; n_robots : N, for the title. The first ``dashed`` gain sets
    (the references: untuned and the paper's) are drawn dashed.
    """
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    for i, label in enumerate(labels):
        style = {"lw": 1.6, "ls": "--" if i < dashed else "-"}
        for ax, values in ((top, psi), (bottom, force)):
            mean, sd = values[i].mean(axis=0), values[i].std(axis=0)
            (line,) = ax.plot(times, mean, label=f"{label}", **style)
            ax.fill_between(times, mean - sd, mean + sd, color=line.get_color(), alpha=0.12)
    top.set_ylabel("force alignment ψ (E8)")
    top.set_ylim(0, 1.02)
    top.legend(loc="lower right", fontsize=8)
    bottom.set_ylabel("total force F (E9)")
    bottom.set_xlabel("t [s]")
    bottom.set_yscale("log")
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
    runs = psi.shape[1]
    fig.suptitle(f"Effect of optimisation: N = {n_robots}, mean ± sd of {runs} held-out runs")
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def j_slices(
    path: Path,
    slices: Mapping[str, tuple[np.ndarray, np.ndarray]],
    paper_gains: Mapping[str, float],
    k_lower_bound: float,
) -> None:
    """J along α, β and k (one panel each, the other gains at the paper's values).

    slices : gain name ("alpha", "beta", "k") -> (grid (M,), J (M,)); α and β
    on log axes, k on a linear axis (its grid starts at 0). Dotted: the
    paper's value of the gain; dashed (k only): the search box's lower bound.
    """
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.4), sharey=True)
    symbols = {"alpha": "α", "beta": "β", "k": "k"}
    for ax, (name, (x, J)) in zip(axes, slices.items(), strict=True):
        ax.plot(x, J, "o-", ms=4)
        ax.axvline(paper_gains[name], color="k", ls=":", lw=1, label="paper's value")
        if name == "k":
            ax.axvline(k_lower_bound, color="tab:red", ls="--", lw=1, label="lower bound")
        else:
            ax.set_xscale("log")
        ax.set_xlabel(symbols[name] + " (others at the paper's values)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_ylabel("J (E10), weights (1/N, −1)")
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
