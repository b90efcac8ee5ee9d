"""The arena a tracking launch's overhead camera sees, from the scenario (pure geometry)."""

from __future__ import annotations

from aes_ros.scenario import Scenario

#: Floor [m] around the formation that a tracking launch's arena adds when the
#: scenario gives none, and the smallest arena (the issue's 2.0 × 1.5 m at 1280 × 960).
TRACKING_ROOM = 0.5
TRACKING_MIN_ARENA = (2.0, 1.5)


def tracking_arena(scenario: Scenario) -> tuple[float, float, float, float]:
    """The arena a tracking launch's camera sees, ``(x_min, x_max, y_min, y_max)`` [m]:
    the scenario's ``arena`` (which the supervisor's arena keeper also keeps the swarm
    in; a tracking LaunchConfig sets it to this when the scenario has none), else the
    initial formation with :data:`TRACKING_ROOM` around it, at least
    :data:`TRACKING_MIN_ARENA` and 4:3 like the camera's picture."""
    if scenario.arena:
        return tuple(float(v) for v in scenario.arena)  # type: ignore[return-value]
    xy = scenario.nominal_positions()
    (x0, y0), (x1, y1) = xy.min(axis=0), xy.max(axis=0)
    w = max(x1 - x0 + 2 * TRACKING_ROOM, TRACKING_MIN_ARENA[0])
    h = max(y1 - y0 + 2 * TRACKING_ROOM, TRACKING_MIN_ARENA[1])
    w, h = max(w, h * 4 / 3), max(h, w * 3 / 4)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    return tuple(round(float(v), 3) for v in (cx - w / 2, cx + w / 2, cy - h / 2, cy + h / 2))
