"""The poses the robots see when the launch models perception error (``--perception``).

The bridge publishes the world's exact poses on ``/sim/ground_truth/poses`` and, on
``/swarm/poses``, the perceived frame of :class:`aes_ros.perception.PerceptionStream`:
the same model as the offline simulator's (noise, delay, camera rate, misses), fed the
true state once per control step. The frame is keyed by the world's step: a state
published again (lockstep re-publishing, a resumed bridge waiting for its robots)
shows the same frame, and the stream advances only when the world steps. The draws
are those of run ``seed`` of the offline simulator (the same generators), so the two
agree in distribution (and step for step when the world moves as the offline model
does). The stamp stays the step's time: the robots answer that step; what they see
in it is as old as the delay.
"""

from __future__ import annotations

import numpy as np

from aes_ros.perception import PerceptionSettings, PerceptionStream


class PerceivedPoses:
    """The perceived frame for each world step (``settings`` of a scenario, N robots,
    control step ``dt`` [s], run ``seed``)."""

    def __init__(self, settings: PerceptionSettings, n_robots: int, dt: float, seed: int) -> None:
        self.stream = PerceptionStream(settings, n_robots, dt, seed)
        self._first: int | None = None
        self._step = -1
        self._frame: tuple[np.ndarray, np.ndarray] | None = None

    def frame(
        self, world_step: int, positions: np.ndarray, headings: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Perceived positions (N, 2) [m] and headings (N,) [rad] at ``world_step``, given
        the true state then; the stream's step 0 is the first world step seen (a
        resumed bridge starts its perception over)."""
        if self._first is None:
            self._first = world_step
        step = world_step - self._first
        if step != self._step or self._frame is None:
            # a world reset or a skipped step cannot be replayed: catch up with this state
            while self._step < step - 1:
                self.stream.see(positions, headings, self._step + 1)
                self._step += 1
            if step > self._step:
                self._frame = self.stream.see(positions, headings, step)
                self._step = step
        return self._frame
