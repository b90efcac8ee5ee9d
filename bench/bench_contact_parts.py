"""Where the offline kernel's time goes with contacts and the IR rays on, part by part.

Records runs of the combined scenario with contacts and the IR avoidance term on (``w_o`` =
4 N, as ``bench_sim.py``'s ``contacts+IR`` row), then replays their states through each
part the kernel adds to a step, single-threaded, in the order and with the lists the
kernel uses (:func:`aes_ros.kernel.advance`):

- ``list``: keeping the candidate pairs (:func:`aes_ros.pair_list.kept_pairs`: the test of
  every body's displacement, the rigid follow, the grid made again now and then);
- ``sweep``: one pass of the contact rule over the list (no overlaps in these runs: the
  avoidance term keeps the bodies apart, so the kernel sweeps once a step), which also
  picks the pairs within the rays' reach;
- ``rays``: every robot's five rays against the walls, obstacles and the bodies of those
  pairs (:func:`aes_ros.ir.cast_rays_listed`).

Each part's time is that of a loop over the recorded states (their body centres computed
from the recorded poses) with the part, less that of the same loop without it (best of
``--trials``). The script also times the whole step, with everything off and with
contacts and IR on (``simulate``, the noise included, as ``bench_sim.py`` does), and
prints µs per step of N robots and the same in units of the off step; ``rest`` is the
on step less the off step and the three parts: the centres and cosines computed in a
loop of their own after the step (inside it, they overlap the force's arithmetic), the
avoidance term and the kernel's bookkeeping. Last line: ``RESULT off_us=… on=… list=…
sweep=… rays=… rest=…`` (in units of the off step).

Usage: ``python bench/bench_contact_parts.py [--runs 4] [--trials 5]``
"""

from __future__ import annotations

import argparse
import math
import time

import numba
import numpy as np
from numba import njit

from aes_ros import scenario, simulator
from aes_ros.avoidance import AVOIDANCE_RANGE, IR_ANGLES
from aes_ros.contacts import NO_BOXES, NO_CIRCLES, NO_WALLS, _separate_listed
from aes_ros.ir import cast_rays_listed, mounting
from aes_ros.kernel_bodies import list_cutoffs, ray_reach
from aes_ros.numba_cache import depend_on
from aes_ros.pair_list import kept_pairs

#: Bodies and the IR avoidance term as bench_sim.py's contacts+IR row has them.
IR_ON = {"contacts": True, "w_o": 4.0}


@njit(cache=True)
def replay(
    positions: np.ndarray,
    headings: np.ndarray,
    radius: float,
    axle_offset: float,
    near: float,
    skin: float,
    parts: int,
) -> float:
    """Go through the recorded states (B, T, N, 2) [m] and (B, T, N) [rad] as the kernel
    does, with parts 0 (the centres only), 1 (+ list), 2 (+ sweep) or 3 (+ rays); returns a
    checksum so that nothing is left out by the compiler."""
    B, T, n = headings.shape
    mount = mounting(IR_ANGLES)
    reach = ray_reach(radius)
    out = np.empty((n, 5))
    scratch = np.empty((n, 2))
    total = 0.0
    for b in range(B):
        pos = np.empty((n, 2))
        cos_h, sin_h = np.empty(n), np.empty(n)
        cx, cy = np.empty(n), np.empty(n)
        ref_x, ref_y = np.full(n, np.inf), np.full(n, np.inf)
        pairs = np.empty((0, 2), np.int64)
        within = np.empty((0, 2), np.int64)
        for t in range(T):
            for i in range(n):
                pos[i, 0] = positions[b, t, i, 0]
                pos[i, 1] = positions[b, t, i, 1]
                cos_h[i] = math.cos(headings[b, t, i])
                sin_h[i] = math.sin(headings[b, t, i])
                cx[i] = pos[i, 0] + axle_offset * cos_h[i]
                cy[i] = pos[i, 1] + axle_offset * sin_h[i]
            total += cx[t % n]
            if parts >= 1:
                pairs = kept_pairs(cx, cy, pairs, ref_x, ref_y, near, skin)
                total += pairs.shape[0]
            if within.shape[0] < pairs.shape[0]:
                within = np.empty((2 * pairs.shape[0], 2), np.int64)
            kept = pairs.shape[0]
            if parts >= 2:
                found, best, kept = _separate_listed(pos, cx, cy, radius, pairs, reach, within)
                total += found + best
            if parts >= 3:
                cast_rays_listed(
                    pos, cos_h, sin_h, radius, axle_offset, mount, AVOIDANCE_RANGE, NO_WALLS,
                    NO_CIRCLES, NO_BOXES, within[:kept], out, scratch,
                )  # fmt: skip
                total += out[t % n, 0]
    return total


# an edit of the parts replayed must compile the replay again (aes_ros.numba_cache)
depend_on(replay, "aes_ros.contacts", "aes_ros.ir", "aes_ros.pair_list")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=4, help="runs recorded (default 4)")
    parser.add_argument("--trials", type=int, default=5, help="timings, best kept (default 5)")
    args = parser.parse_args()
    for name in ("runs", "trials"):
        if getattr(args, name) < 1:
            parser.error(f"--{name}: need >= 1")
    numba.set_num_threads(1)
    off = scenario.load("combined", {"duration": 30.0, "contacts": False})
    on = off.with_overrides(IR_ON)
    seeds = list(range(args.runs))
    res = simulator.simulate(on, seeds, record=True)
    positions = np.ascontiguousarray(res.positions[:, :-1])
    headings = np.ascontiguousarray(res.headings[:, :-1])
    n_states = headings.shape[0] * headings.shape[1]
    body = simulator.BODY
    radius, axle_offset = body.body_radius, body.axle_offset
    near, skin = list_cutoffs(radius, True)

    simulator.simulate(off, seeds, record=False)  # compile / load the caches
    simulator.simulate(on, seeds, record=False)
    for parts in range(4):
        replay(positions, headings, radius, axle_offset, near, skin, parts)
    best = {name: math.inf for name in ("off", "on", 0, 1, 2, 3)}
    for _ in range(args.trials):
        for name, sc in (("off", off), ("on", on)):
            start = time.perf_counter()
            simulator.simulate(sc, seeds, record=False)
            best[name] = min(best[name], (time.perf_counter() - start) / (len(seeds) * sc.n_steps))
        for parts in range(4):
            start = time.perf_counter()
            replay(positions, headings, radius, axle_offset, near, skin, parts)
            best[parts] = min(best[parts], (time.perf_counter() - start) / n_states)
    off_us, on_us = best["off"] * 1e6, best["on"] * 1e6
    cost = {
        "list": (best[1] - best[0]) * 1e6,
        "sweep": (best[2] - best[1]) * 1e6,
        "rays": (best[3] - best[2]) * 1e6,
    }
    cost["rest"] = on_us - off_us - sum(cost.values())
    n = headings.shape[2]
    print(f"combined scenario, {n} robots, contacts and IR on (w_o = 4 N), one thread")
    print(f"{'part':<10}{'us/step':>10}{'x off step':>12}")
    print(f"{'off step':<10}{off_us:>10.2f}{1.0:>12.2f}")
    print(f"{'on step':<10}{on_us:>10.2f}{on_us / off_us:>12.2f}")
    for name, us in cost.items():
        print(f"{name:<10}{us:>10.2f}{us / off_us:>12.2f}")
    print(
        f"RESULT off_us={off_us:.2f} on={on_us / off_us:.2f} "
        + " ".join(f"{name}={us / off_us:.2f}" for name, us in cost.items())
    )


if __name__ == "__main__":
    main()
