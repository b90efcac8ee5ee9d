"""Figures a person can read: time-lapse snapshots and metrics against time.

Shared by the offline simulator and the ROS launcher, so both runs look alike. They
take what they draw already reduced (a few samples, at most a few thousand points
a line), so a long run costs no more memory than a short one.
Uses the non-interactive Agg backend (headless machines, CI).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import LineCollection

from aes_ros.formations import spring_pairs

if TYPE_CHECKING:
    from aes_ros.snapshot_view import SnapshotView


def snapshots(path: Path, view: SnapshotView, neighbors: np.ndarray, title: str = "") -> None:
    """Time-lapse panels like one row of the paper's Fig. 3, one per sample of ``view``.

    view : the panels' samples, the centroid's track and the extent of the run
    (:func:`aes_ros.snapshot_view.snapshot_view`); neighbors : (N, K) sheet (springs drawn
    as lines). Robots are drawn as oriented arrows, the centroid path up to each
    panel's time as a line. All panels share one scale and extent so the motion is
    visible.
    """
    panels = len(view.times)
    pairs = spring_pairs(neighbors)
    lo, hi = view.lo - 0.15, view.hi + 0.15
    aspect = (hi[1] - lo[1]) / (hi[0] - lo[0])
    fig, axes = plt.subplots(
        1, panels, figsize=(4.2 * panels, 4.2 * aspect + 1.2), sharex=True, sharey=True
    )
    arrow = 0.4 * _typical_spacing(view.positions[0], pairs)
    for ax, t, p, h in zip(
        np.atleast_1d(axes), view.times, view.positions, view.headings, strict=True
    ):
        ax.add_collection(
            LineCollection(p[pairs], colors="0.7", linewidths=0.8, zorder=1)  # springs
        )
        track = view.track[view.track_times <= t]
        ax.plot(track[:, 0], track[:, 1], color="tab:red", lw=1.5, zorder=2)
        ax.quiver(
            p[:, 0], p[:, 1], np.cos(h) * arrow, np.sin(h) * arrow,
            angles="xy", scale_units="xy", scale=1.0, width=0.006, color="tab:blue", zorder=3,
        )  # fmt: skip
        ax.plot(*p.mean(axis=0), marker="x", color="tab:red", ms=8, mew=2, zorder=4)
        ax.set_title(f"t = {t:.1f} s")
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.grid(alpha=0.3)
    np.atleast_1d(axes)[0].set_ylabel("y [m]")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _typical_spacing(positions: np.ndarray, pairs: np.ndarray) -> float:
    if len(pairs) == 0:
        return 0.2
    return float(np.median(np.linalg.norm(positions[pairs[:, 0]] - positions[pairs[:, 1]], axis=1)))


def metrics_plot(
    path: Path,
    times: np.ndarray,
    alignment: np.ndarray,
    heading_order: np.ndarray,
    total_force: np.ndarray,
    title: str = "",
) -> None:
    """ψ (E8) and ψ_heading (E7) on top, F (E9) below, against time [s]."""
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    top.plot(times, alignment, label="force alignment ψ (E8)")
    top.plot(times, heading_order, label="heading order ψ_heading (E7)")
    top.set_ylim(0, 1.02)
    top.set_ylabel("order")
    top.legend(loc="lower right")
    top.grid(alpha=0.3)
    bottom.plot(times, total_force, color="tab:green")
    bottom.set_ylabel("total force F (E9)")
    bottom.set_xlabel("t [s]")
    bottom.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
