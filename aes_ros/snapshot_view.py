"""What a run's figures draw, reduced while the run is read once: the snapshot panels
and the centroid's track (:func:`snapshot_view`), and how many samples a plot keeps
(:func:`plot_every`)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

#: At most this many samples on a plot's time axis (every k-th sample, and the last).
MAX_PLOT_SAMPLES = 2000


def plot_every(n_samples: int, limit: int = MAX_PLOT_SAMPLES) -> int:
    """The k of "every k-th sample" that keeps at most ``limit`` samples (plus the last)."""
    return max(1, math.ceil(n_samples / limit))


@dataclass(frozen=True)
class SnapshotView:
    """What ``snapshots.png`` draws of one run.

    times : (P,) [s], positions : (P, N, 2) [m], headings : (P, N) [rad] of the panels'
    samples (the first is the run's first sample); track_times : (M,) [s] and track :
    (M, 2) [m], the centroid at every k-th sample and at the panels' samples; lo, hi :
    (2,) [m], the corners of a box around every position of the run.
    """

    times: np.ndarray
    positions: np.ndarray
    headings: np.ndarray
    track_times: np.ndarray
    track: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


def snapshot_view(
    blocks: Iterable[tuple[int, np.ndarray, np.ndarray, np.ndarray]],
    n_samples: int,
    panels: int = 4,
    max_track: int = MAX_PLOT_SAMPLES,
) -> SnapshotView:
    """The :class:`SnapshotView` of a run read once, in order, a block at a time.

    blocks : (index of the block's first sample, times (k,) [s], positions (k, N, 2)
    [m], headings (k, N) [rad]), covering samples 0 … ``n_samples`` - 1 in order
    (:meth:`~aes_ros.trajectory_file.TrajectoryFile.blocks` of one run). The panels
    are ``panels`` samples evenly spaced from the first to the last; the centroid
    track keeps at most about ``max_track`` samples.
    """
    chosen = np.linspace(0, n_samples - 1, panels).round().astype(int)
    track_index = np.union1d(np.arange(0, n_samples, plot_every(n_samples, max_track)), chosen)
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    panel: dict[int, tuple[float, np.ndarray, np.ndarray]] = {}
    track_times, track = [], []
    for start, times, positions, headings in blocks:
        lo = np.minimum(lo, positions.min(axis=(0, 1)))
        hi = np.maximum(hi, positions.max(axis=(0, 1)))
        inside = track_index[(track_index >= start) & (track_index < start + len(times))] - start
        track_times.append(times[inside])
        track.append(positions[inside].mean(axis=-2))
        for k in chosen[(chosen >= start) & (chosen < start + len(times))]:
            # copies: a view would keep its whole block in memory
            panel[int(k)] = (
                times[k - start],
                positions[k - start].copy(),
                headings[k - start].copy(),
            )
    return SnapshotView(
        times=np.array([panel[k][0] for k in chosen]),
        positions=np.stack([panel[k][1] for k in chosen]),
        headings=np.stack([panel[k][2] for k in chosen]),
        track_times=np.concatenate(track_times),
        track=np.concatenate(track),
        lo=lo,
        hi=hi,
    )
