"""What the dashboard shows, from what the swarm publishes (pure: numpy, no ROS).

:class:`SwarmView` is fed the swarm's messages as arrays (poses, the swarm
command, the metrics, the clock, the silent robots) and makes the
frames the page draws: every robot's pose and its force alignment ψ_i (E8), every
spring's strain, the centroid trail, the rotation centre and the desired
direction, the metrics ψ (E8), ψ_heading (E7) and F (E9), and a status line. The
forces are those of E4 with the dashboard's gains and the supervisor's command,
computed with :mod:`aes_ros.model`, as the supervisor does. The scenario's walls and
obstacles go with the sheet; the bodies' contacts per second and smallest centre
distance are measured in the poses received (:func:`aes_ros.contact_measures.measure_contacts`).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aes_ros.contact_measures import TOUCH_TOLERANCE, measure_contacts
from aes_ros.formations import spring_pairs
from aes_ros.metrics import FORCE_EPS
from aes_ros.model import Gains, SwarmCommand, total_forces
from aes_ros.mona.geometry import MonaGeometry
from aes_ros.obstacles import contact_arrays
from aes_ros.params import ParameterError
from aes_ros.scenario import Scenario

#: Sim seconds of metrics history and centroid trail kept (the strip charts' span).
HISTORY_S = 60.0
#: The gains shown (and set) in the page.
GAIN_NAMES = ("alpha", "beta", "k", "w_l", "w_r")
#: Digits kept in a frame (0.1 mm, 1 mrad): enough to draw, small to send.
DIGITS = 4
#: The most robots drawn: a frame of 10⁴ is 0.5 MB of JSON and about 20 ms of work;
#: a ``/swarm/poses`` with more (or none) is dropped and the last good one kept.
MAX_ROBOTS = 10_000
#: Sim seconds over which the contacts per second and the closest bodies are shown.
CONTACTS_WINDOW_S = 1.0
#: The bodies the contacts are measured with: radius and axle offset [m].
BODY = MonaGeometry()


class PosesError(ValueError):
    """A poses message the view cannot draw (no robots, or more than MAX_ROBOTS)."""


@dataclass
class SwarmView:
    """The swarm as last heard, and the frames made of it.

    scenario : the sheet (neighbours, rest lengths) and the default gains.
    label : the scenario's name in the status line.
    """

    scenario: Scenario
    label: str = ""
    gains: Gains = field(init=False)
    command: SwarmCommand = field(init=False)
    enabled: bool | None = None
    t: float | None = None
    positions: np.ndarray | None = None
    headings: np.ndarray | None = None
    metrics: dict[str, float] = field(default_factory=dict)
    history: deque = field(default_factory=deque)
    trail: deque = field(default_factory=deque)
    silent: list[int] = field(default_factory=list)
    _clock: deque = field(default_factory=lambda: deque(maxlen=200))
    #: (t, contacts, closest centre distance) of each poses message in the last window
    _bodies: deque = field(default_factory=deque)

    def __post_init__(self) -> None:
        #: walls (4,) or (0,), circles (M, 3), boxes (L, 4) [m; odom]
        self.arena = contact_arrays(self.scenario.values)
        self.gains = self.scenario.gains
        self.command = self.scenario.command
        self._sheet(len(self.scenario.nominal_positions()))

    def _sheet(self, n: int) -> None:
        """The sheet of ``n`` robots: the scenario's, or an n-robot grid of it; without
        springs if the scenario has no such grid (e.g. a prime n above its 1000 columns)."""
        scenario = self.scenario
        try:
            if len(scenario.nominal_positions()) != n:
                scenario = scenario.with_robots(n)
            _, self.neighbors, self.rest = scenario.sheet()
        except ParameterError:
            self.neighbors, self.rest = np.full((n, 1), -1, dtype=np.int64), np.zeros((n, 1))
        self.pairs = spring_pairs(self.neighbors)
        self.n = n

    # --- what the swarm says ----------------------------------------------------------

    def on_poses(self, t: float, positions: np.ndarray, headings: np.ndarray) -> None:
        """A ``/swarm/poses`` message: sim time [s], positions (N, 2) [m], headings (N,).

        Raises PosesError, and keeps the swarm as it was, for 0 or more than MAX_ROBOTS
        robots."""
        if len(headings) == 0:
            raise PosesError("no poses")
        if len(headings) > MAX_ROBOTS:
            raise PosesError(f"too many poses: {len(headings)}; at most {MAX_ROBOTS} are drawn")
        if len(headings) != self.n:
            self._sheet(len(headings))
            self.trail.clear()
        if self.t is not None and t < self.t:  # a new clock: start the trail over
            self.trail.clear()
            self.history.clear()
            self._bodies.clear()
        self.t, self.positions, self.headings = t, positions, headings
        c = positions.mean(axis=0)
        self.trail.append((t, float(c[0]), float(c[1])))
        while self.trail and self.trail[0][0] < t - HISTORY_S:
            self.trail.popleft()
        pos = np.ascontiguousarray(positions, dtype=float)
        head = np.ascontiguousarray(headings, dtype=float)
        count, closest = measure_contacts(
            pos, head, BODY.body_radius, BODY.axle_offset, *self.arena, TOUCH_TOLERANCE
        )
        self._bodies.append((t, count, closest))
        while self._bodies[0][0] < t - CONTACTS_WINDOW_S:
            self._bodies.popleft()

    def on_metric(self, name: str, value: float) -> None:
        """``alignment``, ``heading_order`` or ``total_force`` from the supervisor."""
        self.metrics[name] = value
        if name == "total_force" and self.t is not None:
            row = (
                self.t,
                self.metrics.get("alignment", math.nan),
                self.metrics.get("heading_order", math.nan),
                value,
            )
            self.history.append(row)
            while self.history and self.history[0][0] < self.t - HISTORY_S:
                self.history.popleft()

    def on_command(self, direction: tuple[float, float], omega: float) -> None:
        self.command = SwarmCommand(direction, omega, self.command.center)

    def on_center(self, center: tuple[float, float] | None) -> None:
        """The supervisor's rotation centre (None: the live centroid)."""
        self.command = SwarmCommand(self.command.direction, self.command.omega, center)

    def on_clock(self, t: float, wall: float) -> None:
        self._clock.append((wall, t))

    def on_silent(self, robot_ids: list[int]) -> None:
        """The robots the bridge has not heard from lately (``/diagnostics``)."""
        self.silent = [i for i in robot_ids if 0 <= i < self.n]

    def set_gain(self, name: str, value: float) -> None:
        """A gain the robots accepted: the forces drawn use it too."""
        self.gains = Gains(**{**self.gains.__dict__, name: value})

    # --- what the page gets -----------------------------------------------------------

    def real_time_factor(self) -> float | None:
        """Sim seconds per wall second over the last clock messages."""
        if len(self._clock) < 2:
            return None
        (w0, t0), (w1, t1) = self._clock[0], self._clock[-1]
        return (t1 - t0) / (w1 - w0) if w1 > w0 else None

    def contacts(self) -> tuple[float | None, float | None]:
        """Contacts per second of sim time and the smallest centre distance [m] over
        the poses of the last ``CONTACTS_WINDOW_S``: the mean count per message over
        the shortest gap between messages (a step), so missed messages do not count
        as no contacts. None where unknown."""
        if not self._bodies:
            return None, None
        t, count, closest = np.array(self._bodies).T
        gaps = np.diff(t)
        gaps = gaps[gaps > 0]
        rate = float(count.mean() / gaps.min()) if len(gaps) else None
        return rate, float(closest.min())

    def sheet_message(self) -> dict[str, Any]:
        """The static part, sent once per viewer and when the swarm's size changes."""
        return {
            "type": "sheet",
            "n": self.n,
            "springs": self.pairs.tolist(),
            "diameter": 0.08,
            "gains": list(GAIN_NAMES),
            "scenario": self.label,
            "history": [[_r(v) for v in row] for row in self.history],
            "walls": self.arena[0].tolist(),
            "circles": self.arena[1].tolist(),
            "boxes": self.arena[2].tolist(),
        }

    def frame(self) -> dict[str, Any]:
        """The moving part, sent to every viewer at the frame rate."""
        out: dict[str, Any] = {
            "type": "frame",
            "t": self.t,
            "n": self.n,
            "rtf": _r(self.real_time_factor()),
            "enabled": self.enabled,
            "silent": self.silent,
            "direction": [_r(v) for v in self.command.direction],
            "omega": _r(self.command.omega),
            "gains": {name: _r(getattr(self.gains, name)) for name in GAIN_NAMES},
            "metrics": {k: _r(v) for k, v in self.metrics.items()},
        }
        if self.positions is None:
            return out
        rate, closest = self.contacts()
        out.update(contacts_per_s=_r(rate), min_centre_distance=_r(closest))
        pos, head = self.positions, self.headings
        forces = total_forces(pos, self.neighbors, self.rest, self.gains, self.command)
        norm = np.hypot(forces[:, 0], forces[:, 1])
        along = np.abs(forces[:, 0] * np.cos(head) + forces[:, 1] * np.sin(head))
        psi = np.where(norm > FORCE_EPS, along / np.where(norm > FORCE_EPS, norm, 1.0), 1.0)
        strain = spring_strains(pos, self.pairs, self.neighbors, self.rest)
        center = self.command.center
        centroid = pos.mean(axis=0)
        out.update(
            x=np.round(pos[:, 0], DIGITS).tolist(),
            y=np.round(pos[:, 1], DIGITS).tolist(),
            theta=np.round(head, 3).tolist(),
            psi=np.round(psi, 3).tolist(),
            force=np.round(norm, 3).tolist(),
            strain=np.round(strain, 3).tolist(),
            centroid=[_r(v) for v in centroid],
            center=[_r(v) for v in (centroid if center is None else center)],
            trail=[[_r(x), _r(y)] for _, x, y in list(self.trail)[::5]],
        )
        return out


def spring_strains(
    positions: np.ndarray, pairs: np.ndarray, neighbors: np.ndarray, rest: np.ndarray
) -> np.ndarray:
    """Relative deformation (|r_ij| - l_ij) / l_ij of each spring ``pairs: (M, 2)`` (i < j),
    positive when stretched. positions : (N, 2) [m]; neighbors, rest : (N, K)."""
    if len(pairs) == 0:
        return np.zeros(0)
    i, j = pairs[:, 0], pairs[:, 1]
    slot = np.argmax(neighbors[i] == j[:, None], axis=1)
    length = rest[i, slot]
    return (np.linalg.norm(positions[j] - positions[i], axis=1) - length) / length


def _r(value: float | None) -> float | None:
    """A number for JSON: rounded, and None for NaN/inf (JSON has no such numbers)."""
    if value is None or not math.isfinite(value):
        return None
    return round(float(value), DIGITS)
