"""The swarm in clutter: alignment, collisions and progress against post density and ``w_o``.

The packaged ``cluttered`` scenario (a 4 x 4 sheet driven west, contacts on) with 0, 2, 4
or 8 round posts (r = 5 cm) scattered across its path in a band 0.7–1.3 m west of the
start, and the IR obstacle-avoidance weight ``w_o`` (docs/model.md, "Obstacle
avoidance") from 0 (off) to 8, offline with the numba kernel, 60 s per run. Monte-Carlo
run r (0-based) uses seed S + r for the start and the noise, and ``(S + r, posts)`` for
where the posts stand, so every ``w_o`` meets the same posts (common random numbers).

Per run: ψ̄, the alignment (E8) averaged after a 5 s transient; collisions per
robot-minute, a collision being the start of a touch (centre distances within the contact
tolerance) between a robot and a post, and separately between two robots; progress, the
centroid's displacement along the desired direction [m]; and the fraction of robots past
the band of posts at the end.

Outputs (``--out``): ``clutter.png``, ``clutter_runs.csv`` (one row per run),
``clutter.csv`` (mean and standard deviation per (posts, w_o)) and ``clutter.json``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from tqdm import tqdm

from aes_ros import scenario
from aes_ros.contact_measures import TOUCH_TOLERANCE
from aes_ros.simulator import BODY, SimResult, simulate
from aes_ros.studies.common import Where, write_csv

POSTS = (0, 2, 4, 8)
W_O = (0.0, 1.0, 2.0, 4.0, 8.0)
POST_RADIUS = 0.05  # [m]
#: The band the posts stand in, west of the sheet's start: x, y ranges [m].
BAND_X = (-1.3, -0.7)
BAND_Y = (-0.45, 0.45)
#: Closest centre distance of two posts [m].
POST_SPACING = 0.16
DURATION = 60.0  # [s]
TRANSIENT = 5.0  # [s]
RUNS = 20


def place_posts(n: int, seed: int) -> np.ndarray:
    """``n`` posts (n, 3) as (x, y, r) [m] in the band, at least POST_SPACING apart,
    drawn from ``seed`` (the same seed and n give the same posts)."""
    rng = np.random.default_rng([seed, n])
    posts: list[tuple[float, float]] = []
    for _ in range(100_000):
        if len(posts) == n:
            break
        x, y = rng.uniform(*BAND_X), rng.uniform(*BAND_Y)
        if all(np.hypot(x - px, y - py) >= POST_SPACING for px, py in posts):
            posts.append((x, y))
    else:
        raise ValueError(f"posts: {n} do not fit {POST_SPACING} m apart in the band")
    return np.array([(x, y, POST_RADIUS) for x, y in posts]).reshape(n, 3)


def onsets(touching: np.ndarray) -> np.ndarray:
    """Starts of touches along the time axis 1 of ``touching`` (B, T+1, ...): summed over
    everything but the run, (B,); a touch at t = 0 counts as one."""
    t = touching.astype(np.int8)
    starts = np.diff(t, axis=1, prepend=0) == 1
    return starts.reshape(len(t), -1).sum(axis=1)


def run_metrics(result: SimResult, posts: np.ndarray, direction: np.ndarray) -> dict[str, Any]:
    """ψ̄, collisions per robot-minute (posts, robots), progress [m] and the fraction
    past the band of one simulated batch, each (B,)."""
    pos, head = result.positions, result.headings
    centres = pos + BODY.axle_offset * np.stack([np.cos(head), np.sin(head)], axis=-1)
    B, _, N, _ = centres.shape
    robot_minutes = N * result.times[-1] / 60.0
    reach = BODY.body_radius + TOUCH_TOLERANCE
    if len(posts):
        d = np.linalg.norm(centres[..., None, :] - posts[:, :2], axis=-1)  # (B, T+1, N, M)
        post_hits = onsets(d <= posts[:, 2] + reach)
    else:
        post_hits = np.zeros(B)
    gaps = np.linalg.norm(centres[..., :, None, :] - centres[..., None, :, :], axis=-1)
    pairs = np.triu(gaps <= 2 * BODY.body_radius + TOUCH_TOLERANCE, k=1)
    robot_hits = onsets(pairs)
    alignment = result.metric("alignment")[:, result.times >= TRANSIENT]
    along = result.centroid @ direction
    band_far = -BAND_X[0] if direction[0] < 0 else BAND_X[1]
    past = (centres[:, -1] @ direction > band_far + POST_RADIUS + BODY.body_radius).mean(axis=1)
    return {
        "psi": alignment.mean(axis=1),
        "post_collisions_per_robot_min": post_hits / robot_minutes,
        "robot_collisions_per_robot_min": robot_hits / robot_minutes,
        "progress_m": along[:, -1] - along[:, 0],
        "past_fraction": past,
    }


def run(
    out: Path, where: Where, quick: bool = False, runs: int | None = None, seed: int = 0
) -> dict[str, Any]:
    base = scenario.load("cluttered").with_overrides({"duration": 30.0 if quick else DURATION})
    direction = np.asarray(base.direction, dtype=float)
    posts_axis = (0, 4) if quick else POSTS
    w_axis = (0.0, 4.0) if quick else W_O
    runs = runs if runs is not None else (2 if quick else RUNS)
    rows: list[dict[str, Any]] = []
    cells = [(n, w) for n in posts_axis for w in w_axis]
    bar = tqdm(total=len(cells) * runs, unit="run", disable=not where.progress, leave=False)
    for n, w_o in cells:
        for r in range(runs):
            posts = place_posts(n, seed + r)
            obstacles = [{"circle": [float(v) for v in p]} for p in posts]
            sc = base.with_overrides({"w_o": w_o, "obstacles": obstacles})
            m = run_metrics(simulate(sc, [seed + r]), posts, direction)
            rows.append(
                {"posts": n, "w_o": w_o, "seed": seed + r} | {k: float(v[0]) for k, v in m.items()}
            )
            bar.update(1)
    bar.close()
    summary = _summarize(rows, cells)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "clutter_runs.csv", rows)
    write_csv(out / "clutter.csv", summary)
    result = {
        "robots": len(base.nominal_positions()),
        "duration_s": base.duration,
        "runs": runs,
        "seed": seed,
        "post_radius_m": POST_RADIUS,
        "band_x_m": BAND_X,
        "band_y_m": BAND_Y,
        "cells": summary,
    }
    (out / "clutter.json").write_text(json.dumps(result, indent=1))
    _figure(out / "clutter.png", summary, runs, base.duration)
    return result


METRICS = (
    ("psi", "ψ̄ (alignment)"),
    ("post_collisions_per_robot_min", "robot–post collisions per robot-minute"),
    ("robot_collisions_per_robot_min", "robot–robot collisions per robot-minute"),
    ("progress_m", "progress along v_d [m]"),
)


def _summarize(rows: list[dict[str, Any]], cells: list[tuple[int, float]]) -> list[dict]:
    summary = []
    for n, w_o in cells:
        cell = [r for r in rows if (r["posts"], r["w_o"]) == (n, w_o)]
        line: dict[str, Any] = {"posts": n, "w_o": w_o, "runs": len(cell)}
        for key in (*(k for k, _ in METRICS), "past_fraction"):
            values = np.array([r[key] for r in cell])
            line[f"{key}_mean"] = float(values.mean())
            line[f"{key}_std"] = float(values.std(ddof=1)) if len(values) > 1 else 0.0
        summary.append(line)
    return summary


def _figure(path: Path, summary: list[dict], runs: int, duration: float) -> None:
    fig, axes = plt.subplots(1, 4, figsize=(16, 3.8))
    for ax, (key, label) in zip(axes, METRICS, strict=True):
        for w_o in sorted({s["w_o"] for s in summary}):
            line = [s for s in summary if s["w_o"] == w_o]
            ax.errorbar(
                [s["posts"] for s in line],
                [s[f"{key}_mean"] for s in line],
                yerr=[s[f"{key}_std"] for s in line],
                marker="o",
                ms=4,
                capsize=2,
                label=f"w_o = {w_o:g}",
            )
        ax.set(
            xlabel="posts across the path",
            ylabel=label,
            xticks=sorted({s["posts"] for s in summary}),
        )
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(
        f"4 x 4 sheet driven west through posts (r = {POST_RADIUS * 100:g} cm), "
        f"contacts on, {duration:g} s, mean ± sd of {runs} runs",
        fontsize=10,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
