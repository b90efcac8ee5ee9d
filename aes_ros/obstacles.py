"""Obstacles of a scenario: circles and boxes (docs/model.md#contacts-walls-and-obstacles).

The ``obstacles`` parameter is written in YAML as a list such as
``[{circle: [1.0, 0.5, 0.1]}, {box: [2, 2.2, -1, 1]}]`` or on one line (``--set``, the ROS
string parameter) as ``circle:1,0.5,0.1;box:2,2.2,-1,1``; empty means none. :func:`parse`
turns either into a tuple of ``(kind, numbers)`` pairs, :func:`format_obstacles` gives the
one-line form back, and :func:`contact_arrays` gives a scenario's walls and obstacles as
the arrays of :func:`aes_ros.contacts.resolve_contacts`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

#: Obstacle kinds and their numbers.
FIELDS = {"circle": ("x", "y", "r"), "box": ("x_min", "x_max", "y_min", "y_max")}

Obstacle = tuple[str, tuple[float, ...]]


def parse(value: Any, low: float = -math.inf, high: float = math.inf) -> tuple[Obstacle, ...]:
    """Obstacles from the one-line string, a YAML list of ``{kind: numbers}`` or of
    ``(kind, numbers)`` pairs; raises ValueError saying what is wrong.

    Every number must be finite and in [low, high]; a circle's r > 0; a box's
    x_min < x_max and y_min < y_max.
    """
    if value is None:
        return ()
    if isinstance(value, str):
        items: list[Any] = []
        for part in value.split(";"):
            if not part.strip():
                continue
            kind, sep, numbers = part.partition(":")
            if not sep:
                raise ValueError("each obstacle is kind:numbers, e.g. circle:1,0.5,0.1")
            items.append((kind, [v for v in numbers.split(",") if v.strip()]))
    elif isinstance(value, list | tuple):
        items = list(value)
    else:
        raise ValueError("need a list of circles and boxes")
    return tuple(_one(item, low, high) for item in items)


def _one(item: Any, low: float, high: float) -> Obstacle:
    if isinstance(item, Mapping):
        if len(item) != 1:
            raise ValueError("each obstacle is one {circle: [...]} or {box: [...]}")
        ((kind, numbers),) = item.items()
    elif isinstance(item, list | tuple) and len(item) == 2 and isinstance(item[0], str):
        kind, numbers = item
    else:
        raise ValueError("each obstacle is {circle: [x, y, r]} or {box: [...]}")
    kind = str(kind).strip().lower()
    if kind not in FIELDS:
        raise ValueError(f"unknown obstacle {kind!r}")
    if not isinstance(numbers, list | tuple) or len(numbers) != len(FIELDS[kind]):
        raise ValueError(f"a {kind} needs {len(FIELDS[kind])} numbers {','.join(FIELDS[kind])}")
    out = []
    for v in numbers:
        if isinstance(v, bool):
            raise ValueError(f"{kind}: {v!r} is not a number")
        x = float(v)
        if not math.isfinite(x) or not low <= x <= high:
            shown = repr(v) if len(repr(v)) <= 20 else repr(v)[:19] + "…"
            raise ValueError(f"{kind}: {shown} is not a finite number in [{low:g}, {high:g}]")
        out.append(x)
    if kind == "circle" and out[2] <= 0.0:
        raise ValueError("a circle needs r > 0")
    if kind == "box" and not (out[0] < out[1] and out[2] < out[3]):
        raise ValueError("a box needs x_min < x_max and y_min < y_max")
    return kind, tuple(out)


def format_obstacles(obstacles: tuple[Obstacle, ...]) -> str:
    """The one-line form, ``circle:x,y,r;box:x_min,x_max,y_min,y_max`` ('' for none)."""
    return ";".join(f"{kind}:" + ",".join(f"{v:g}" for v in nums) for kind, nums in obstacles)


def arrays(obstacles: Any) -> tuple[np.ndarray, np.ndarray]:
    """Circles (M, 3) x, y, r and boxes (L, 4) x_min, x_max, y_min, y_max [m], float64."""
    parsed = parse(obstacles)
    circles = [nums for kind, nums in parsed if kind == "circle"]
    boxes = [nums for kind, nums in parsed if kind == "box"]
    return np.array(circles, float).reshape(-1, 3), np.array(boxes, float).reshape(-1, 4)


def contact_arrays(values: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A scenario's (``Scenario.values``) walls (4,) or (0,), circles and boxes."""
    walls = np.array(values.get("walls", ()) or (), float).reshape(-1)
    circles, boxes = arrays(values.get("obstacles", ()))
    return walls, circles, boxes
