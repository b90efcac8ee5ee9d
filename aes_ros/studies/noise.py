"""The noise phase diagram: where collective motion breaks down.

Order is the heading order ψ_heading (E7), time-averaged after a transient, of a
sheet driven west (linear setup, the paper's gains). Two noises act on a robot:
D_r on the force it senses, D_θ on its turning (docs/design.md#model).

1. ψ̄_heading over (D_r, D_θ) on a log grid, 100 robots in a square sheet;
2. ψ̄_heading along each noise alone (the other at its default), for N ≈ 25, 100,
   400 and 1600 robots in square and hexagonal sheets; the noise at which
   ψ̄_heading falls below 0.5 is the "breakdown noise" of that sheet.

Outputs (``--out``): ``noise_phase.png``, ``phase_grid.csv``, ``noise_lines.csv``,
``breakdown.csv`` and ``noise.json``.
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
from aes_ros.studies.common import Where, sweep_points, write_csv
from aes_ros.sweep.spec import parse_axis, points

#: Square sheets (N robots) and hexagonal ones (rings s: N = 3s(s+1)+1) of about
#: 25, 100, 400 and 1600 robots.
SQUARE = (25, 100, 400, 1600)
HEX_RINGS = (2, 5, 11, 23)
ORDER_LINE = 0.5


def breakdown(noise: np.ndarray, order: np.ndarray, level: float = ORDER_LINE) -> float:
    """The noise (log-interpolated) at which ``order`` first falls below ``level``;
    NaN if it never does, 0 if it starts below."""
    below = np.flatnonzero(order < level)
    if len(below) == 0:
        return float("nan")
    i = below[0]
    if i == 0:
        return 0.0
    x0, x1 = np.log(noise[i - 1]), np.log(noise[i])
    y0, y1 = order[i - 1], order[i]
    return float(np.exp(x0 + (level - y0) * (x1 - x0) / (y1 - y0)))


def run(out: Path, where: Where, quick: bool = False) -> dict[str, Any]:
    base = scenario.load("linear").with_overrides({"duration": 20.0 if quick else 60.0})
    transient = 5.0 if quick else 20.0
    mc = 2 if quick else 4
    n_grid = 4 if quick else 9
    square = SQUARE[:2] if quick else SQUARE
    rings = HEX_RINGS[:2] if quick else HEX_RINGS

    grid_axes = [
        parse_axis(f"d_r=log:0.05:10:{n_grid}"),
        parse_axis(f"d_theta=log:0.01:10:{n_grid}"),
    ]
    grid = sweep_points(
        "noise_grid",
        base.with_robots(25 if quick else 100),
        ["d_r", "d_theta"],
        points(grid_axes),
        where,
        mc=mc,
        transient=transient,
    )
    lines: list[dict[str, Any]] = []
    rows_breakdown = []
    n_line = 5 if quick else 12
    for noise, spec in (("d_theta", f"log:0.01:10:{n_line}"), ("d_r", f"log:0.05:10:{n_line}")):
        values = parse_axis(f"{noise}={spec}").grid()
        for sheet, sizes in (("square", square), ("hex", rings)):
            for size in sizes:
                sc = (
                    base.with_robots(size)
                    if sheet == "square"
                    else base.with_overrides({"formation": "hex", "rings": size})
                )
                n = len(sc.nominal_positions())
                rows = sweep_points(
                    f"noise_{noise}_{sheet}_{n}",
                    sc,
                    [noise],
                    values[:, None],
                    where,
                    mc=mc,
                    transient=transient,
                )
                order = np.array([r["psi_heading_mean"] for r in rows])
                for r in rows:
                    lines.append(
                        {
                            "noise": noise,
                            "sheet": sheet,
                            "robots": n,
                            "value": r[noise],
                            "psi_heading": r["psi_heading_mean"],
                            "psi_heading_std": r["psi_heading_std"],
                        }
                    )
                rows_breakdown.append(
                    {
                        "noise": noise,
                        "sheet": sheet,
                        "robots": n,
                        "breakdown": breakdown(values, order),
                    }
                )
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "phase_grid.csv", grid)
    write_csv(out / "noise_lines.csv", lines)
    write_csv(out / "breakdown.csv", rows_breakdown)
    result = {
        "order_line": ORDER_LINE,
        "defaults": {"d_r": base.d_r, "d_theta": base.d_theta},
        "breakdown": rows_breakdown,
        "ordered_at_defaults": bool(
            min(r["psi_heading"] for r in lines if r["robots"] <= 100 and r["value"] <= 0.02)
            > ORDER_LINE
        ),
    }
    (out / "noise.json").write_text(json.dumps(result, indent=1))
    _figure(out / "noise_phase.png", grid, lines, base)
    return result


def _figure(path: Path, grid: list[dict], lines: list[dict], base) -> None:
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4))
    d_r = np.unique([r["d_r"] for r in grid])
    d_t = np.unique([r["d_theta"] for r in grid])
    image = np.full((len(d_t), len(d_r)), np.nan)
    for r in grid:
        image[np.searchsorted(d_t, r["d_theta"]), np.searchsorted(d_r, r["d_r"])] = r[
            "psi_heading_mean"
        ]
    mesh = axes[0].pcolormesh(_edges(d_r), _edges(d_t), image, vmin=0, vmax=1, cmap="viridis")
    axes[0].contour(d_r, d_t, image, levels=[ORDER_LINE], colors="w")
    axes[0].plot(base.d_r, base.d_theta, "r*", ms=12, label="defaults")
    axes[0].set(
        xscale="log",
        yscale="log",
        xlabel="sensing noise D_r",
        ylabel="turning noise D_θ",
        title="heading order ψ̄_heading, 100 robots (square)",
    )
    axes[0].legend(fontsize=8)
    fig.colorbar(mesh, ax=axes[0])
    for ax, noise, label in (
        (axes[1], "d_theta", "turning noise D_θ"),
        (axes[2], "d_r", "sensing noise D_r"),
    ):
        for sheet, style in (("square", "-"), ("hex", "--")):
            for n in sorted({r["robots"] for r in lines if r["sheet"] == sheet}):
                rows = [
                    r for r in lines if (r["noise"], r["sheet"], r["robots"]) == (noise, sheet, n)
                ]
                ax.semilogx(
                    [r["value"] for r in rows],
                    [r["psi_heading"] for r in rows],
                    style,
                    marker="o",
                    ms=3,
                    label=f"{sheet} N={n}",
                )
        ax.axhline(ORDER_LINE, color="grey", lw=0.8)
        ax.set(
            xlabel=label,
            ylabel="ψ̄_heading",
            ylim=(0, 1.02),
            title=f"order against {label} (other noise at default)",
        )
        ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _edges(c: np.ndarray) -> np.ndarray:
    logc = np.log(c)
    mids = (logc[:-1] + logc[1:]) / 2
    return np.exp(np.concatenate([[2 * logc[0] - mids[0]], mids, [2 * logc[-1] - mids[-1]]]))
