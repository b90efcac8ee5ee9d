"""Walls and obstacles as static pybullet bodies (docs/model.md#contacts-walls-and-obstacles).

The walls are four thin boxes whose inner faces lie on the scenario's ``walls`` rectangle;
a circle obstacle is a cylinder, a box obstacle a box. All stand on the floor, ``HEIGHT``
tall, massless (static), in the robots' body collision group: robot bodies collide with
them in dynamic mode and the IR rays meet them in both modes.
"""

from __future__ import annotations

import numpy as np
import pybullet as pb

#: Height [m] of walls and obstacles (above the Mona's body and its IR sensors).
HEIGHT = 0.1
#: Thickness [m] of a wall, outside the rectangle.
WALL_THICKNESS = 0.05


def wall_boxes(walls: np.ndarray, thickness: float = WALL_THICKNESS) -> np.ndarray:
    """The four wall boxes (4, 4) x_min, x_max, y_min, y_max [m] around the rectangle
    ``walls`` = x_min, x_max, y_min, y_max (none for an empty ``walls``)."""
    if len(walls) == 0:
        return np.empty((0, 4))
    x0, x1, y0, y1 = (float(v) for v in walls)
    t = thickness
    return np.array(
        [
            [x0 - t, x0, y0 - t, y1 + t],  # left, corners included
            [x1, x1 + t, y0 - t, y1 + t],  # right
            [x0, x1, y0 - t, y0],  # bottom
            [x0, x1, y1, y1 + t],  # top
        ]
    )


def add_arena(
    client: int,
    walls: np.ndarray,
    circles: np.ndarray,
    boxes: np.ndarray,
    group: int,
    mask: int,
) -> list[int]:
    """Add the walls (4,) or (0,), circles (M, 3) and boxes (L, 4) [m] to pybullet
    ``client`` as static bodies in collision ``group`` with ``mask``; their body ids."""
    bodies = []
    for x0, x1, y0, y1 in np.vstack([wall_boxes(walls), boxes.reshape(-1, 4)]).tolist():
        half = [0.5 * (x1 - x0), 0.5 * (y1 - y0), 0.5 * HEIGHT]
        shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half, physicsClientId=client)
        visual = pb.createVisualShape(
            pb.GEOM_BOX, halfExtents=half, rgbaColor=(0.2, 0.2, 0.2, 1.0), physicsClientId=client
        )
        centre = [0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.5 * HEIGHT]
        bodies.append(_static(client, shape, visual, centre))
    for x, y, r in circles.reshape(-1, 3).tolist():
        shape = pb.createCollisionShape(
            pb.GEOM_CYLINDER, radius=r, height=HEIGHT, physicsClientId=client
        )
        visual = pb.createVisualShape(
            pb.GEOM_CYLINDER,
            radius=r,
            length=HEIGHT,
            rgbaColor=(0.2, 0.2, 0.2, 1.0),
            physicsClientId=client,
        )
        bodies.append(_static(client, shape, visual, [x, y, 0.5 * HEIGHT]))
    for body in bodies:
        pb.setCollisionFilterGroupMask(body, -1, group, mask, physicsClientId=client)
    return bodies


def _static(client: int, shape: int, visual: int, centre: list[float]) -> int:
    return pb.createMultiBody(
        0.0,
        shape,
        visual,
        basePosition=centre,
        physicsClientId=client,
    )


def solid_outlines(
    walls: np.ndarray, circles: np.ndarray, boxes: np.ndarray, points: int = 48
) -> list[np.ndarray]:
    """The bottom and top outlines (K, 3) [m] of every wall box, circle (``points`` per
    circle) and box, as the bodies of :func:`add_arena` stand: what a camera draws as the
    hull of their projections."""
    out = []
    for x0, x1, y0, y1 in np.vstack([wall_boxes(walls), boxes.reshape(-1, 4)]).tolist():
        out.append(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))
    a = np.linspace(0.0, 2.0 * np.pi, points, endpoint=False)
    for x, y, r in circles.reshape(-1, 3).tolist():
        out.append(np.stack([x + r * np.cos(a), y + r * np.sin(a)], axis=-1))
    return [
        np.concatenate([np.c_[ring, np.zeros(len(ring))], np.c_[ring, np.full(len(ring), HEIGHT)]])
        for ring in out
    ]
