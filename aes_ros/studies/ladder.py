"""The reality-gap ladder: the same swarm, one rung of realism at a time.

The paper's three setups (linear, rotation, combined; 30 s) with the paper's and the
TCACS gains, :data:`ROBOTS` robots, several seeds, on six rungs:

1. ``offline``: the offline simulator, ideal sensing, commands clipped to the Mona's
   limits as the robots clip them (the simulator's default is unclipped);
2. ``offline+perception``: the offline simulator with the perception model
   (:mod:`aes_ros.perception`) set to what the camera tracker measured
   (:data:`TRACKER_FIT`);
3. ``kinematic``: the ROS system on pybullet, bodies following ``cmd_vel`` exactly
   (lockstep, as fast as possible);
4. ``dynamic``: the same with wheel motors and collisions;
5. ``dynamic-rt``: the same in real time (no lockstep: the bridge steps on the wall
   clock and a command that comes late acts a step late), the stepping of the next rung;
6. ``camera``: dynamic in real time, the robots reading the simulated overhead camera
   through the ArUco tracker (real time: the tracker's latency is wall time).

Each run gives ψ̄ (E8) and ψ̄_heading (E7) over t ≥ :data:`TRANSIENT`, F̄/N (E9), the
cost J with the paper's weights (E10; a ROS run's per-sample mean times the setup's
step count, so that runs sampled differently compare), the centroid's speed and its
heading error against the desired direction over the same span (none for the rotation
setup, which has no drive). The ROS rungs share one arena (:data:`ARENA`, also what
the camera sees) large enough that the arena keeper never acts.

Outputs (``--out``): ``ladder.csv`` (every run), ``ladder_summary.csv`` (mean and
standard deviation per rung, setup and gains), ``ladder.png`` and ``ladder.json``
(which rung changes ψ̄ most, and whether the TCACS gains keep their lower J on every
rung). The ROS runs' directories are kept in ``--work`` (a finished run is not run
again).
"""

from __future__ import annotations

import csv
import itertools
import json
import math
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from aes_ros import scenario as scenario_mod
from aes_ros import simulator
from aes_ros.optim.cost import default_weights
from aes_ros.studies.common import GainSet, Where, study_gain_sets, write_csv

SETUPS = ("linear", "rotation", "combined")
#: The swarm's size on every rung: the camera rung runs in real time on two cores.
ROBOTS = 25
#: ψ̄, ψ̄_heading, F̄/N, the centroid's speed and heading are averaged over t ≥ this [s].
TRANSIENT = 10.0
#: The perception model fitted to the camera tracker at 25 robots
#: (docs/real_robots.md, ``bench/bench_tracking.py``): 0.055 mm RMS of position, 33 ms
#: from exposure to the robots (median), 20 frames a second, 99.2 % detected a frame.
TRACKER_FIT = {
    "perception_sigma": 0.000055,
    "perception_delay": 0.033,
    "perception_rate": 20.0,
    "perception_miss": 0.008,
}
#: The ROS rungs' arena [m] (x_min, x_max, y_min, y_max): the 25-robot sheet starts
#: within ±0.4 m and drives at most 1.5 m west in 30 s; 4:3 like the camera's picture.
ARENA = (-2.6, 1.0, -1.35, 1.35)
#: The camera rung's resolution: 1.8 mm a pixel over ARENA.
CAMERA = "2048x1536"


@dataclass(frozen=True)
class Rung:
    key: str
    label: str
    launch: tuple[str, ...] = ()  # empty: offline
    perception: bool = False


RUNGS = (
    Rung("offline", "offline, ideal"),
    Rung("offline+perception", "offline, tracker's error", perception=True),
    Rung("kinematic", "pybullet kinematic", ("--mode", "kinematic", "--lockstep",
                                             "--real-time-factor", "0")),
    Rung("dynamic", "pybullet dynamic", ("--mode", "dynamic", "--lockstep",
                                         "--real-time-factor", "0")),
    Rung("dynamic-rt", "dynamic, real time", ("--mode", "dynamic")),
    Rung("camera", "dynamic + camera + tracker", ("--mode", "dynamic", "--tracking", "camera",
                                                  "--camera-size", CAMERA)),
)  # fmt: skip


def run_metrics(
    t: np.ndarray,
    psi: np.ndarray,
    order: np.ndarray,
    force: np.ndarray,
    centroid: np.ndarray,
    n_robots: int,
    n_steps: int,
    direction: tuple[float, float] | None,
) -> dict[str, float]:
    """One run's figures from its samples: times ``t`` (T,) [s from the run's start],
    ψ (E8), ψ_heading (E7) and F (E9), each (T,), ``centroid`` (T, 2) [m]. ``n_steps``:
    the setup's steps (J is the per-sample mean times n_steps + 1); ``direction``: the
    desired direction (None: no drive, no heading error)."""
    after = t >= TRANSIENT - 1e-9
    w1, w2 = default_weights(n_robots)
    span = float(t[after][-1] - t[after][0])
    moved = centroid[after][-1] - centroid[after][0]
    speed = float(np.hypot(*moved) / span) if span > 0 else math.nan
    error = math.nan
    if direction is not None and speed > 1e-3:
        angle = math.atan2(moved[1], moved[0]) - math.atan2(direction[1], direction[0])
        error = abs(math.degrees((angle + math.pi) % (2 * math.pi) - math.pi))
    return {
        "psi": float(psi[after].mean()),
        "psi_heading": float(order[after].mean()),
        "force_per_robot": float(force[after].mean() / n_robots),
        "J": float((n_steps + 1) * np.mean(w1 * force + w2 * psi)),
        "speed": speed,
        "heading_error_deg": error,
    }


def _direction(sc: scenario_mod.Scenario) -> tuple[float, float] | None:
    d = sc.command.direction
    return (float(d[0]), float(d[1])) if sc.w_l > 0 and np.hypot(*d) > 0 else None


def offline_rows(
    sc: scenario_mod.Scenario, seeds: list[int], perception: dict[str, float] | None
) -> list[dict[str, float]]:
    """The offline simulator's runs of ``sc`` (one per seed)."""
    if perception:
        sc = sc.with_overrides(perception, source="ladder")
    result = simulator.simulate(sc, seeds, record=False)
    n = len(sc.nominal_positions())
    m = result.metrics
    return [
        run_metrics(result.times, m[b, :, 0], m[b, :, 1], m[b, :, 2], m[b, :, 3:5], n,
                    sc.n_steps, _direction(sc))
        for b in range(len(seeds))
    ]  # fmt: skip


def read_run(directory: Path, sc: scenario_mod.Scenario) -> dict[str, float]:
    """The figures of a ROS run from its ``metrics.csv`` (times from its first row)."""
    with (directory / "metrics.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    col = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    t = col["t"] - col["t"][0]
    keep = t <= sc.duration + 1e-9
    centroid = np.stack([col["centroid_x"], col["centroid_y"]], axis=-1)[keep]
    return run_metrics(
        t[keep], col["alignment"][keep], col["heading_order"][keep], col["total_force"][keep],
        centroid, len(sc.nominal_positions()), sc.n_steps, _direction(sc),
    )  # fmt: skip


def launch_run(
    rung: Rung, setup: str, gains: GainSet, seed: int, directory: Path, domain: int
) -> Path:
    """Run one ROS rung (``aes-swarm launch``) into ``directory`` unless a finished run
    is there already (an unfinished one, cut short, is replaced: ``--overwrite``); its
    log in ``directory/ladder.log``."""
    if (directory / "done").exists():
        return directory
    directory.mkdir(parents=True, exist_ok=True)
    cmd = [
        str(Path(sys.executable).parent / "aes-swarm"), "launch", "--setup", setup,
        "--robots", str(ROBOTS), "--seed", str(seed), "--on-failure", "stop",
        "--set", f"alpha={gains.alpha}", "--set", f"beta={gains.beta}", "--set", f"k={gains.k}",
        "--set", "arena=" + ",".join(f"{v:g}" for v in ARENA),
        *rung.launch, "--out", str(directory), "--overwrite",
    ]  # fmt: skip
    env = {**os.environ, "ROS_DOMAIN_ID": str(domain)}
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    with (directory / "ladder.log").open("w") as log:
        code = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, env=env, timeout=900)
    if code.returncode != 0:
        tail = (directory / "ladder.log").read_text()[-2000:]
        raise RuntimeError(f"ladder: {rung.key} {setup} seed {seed} failed:\n{tail}")
    (directory / "done").write_text(" ".join(cmd) + "\n")
    return directory


def run(out: Path, where: Where, quick: bool = False) -> dict[str, Any]:
    sets = study_gain_sets()
    chosen = [
        next(g for g in sets if g.label.startswith("paper")),
        next(g for g in sets if g.label.startswith("TCACS, weights (1/N, −1)")),
    ]
    seeds = [0] if quick else [0, 1, 2]
    offline_seeds = list(range(2 if quick else 10))
    setups = SETUPS[2:] if quick else SETUPS
    rungs = [r for r in RUNGS if not quick or r.key != "camera"]
    domain = 150 + os.getpid() % 50
    rows: list[dict[str, Any]] = []
    total = len(rungs) * len(setups) * len(chosen)
    done = 0
    for rung in rungs:
        for setup in setups:
            for g in chosen:
                # clip: the robots' limits, which the ROS rungs always apply
                gains = {"alpha": g.alpha, "beta": g.beta, "k": g.k, "clip": True}
                sc = scenario_mod.load(setup).with_robots(ROBOTS).with_overrides(gains, "ladder")
                if quick:
                    sc = sc.with_overrides({"duration": 15.0}, source="ladder")
                if not rung.launch:
                    fit = TRACKER_FIT if rung.perception else None
                    found = list(
                        zip(offline_seeds, offline_rows(sc, offline_seeds, fit), strict=True)
                    )
                else:
                    found = []
                    for s in seeds:
                        d = where.work / rung.key / setup / short_label(g) / f"seed{s}"
                        launch_run(rung, setup, g, s, d, domain)
                        found.append((s, read_run(d, sc)))
                for s, r in found:
                    rows.append({"rung": rung.key, "setup": setup, "gains": g.label,
                                 "seed": s, **r})  # fmt: skip
                done += 1
                if where.progress:
                    print(f"ladder: {done}/{total} {rung.key} {setup} {g.label}", flush=True)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "ladder.csv", rows)
    summary = summarize(rows)
    write_csv(out / "ladder_summary.csv", summary)
    result = {
        "robots": ROBOTS,
        "transient_s": TRANSIENT,
        "ros_seeds": seeds,
        "offline_seeds": offline_seeds,
        "tracker_fit": TRACKER_FIT,
        **verdict(summary, [r.key for r in rungs], setups, chosen),
    }
    (out / "ladder.json").write_text(json.dumps(result, indent=1))
    _figure(out / "ladder.png", summary, rungs, setups, chosen)
    return result


def short_label(g: GainSet) -> str:
    """``paper`` or ``TCACS``: a gain set's name without its values or weights."""
    return g.label.split(",")[0].split(" (")[0]


FIGURES = ("psi", "psi_heading", "force_per_robot", "J", "speed", "heading_error_deg")


def summarize(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Mean and standard deviation of every figure per (rung, setup, gains)."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["rung"], r["setup"], r["gains"]), []).append(r)
    out = []
    for (rung, setup, gains), runs in groups.items():
        row: dict[str, Any] = {"rung": rung, "setup": setup, "gains": gains, "runs": len(runs)}
        for f in FIGURES:
            values = np.array([r[f] for r in runs], dtype=float)
            row[f"{f}_mean"] = float(np.nanmean(values)) if np.isfinite(values).any() else math.nan
            row[f"{f}_std"] = float(np.nanstd(values)) if np.isfinite(values).any() else math.nan
        out.append(row)
    return out


def verdict(
    summary: list[dict[str, Any]], rungs: list[str], setups: tuple[str, ...], chosen: list[GainSet]
) -> dict[str, Any]:
    """Which step up the ladder changes ψ̄ most (mean |Δψ̄| over setups and gains), and
    on which rungs the TCACS gains keep a lower J than the paper's in every setup."""
    cell = {(s["rung"], s["setup"], s["gains"]): s for s in summary}
    steps = {}
    for lower, upper in itertools.pairwise(rungs):
        deltas = [
            abs(cell[(upper, s, g.label)]["psi_mean"] - cell[(lower, s, g.label)]["psi_mean"])
            for s in setups for g in chosen
        ]  # fmt: skip
        steps[f"{lower} -> {upper}"] = float(np.mean(deltas))
    paper, tcacs = chosen[0].label, chosen[1].label
    keeps = {
        rung: {s: cell[(rung, s, tcacs)]["J_mean"] < cell[(rung, s, paper)]["J_mean"]
               for s in setups}
        for rung in rungs
    }  # fmt: skip
    return {
        "mean_abs_psi_change": steps,
        "largest_change": max(steps, key=steps.get) if steps else None,
        "tcacs_lower_J": keeps,
        "tcacs_keeps_advantage_on_every_rung": all(all(v.values()) for v in keeps.values()),
    }


def _figure(
    path: Path, summary: list[dict], rungs: list[Rung], setups: tuple[str, ...],
    chosen: list[GainSet],
) -> None:  # fmt: skip
    panels = (("psi", "ψ̄ (E8)"), ("psi_heading", "ψ̄_heading (E7)"), ("J", "J (E10)"))
    fig, axes = plt.subplots(len(panels), len(setups), figsize=(4.6 * len(setups), 8.5),
                             squeeze=False)  # fmt: skip
    x = np.arange(len(rungs))
    for col, setup in enumerate(setups):
        for row, (f, label) in enumerate(panels):
            ax = axes[row, col]
            for k, (g, color) in enumerate(zip(chosen, ("C0", "C3"), strict=False)):
                cells = [next(s for s in summary
                              if (s["rung"], s["setup"], s["gains"]) == (r.key, setup, g.label))
                         for r in rungs]  # fmt: skip
                ax.errorbar(x + (k - 0.5) * 0.15, [c[f"{f}_mean"] for c in cells],
                            yerr=[c[f"{f}_std"] for c in cells], color=color, marker="o", ms=4,
                            capsize=2, lw=1, label=short_label(g))  # fmt: skip
            ax.set_xticks(x, [r.label for r in rungs], rotation=30, ha="right", fontsize=7)
            ax.set(ylabel=label)
            if row == 0:
                ax.set_title(f"{setup}, {ROBOTS} robots")
            if row == 0 and col == 0:
                ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
