"""The swarm as ``visualization_msgs/MarkerArray`` for RViz2 and Foxglove (``/swarm/markers``).

From one dashboard frame (:meth:`dashboard_node.view.SwarmView.frame`), in the
world frame ``odom``, namespaces as RViz lists them:

- ``bodies``: one cylinder per robot (Ø 80 mm, 35 mm high; id = robot id),
  coloured by its force alignment ψ_i (red 0 → green 1), grey when silent;
- ``headings``: one line per robot from its centre 60 mm along its heading;
- ``springs``: every spring (LINE_LIST), grey at rest, red when stretched or
  compressed by 30 % or more;
- ``centroid_path``: the centroid over the last minute (LINE_STRIP);
- ``direction``: an arrow from the centroid along v_d (length ∝ |v_d|);
- ``rotation_center``: a small sphere at x_c;
- ``walls``: the scenario's walls, a closed dark line on their rectangle;
- ``obstacles``: its circles (dark cylinders) and boxes (dark cubes), ``ARENA_HEIGHT`` tall.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from aes_ros.ros import interface as names

#: The Mona's body: diameter and height [m] (docs/design.md#mona).
BODY_DIAMETER, BODY_HEIGHT = 0.08, 0.035
#: Strain drawn fully red [-]; length of a heading line [m].
STRAIN_RED, HEADING_LENGTH = 0.3, 0.06
#: A marker left alone disappears after this long: a stopped dashboard leaves no ghosts.
LIFETIME = Duration(sec=1, nanosec=0)
#: Height [m] drawn for walls and obstacles; their colour.
ARENA_HEIGHT = 0.1
ARENA_COLOR = ColorRGBA(r=0.2, g=0.2, b=0.2, a=1.0)


def alignment_color(psi: float, silent: bool = False) -> ColorRGBA:
    """Red (ψ_i = 0) through yellow to green (1); grey for a silent robot."""
    if silent:
        return ColorRGBA(r=0.5, g=0.5, b=0.5, a=0.6)
    psi = min(max(psi, 0.0), 1.0)
    return ColorRGBA(r=min(1.0, 2.0 * (1.0 - psi)), g=min(1.0, 2.0 * psi), b=0.1, a=1.0)


def strain_color(strain: float) -> ColorRGBA:
    """Grey at rest length, red at ±STRAIN_RED and beyond."""
    a = min(abs(strain) / STRAIN_RED, 1.0)
    return ColorRGBA(r=0.6 + 0.4 * a, g=0.6 * (1.0 - a), b=0.6 * (1.0 - a), a=0.9)


def _marker(ns: str, marker_id: int, kind: int, stamp: Time) -> Marker:
    m = Marker(ns=ns, id=marker_id, type=kind, action=Marker.ADD, lifetime=LIFETIME)
    m.header.frame_id = names.WORLD_FRAME
    m.header.stamp = stamp
    m.pose.orientation.w = 1.0
    return m


def _point(x: float, y: float, z: float = 0.0) -> Point:
    return Point(x=float(x), y=float(y), z=float(z))


def arena_markers(
    walls: np.ndarray, circles: np.ndarray, boxes: np.ndarray, stamp: Time
) -> list[Marker]:
    """Markers of the walls (4,) x_min, x_max, y_min, y_max or (0,), the circles (M, 3)
    x, y, r and the boxes (L, 4) x_min, x_max, y_min, y_max [m; odom]."""
    out = []
    if len(walls):
        x0, x1, y0, y1 = (float(v) for v in walls)
        line = _marker("walls", 0, Marker.LINE_STRIP, stamp)
        line.scale.x = 0.02
        line.color = ARENA_COLOR
        corners = ((x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0))
        line.points = [_point(x, y, ARENA_HEIGHT / 2) for x, y in corners]
        out.append(line)
    posts = np.reshape(circles, (-1, 3)).tolist()
    for k, (x, y, r) in enumerate(posts):
        post = _marker("obstacles", k, Marker.CYLINDER, stamp)
        post.pose.position = _point(x, y, ARENA_HEIGHT / 2)
        post.scale.x = post.scale.y = 2.0 * r
        post.scale.z = ARENA_HEIGHT
        post.color = ARENA_COLOR
        out.append(post)
    for k, (x0, x1, y0, y1) in enumerate(np.reshape(boxes, (-1, 4)).tolist(), len(posts)):
        box = _marker("obstacles", k, Marker.CUBE, stamp)
        box.pose.position = _point((x0 + x1) / 2, (y0 + y1) / 2, ARENA_HEIGHT / 2)
        box.scale.x, box.scale.y, box.scale.z = x1 - x0, y1 - y0, ARENA_HEIGHT
        box.color = ARENA_COLOR
        out.append(box)
    return out


def swarm_markers(
    frame: dict[str, Any],
    springs: Sequence[Sequence[int]],
    stamp: Time,
    arena: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> MarkerArray:
    """The markers of one dashboard ``frame`` (with robot poses) and its ``springs``,
    and of the ``arena``'s walls, circles and boxes (:func:`arena_markers`) if given."""
    out = MarkerArray()
    x, y, theta, psi = frame["x"], frame["y"], frame["theta"], frame["psi"]
    silent = set(frame.get("silent", []))
    for i in range(len(x)):
        body = _marker("bodies", i, Marker.CYLINDER, stamp)
        body.pose.position = _point(x[i], y[i], BODY_HEIGHT / 2)
        body.scale.x = body.scale.y = BODY_DIAMETER
        body.scale.z = BODY_HEIGHT
        body.color = alignment_color(psi[i], i in silent)
        out.markers.append(body)
    headings = _marker("headings", 0, Marker.LINE_LIST, stamp)
    headings.scale.x = 0.008
    headings.color = ColorRGBA(r=0.1, g=0.1, b=0.1, a=1.0)
    for i in range(len(x)):
        tip = (
            x[i] + HEADING_LENGTH * math.cos(theta[i]),
            y[i] + HEADING_LENGTH * math.sin(theta[i]),
        )
        headings.points += [_point(x[i], y[i], BODY_HEIGHT), _point(*tip, BODY_HEIGHT)]
    out.markers.append(headings)
    lines = _marker("springs", 0, Marker.LINE_LIST, stamp)
    lines.scale.x = 0.004
    for (i, j), strain in zip(springs, frame["strain"], strict=True):
        lines.points += [_point(x[i], y[i]), _point(x[j], y[j])]
        color = strain_color(strain)
        lines.colors += [color, color]
    out.markers.append(lines)
    path = _marker("centroid_path", 0, Marker.LINE_STRIP, stamp)
    path.scale.x = 0.01
    path.color = ColorRGBA(r=0.85, g=0.1, b=0.1, a=1.0)
    path.points = [_point(px, py) for px, py in frame["trail"]]
    if len(path.points) >= 2:
        out.markers.append(path)
    cx, cy = frame["centroid"]
    dx, dy = frame["direction"]
    arrow = _marker("direction", 0, Marker.ARROW, stamp)
    arrow.points = [_point(cx, cy, 0.05), _point(cx + 0.5 * dx, cy + 0.5 * dy, 0.05)]
    arrow.scale.x, arrow.scale.y, arrow.scale.z = 0.02, 0.05, 0.06
    arrow.color = ColorRGBA(r=0.1, g=0.3, b=0.9, a=1.0)
    if abs(dx) + abs(dy) > 0:
        out.markers.append(arrow)
    center = _marker("rotation_center", 0, Marker.SPHERE, stamp)
    center.pose.position = _point(*frame["center"])
    center.scale.x = center.scale.y = center.scale.z = 0.04
    center.color = ColorRGBA(r=0.6, g=0.1, b=0.8, a=1.0)
    out.markers.append(center)
    if arena is not None:
        out.markers += arena_markers(*arena, stamp)
    return out
