"""How good must sensing be? The tolerance of the AES to perception error.

The robots see each other through a tracker's pose list (:mod:`aes_ros.perception`):
position noise σ_p, delay τ, refresh rate f_cam and per-robot miss probability.
Each is swept alone, the other three at lab-typical values (:data:`LAB`: a 20 Hz
overhead camera with 3 mm of noise, 50 ms of latency and 1 % of the robots missed a
frame), on the combined setup (60 s, commands clipped to the Mona's limits as a lab's
robots clip them; ψ̄ (E8) averaged over t ≥ 20 s), for 25 and
100 robots, with the paper's and the TCACS gains of the tuning study. Common random
numbers throughout: every point runs the same seeds.

Where ψ̄ first falls below :data:`LEVEL` (0.8) along an axis is its **tolerance**,
interpolated linearly between grid points; its 95 % interval is where the curves
ψ̄ ± 1.96·s/√runs cross the level (``ci_from``: the lower edge, where a breakdown
becomes possible; ``ci_to``: the upper edge, where it is certain; NaN: not within the
swept range). The lab needs tracking better than the tightest tolerance over sizes and
gains (:func:`requirement`).

Outputs (``--out``): ``perception.png``, ``perception.csv`` (every point),
``tolerance.csv`` (one row per axis, size and gains) and ``perception.json``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from aes_ros import scenario
from aes_ros.studies.common import GainSet, Where, study_gain_sets, sweep_points, write_csv

#: ψ̄ below which collective motion counts as broken down.
LEVEL = 0.8
#: Lab-typical perception: what the axes not swept are held at.
LAB = {
    "perception_sigma": 0.003,
    "perception_delay": 0.05,
    "perception_rate": 20.0,
    "perception_miss": 0.01,
}


@dataclass(frozen=True)
class Axis:
    """One swept perception parameter: its grid, how it is shown, and which way is worse."""

    name: str
    label: str
    scale: float  # shown value = value × scale
    unit: str
    grid: tuple[float, ...]
    worse_when_lower: bool = False


#: The issue's ranges (σ_p 0–30 mm, τ 0–500 ms, f_cam 50–2 Hz, miss 0–30 %), each
#: continued to where the swarm breaks down or the parameter's range ends, so that a
#: tolerance beyond the lab range is found rather than reported as "more than".
AXES = (
    Axis("perception_sigma", "position noise σ_p", 1e3, "mm",
         (0.0, 0.001, 0.002, 0.003, 0.005, 0.0075, 0.01, 0.015, 0.02, 0.025, 0.03,
          0.04, 0.05, 0.06, 0.08, 0.1)),
    Axis("perception_delay", "delay τ", 1e3, "ms",
         (0.0, 0.025, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0)),
    Axis("perception_rate", "camera rate f_cam", 1.0, "Hz",
         (50.0, 30.0, 20.0, 15.0, 10.0, 7.5, 5.0, 4.0, 3.0, 2.0, 1.5, 1.0, 0.75, 0.5),
         worse_when_lower=True),
    Axis("perception_miss", "missed detections", 1e2, "%",
         (0.0, 0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)),
)  # fmt: skip
QUICK_AXES = tuple(
    Axis(a.name, a.label, a.scale, a.unit, a.grid[::3] + a.grid[-1:], a.worse_when_lower)
    for a in AXES
)


def crossing(x: np.ndarray, y: np.ndarray, level: float = LEVEL) -> float:
    """Where ``y`` (along ``x``, ordered from best to worst) first falls below ``level``,
    interpolated linearly; NaN if it never does, ``x[0]`` if it starts below."""
    below = np.flatnonzero(np.asarray(y) < level)
    if len(below) == 0:
        return math.nan
    i = int(below[0])
    if i == 0:
        return float(x[0])
    x0, x1, y0, y1 = float(x[i - 1]), float(x[i]), float(y[i - 1]), float(y[i])
    return x0 + (level - y0) * (x1 - x0) / (y1 - y0)


def tolerance(
    x: np.ndarray, mean: np.ndarray, std: np.ndarray, runs: int, level: float = LEVEL
) -> tuple[float, float, float]:
    """(tolerance, low, high): where ψ̄ (``mean`` over ``runs`` runs, standard deviation
    ``std``, along ``x`` from best to worst) crosses ``level``, and where the edges of
    its 95 % confidence band do (the band's lower edge crosses first)."""
    half = 1.96 * np.asarray(std) / math.sqrt(max(runs, 1))
    first = crossing(x, np.asarray(mean) - half, level)
    last = crossing(x, np.asarray(mean) + half, level)
    return crossing(x, mean, level), first, last


def run(out: Path, where: Where, quick: bool = False) -> dict[str, Any]:
    sets = study_gain_sets()
    chosen = [
        next(g for g in sets if g.label.startswith("paper")),
        next(g for g in sets if g.label.startswith("TCACS, weights (1/N, −1)")),
    ]
    # clip: a lab's robots obey the Mona's limits (the other offline studies do not clip)
    base = scenario.load("combined").with_overrides(
        {"duration": 20.0 if quick else 60.0, "clip": True}
    )
    transient = 5.0 if quick else 20.0
    mc = 3 if quick else 10
    sizes = (25,) if quick else (25, 100)
    axes = QUICK_AXES if quick else AXES
    names = ["alpha", "beta", "k", *LAB]
    table, labels = [], []
    for g in chosen:
        for axis in axes:
            for value in axis.grid:
                setting = {**LAB, axis.name: value}
                table.append([g.alpha, g.beta, g.k, *setting.values()])
                labels.append((g.label, axis.name, value))
    rows = []
    for n in sizes:
        summary = sweep_points(
            f"perception_{n}", base.with_robots(n), names, np.array(table), where,
            mc=mc, transient=transient,
        )  # fmt: skip
        for (gains, axis, value), r in zip(labels, summary, strict=True):
            rows.append({
                "robots": n, "gains": gains, "axis": axis, "value": value,
                "runs": int(r["runs"]), "psi": r["psi_mean"], "psi_std": r["psi_std"],
                "psi_heading": r["psi_heading_mean"], "J": r["J_mean"],
            })  # fmt: skip
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "perception.csv", rows)
    tolerances = _tolerances(rows, axes, chosen, sizes)
    write_csv(out / "tolerance.csv", tolerances)
    result = {
        "level": LEVEL,
        "lab": LAB,
        "setup": f"combined, {base.duration:g} s, psi averaged over t >= {transient:g} s",
        "runs_per_point": mc,
        "tolerance": tolerances,
        "requirement": requirement(tolerances, axes),
    }
    (out / "perception.json").write_text(json.dumps(result, indent=1))
    _figure(out / "perception.png", rows, tolerances, axes, chosen, sizes)
    return result


def _cell(rows: list[dict], n: int, gains: str, axis: str) -> list[dict]:
    return [r for r in rows if (r["robots"], r["gains"], r["axis"]) == (n, gains, axis)]


def _tolerances(
    rows: list[dict], axes: tuple[Axis, ...], chosen: list[GainSet], sizes: tuple[int, ...]
) -> list[dict[str, Any]]:
    found = []
    for n in sizes:
        for g in chosen:
            for axis in axes:
                cell = _cell(rows, n, g.label, axis.name)
                x = np.array([r["value"] for r in cell]) * axis.scale
                t, lo, hi = tolerance(
                    x, np.array([r["psi"] for r in cell]), np.array([r["psi_std"] for r in cell]),
                    cell[0]["runs"],
                )  # fmt: skip
                found.append({
                    "robots": n, "gains": g.label, "axis": axis.name, "unit": axis.unit,
                    "tolerance": t, "ci_from": lo, "ci_to": hi,
                    "swept_to": float(x[-1]),
                })  # fmt: skip
    return found


def requirement(tolerances: list[dict[str, Any]], axes: tuple[Axis, ...]) -> dict[str, Any]:
    """The tightest tolerance of each axis over sizes and gains, and the sentence that
    says what a lab needs (an axis that never broke the swarm is 'beyond' its range)."""
    need: dict[str, Any] = {}
    words = []
    for axis in axes:
        cells = [t for t in tolerances if t["axis"] == axis.name]
        broken = [t["tolerance"] for t in cells if not math.isnan(t["tolerance"])]
        if not broken:
            need[axis.name] = None
            words.append(f"{axis.label} beyond {cells[0]['swept_to']:g} {axis.unit}")
            continue
        value = max(broken) if axis.worse_when_lower else min(broken)
        need[axis.name] = value
        words.append(f"{axis.label} {'above' if axis.worse_when_lower else 'below'} "
                     f"{value:.3g} {axis.unit}")  # fmt: skip
    need["sentence"] = (
        f"psi stays above {LEVEL:g} (each limit with the others at lab values) with "
        + ", ".join(words)
    )
    return need


def _figure(
    path: Path,
    rows: list[dict],
    tolerances: list[dict],
    axes: tuple[Axis, ...],
    chosen: list[GainSet],
    sizes: tuple[int, ...],
) -> None:
    fig, panels = plt.subplots(1, len(axes), figsize=(4.2 * len(axes), 3.8), squeeze=False)
    styles = {sizes[0]: "-", sizes[-1]: "--"}
    for ax, axis in zip(panels[0], axes, strict=True):
        for g, color in zip(chosen, ("C0", "C3"), strict=False):
            for n in sizes:
                cell = _cell(rows, n, g.label, axis.name)
                x = np.array([r["value"] for r in cell]) * axis.scale
                y = np.array([r["psi"] for r in cell])
                half = 1.96 * np.array([r["psi_std"] for r in cell]) / math.sqrt(cell[0]["runs"])
                ax.plot(x, y, color=color, ls=styles[n], marker="o", ms=3,
                        label=f"{g.label.split(',')[0].split(' (')[0]}, N={n}")  # fmt: skip
                ax.fill_between(x, y - half, y + half, color=color, alpha=0.12, lw=0)
        ax.axhline(LEVEL, color="k", lw=0.8, ls=":")
        lab = LAB[axis.name] * axis.scale
        ax.axvline(lab, color="0.6", lw=0.8)
        ax.set(xlabel=f"{axis.label} [{axis.unit}]", ylabel="ψ̄ (E8)", ylim=(0.3, 1.0))
        if axis.worse_when_lower:  # a rate: on a log axis, worse to the right
            ax.set_xscale("log")
            ax.set_xticks([0.5, 1, 2, 5, 10, 20, 50], ["0.5", "1", "2", "5", "10", "20", "50"])
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.invert_xaxis()
        ax.set_title(f"{axis.label}\n(others at lab values; grey: lab)", fontsize=9)
    panels[0, 0].legend(fontsize=7, loc="lower left")
    fig.suptitle(f"combined setup: ψ̄ against perception error; dotted: ψ̄ = {LEVEL:g}",
                 fontsize=10)  # fmt: skip
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
