"""The README's clutter picture: the ``cluttered`` sheet crossing its two posts, offline,
with the IR obstacle avoidance on (w_o = 4) and off (w_o = 0), the same seed.

    .venv/bin/python scripts/clutter_picture.py --out docs/clutter    # DIR/clutter.png

Each robot's path, its body (Ø 8 cm) at 0, 10, 20 and 30 s, the posts, and the closest
any body came to a post.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import PatchCollection
from matplotlib.patches import Circle

from aes_ros import scenario
from aes_ros.obstacles import contact_arrays
from aes_ros.simulator import BODY, simulate

SNAPSHOTS = (0.0, 10.0, 20.0, 30.0)  # [s]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out", type=Path, default=Path("out/clutter"), metavar="DIR",
        help="the directory this command writes clutter.png to (default out/clutter; "
        "the README's: docs/clutter)",
    )  # fmt: skip
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="the run's seed")
    args = parser.parse_args()
    base = scenario.load("cluttered")
    _, circles, _ = contact_arrays(base.values)
    fig, axes = plt.subplots(1, 2, figsize=(12, 3.3), sharey=True)
    for ax, w_o in zip(axes, (base.values["w_o"], 0.0), strict=True):
        result = simulate(base.with_overrides({"w_o": w_o}), args.seed)
        pos, head = result.positions[0], result.headings[0]
        centres = pos + BODY.axle_offset * np.stack([np.cos(head), np.sin(head)], axis=-1)
        gaps = np.linalg.norm(centres[:, :, None] - circles[:, :2], axis=-1) - circles[:, 2]
        closest_mm = 1000 * (gaps.min() - BODY.body_radius)
        ax.plot(pos[:, :, 0], pos[:, :, 1], lw=0.6, color="tab:blue", alpha=0.6)
        for t in SNAPSHOTS:
            i = round(t / base.dt)
            bodies = [Circle(c, BODY.body_radius) for c in centres[i]]
            ax.add_collection(
                PatchCollection(bodies, facecolor="none", edgecolor="tab:blue", lw=0.8)
            )
            x, y = centres[i].max(axis=0)
            ax.annotate(f"{t:g} s", (x, y + 0.06), fontsize=8, ha="right")
        posts = [Circle(c[:2], c[2]) for c in circles]
        ax.add_collection(PatchCollection(posts, facecolor="dimgrey", edgecolor="black"))
        ax.set_aspect("equal")
        ax.set(
            xlim=(-3.0, 0.4),
            ylim=(-0.65, 0.65),
            xlabel="x [m]",
            title=f"w_o = {w_o:g}: closest body to a post {max(closest_mm, 0.0):.0f} mm",
        )
    axes[0].set_ylabel("y [m]")
    fig.suptitle(
        f"cluttered: 4 × 4 sheet driven west past two posts, contacts on, seed {args.seed}",
        fontsize=10,
    )
    fig.tight_layout()
    args.out.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out / "clutter.png", dpi=80, bbox_inches="tight")
    plt.close(fig)
    print(f"clutter picture: {args.out / 'clutter.png'}")


if __name__ == "__main__":
    main()
