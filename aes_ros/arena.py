"""The arena keeper: keep the swarm inside a rectangle by turning or stopping it.

A lab's arena (or the overhead camera's view, which a lab sets as the arena) is a
rectangle in the world frame ``odom``. The supervisor asks :func:`keep_in_arena`
at every ``/swarm/poses``; the rule is pure (state in, decision and state out) so
that the same code runs in the supervisor node and in the tests.

The rule (``margin`` m, ``release`` = :data:`RELEASE_FACTOR` × ``margin``):

1. A wall becomes *guarded* when some robot is within ``margin`` of it, and stays
   guarded until every robot is at least ``release`` from it again (hysteresis:
   a robot whose distance jitters about ``margin`` does not guard and free the
   wall at every pose).
2. The keeper acts when the command v_d points out through a guarded wall
   (v_d·n > 0, n the wall's outward normal); a swarm without a drive (v_d = 0)
   goes where its sheet takes it, so then any guarded wall counts.
3. ``turn``: the new v_d points from the swarm's centroid to the arena's centre,
   with the old speed |v_d| (1, the setups' drive, when v_d was 0). If that
   direction is not strictly inward for every guarded wall (a swarm wider than
   half the arena), it is the sum of the guarded walls' inward normals instead;
   if those cancel (the swarm spans the arena between two opposite walls), no
   direction helps and the keeper stops the swarm. ``stop``: the swarm is stopped
   (the supervisor disables the robots: with v_d = 0 the AES robots would still
   drive at v_0 and drift).

   The new direction points inward for every guarded wall, so the rule does not
   act again until a new wall is guarded or someone points the swarm outward
   again; it is never re-aimed while the swarm turns (no flapping between
   directions at every pose).

Default margin (:data:`DEFAULT_MARGIN`, ``arena_margin``): the robot's radius plus what
a robot covers at top speed during the keeper's reaction time, ``0.04 m + 0.13 m/s × 1 s``,
so that the body stays inside; the reaction time is mostly the sheet turning round
(docs/ros.md#parameters; ``tests/unit/test_arena_keeper_rule.py`` runs the loop). A camera
in the loop adds its delay τ: raise the margin by 0.13 m/s × τ.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from aes_ros.params import PARAMS

#: The walls in the order of the ``arena`` parameter's bounds: x_min, x_max, y_min, y_max.
WALLS = ("west", "east", "south", "north")
#: Outward normal of each wall of :data:`WALLS` (4, 2).
OUTWARD = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]])
#: The keeper's policies: turn the swarm back, or stop it.
POLICIES = PARAMS["arena_policy"].choices
#: Default distance from a wall at which the keeper acts [m]: the robot's radius plus
#: its top speed × the reaction time (module docstring; ``arena_margin`` in PARAMS).
DEFAULT_MARGIN = PARAMS["arena_margin"].default
#: A guarded wall is freed once every robot is this many margins away from it.
RELEASE_FACTOR = 2.0
#: The drive |v_d| given to a swarm that had none when the keeper turns it.
UNIT_DRIVE = 1.0


@dataclass(frozen=True)
class Arena:
    """A rectangle in the world frame ``odom`` [m]: x_min < x_max, y_min < y_max."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float

    def __post_init__(self) -> None:
        if not (self.x_min < self.x_max and self.y_min < self.y_max):
            raise ValueError(f"arena {self.bounds}: need x_min < x_max and y_min < y_max")

    @classmethod
    def from_bounds(cls, bounds: Sequence[float]) -> Arena | None:
        """The arena of ``(x_min, x_max, y_min, y_max)``, or None for ``()`` (no arena)."""
        if len(bounds) == 0:
            return None
        x_min, x_max, y_min, y_max = (float(v) for v in bounds)
        return cls(x_min, x_max, y_min, y_max)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        return (self.x_min, self.x_max, self.y_min, self.y_max)

    @property
    def centre(self) -> np.ndarray:
        """(2,) [m]."""
        return np.array([(self.x_min + self.x_max) / 2, (self.y_min + self.y_max) / 2])

    def clearances(self, positions: np.ndarray) -> np.ndarray:
        """Distance of each position to each wall of :data:`WALLS` [m], negative outside.

        positions : (..., N, 2) [m; odom]. Returns (..., N, 4).
        """
        x, y = positions[..., 0], positions[..., 1]
        return np.stack([x - self.x_min, self.x_max - x, y - self.y_min, self.y_max - y], axis=-1)


@dataclass(frozen=True)
class KeeperState:
    """Which walls of :data:`WALLS` are guarded (rule step 1)."""

    guarded: tuple[bool, bool, bool, bool] = (False, False, False, False)


@dataclass(frozen=True)
class Decision:
    """What :func:`keep_in_arena` decided.

    action : ``keep`` (the command stays), ``turn`` or ``stop``.
    direction : v_d after the decision (the new one for ``turn``, else the old one).
    state : the keeper's state for the next call.
    wall : the wall the command pointed out through (None for ``keep``).
    robot : the robot closest to that wall, and ``clearance`` its distance to it [m].
    note : why a ``turn`` policy stopped the swarm ("" otherwise).
    """

    action: str
    direction: tuple[float, float]
    state: KeeperState
    wall: str | None = None
    robot: int | None = None
    clearance: float = math.inf
    note: str = ""

    def describe(self, old_direction: Sequence[float]) -> str:
        """One line for the log: what the keeper did and why."""
        if self.action == "keep":
            return "arena keeper: the command stays"
        old = f"({old_direction[0]:.3g}, {old_direction[1]:.3g})"
        where = f"robot {self.robot} {self.clearance:.3f} m from the {self.wall} wall"
        if self.action == "turn":
            new = f"({self.direction[0]:.3g}, {self.direction[1]:.3g})"
            return f"arena keeper turned the swarm; {where}: v_d {old} -> {new}"
        note = f" ({self.note})" if self.note else ""
        return f"arena keeper stopped the swarm; {where}, v_d {old}: robots disabled{note}"


def keep_in_arena(
    positions: np.ndarray,
    direction: Sequence[float],
    arena: Arena,
    state: KeeperState | None = None,
    *,
    policy: str = "turn",
    margin: float = DEFAULT_MARGIN,
    release: float | None = None,
) -> Decision:
    """Keep, turn or stop the swarm so that no robot leaves ``arena`` (module docstring).

    Parameters
    ----------
    positions : (N, 2) robot positions [m; odom]. One swarm: the decision and the
        state belong to it, so there are no batch axes here (:meth:`Arena.clearances`
        has them).
    direction : v_d (2,), world frame, the command the robots follow now.
    arena : the rectangle.
    state : the keeper's state from the previous call (None: nothing guarded).
    policy : ``turn`` or ``stop``.
    margin : distance from a wall at which a wall becomes guarded [m], > 0.
    release : distance at which a guarded wall is freed [m] (default
        :data:`RELEASE_FACTOR` × ``margin``), ≥ ``margin``.

    Returns
    -------
    Decision: ``keep`` while the command does not point out through a guarded wall.
    """
    if policy not in POLICIES:
        raise ValueError(f"policy {policy!r}: expected one of {', '.join(POLICIES)}")
    release = RELEASE_FACTOR * margin if release is None else release
    state = KeeperState() if state is None else state
    positions = np.asarray(positions, dtype=float).reshape(-1, 2)
    d = np.asarray(direction, dtype=float).reshape(2)
    old = (float(d[0]), float(d[1]))
    clear = arena.clearances(positions)  # (N, 4)
    nearest = clear.min(axis=0)  # (4,)
    guarded = (np.array(state.guarded) & (nearest < release)) | (nearest < margin)
    new_state = KeeperState(tuple(bool(g) for g in guarded))
    speed = float(np.hypot(*d))
    outward = OUTWARD @ d > 0.0 if speed > 0.0 else np.ones(4, dtype=bool)
    threat = guarded & outward
    if not threat.any():
        return Decision("keep", old, new_state)
    wall = int(np.flatnonzero(threat)[np.argmin(nearest[threat])])
    robot = int(np.argmin(clear[:, wall]))
    found = dict(wall=WALLS[wall], robot=robot, clearance=float(clear[robot, wall]))
    inward = _inward(positions, arena, guarded) if policy == "turn" else None
    if inward is None:
        note = "" if policy == "stop" else "the swarm spans the arena: no way leads inward"
        return Decision("stop", old, new_state, **found, note=note)
    new = inward * (speed if speed > 0.0 else UNIT_DRIVE)
    return Decision("turn", (float(new[0]), float(new[1])), new_state, **found)


def _inward(positions: np.ndarray, arena: Arena, guarded: np.ndarray) -> np.ndarray | None:
    """Unit direction from the centroid to the centre, or the sum of the guarded walls'
    inward normals where that is not inward for every guarded wall; None if those
    cancel."""
    to_centre = arena.centre - positions.mean(axis=0)
    length = float(np.hypot(*to_centre))
    if length > 0.0:
        unit = to_centre / length
        if np.all(OUTWARD[guarded] @ unit < 0.0):
            return unit
    normals = -OUTWARD[guarded].sum(axis=0)
    length = float(np.hypot(*normals))
    return normals / length if length > 0.0 else None


def arena_or_none(value: Any) -> Arena | None:
    """The :class:`Arena` of an ``arena`` parameter's value (validated by PARAMS)."""
    return Arena.from_bounds(PARAMS["arena"].validate(value))
