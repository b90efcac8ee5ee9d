"""A run's samples read back from ``trajectory.h5`` (the layout in
:mod:`aes_ros.trajectory_file`): whole, a slice, every k-th sample or chosen samples, of
a run still going or cut short too (its complete samples)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aes_ros.trajectory_file import FILE_NAME, open_trajectory

#: The trajectory's file name in a run directory.
TRAJECTORY_FILE = FILE_NAME


@dataclass(frozen=True)
class Trajectory:
    """A run's samples: times (T,) [s], positions (B, T, N, 2) [m], headings (B, T, N) [rad]."""

    times: np.ndarray
    positions: np.ndarray
    headings: np.ndarray


def load_trajectory(
    path: Path, every: int = 1, *, start: int = 0, stop: int | None = None
) -> Trajectory:
    """Read ``trajectory.h5`` (the file, or a run directory holding it): samples
    ``start``, ``start + every``, … before ``stop`` (default: all of them).

    Reads what a run still going or cut short has on disk (its complete samples), and
    only the samples asked for: ``every=k`` of a long run costs 1/k of its memory.
    """
    if every < 1:
        raise ValueError(f"every={every}: need an integer >= 1")
    with open_trajectory(path) as traj:
        return Trajectory(*traj.read(slice(start, stop, every)))


def trajectory_samples(path: Path, indices: Iterable[int]) -> Trajectory:
    """The samples at ``indices`` (any order, repeats allowed; negative counts from
    the end) of ``trajectory.h5`` (the file or a run directory), in that order."""
    with open_trajectory(path) as traj:
        wanted = np.asarray(list(indices), dtype=np.int64)
        wanted = np.where(wanted < 0, wanted + traj.n_samples, wanted)
        if wanted.size and (wanted.min() < 0 or wanted.max() >= traj.n_samples):
            raise IndexError(f"sample indices out of [0, {traj.n_samples})")
        unique, order = np.unique(wanted, return_inverse=True)
        times, positions, headings = traj.read(unique)
    return Trajectory(times[order], positions[:, order], headings[:, order])
