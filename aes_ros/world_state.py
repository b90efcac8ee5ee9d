"""A snapshot of the world: sim time, positions and headings (pure).

Written by the launcher from the last ``/swarm/poses`` it received when the
bridge dies, and read by the restarted bridge (its ``resume_from`` parameter), so
that the swarm carries on where it was instead of jumping back to t = 0.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class WorldState:
    """t : sim time [s]; positions : (N, 2) [m; odom]; headings : (N,) [rad]."""

    t: float
    positions: np.ndarray
    headings: np.ndarray

    def save(self, path: Path) -> Path:
        """Write to ``path`` (.npz) under a temporary name, then rename."""
        path = Path(path)
        temporary = path.with_name("." + path.name + ".tmp")
        with open(temporary, "wb") as fh:
            np.savez(fh, t=self.t, positions=self.positions, headings=self.headings)
        os.replace(temporary, path)
        return path

    @classmethod
    def load(cls, path: Path, n_robots: int | None = None) -> WorldState:
        """Read a state; ValueError if it is not one of ``n_robots`` finite poses."""
        try:
            with np.load(path) as data:
                state = cls(float(data["t"]), data["positions"], data["headings"])
        except (OSError, KeyError, ValueError) as exc:
            raise ValueError(f"resume_from: {path}: not a world state ({exc})") from None
        n = len(state.headings)
        if state.positions.shape != (n, 2) or (n_robots is not None and n != n_robots):
            raise ValueError(
                f"resume_from: {path}: {state.positions.shape} positions, {n} headings; "
                f"expected {n_robots} robots"
            )
        finite = np.isfinite(state.positions).all() and np.isfinite(state.headings).all()
        if not (finite and np.isfinite(state.t) and state.t >= 0.0):
            raise ValueError(f"resume_from: {path}: not finite, or a negative time")
        return state
