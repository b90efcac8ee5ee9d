"""The arena layout file (``arena.yaml``): the reference markers on the floor
(docs/design.md#tracking).

:func:`load_layout` reads it, :func:`save_layout` writes it, :func:`corner_layout`
makes the one a simulated launch uses. The simulated camera draws its markers, the
tracker calibrates with them. Every field is validated: a missing, mis-shaped or
non-finite one raises :class:`CalibrationError` naming the field and what it should be.

``arena.yaml``::

    marker_height: 0.038          # [m] the robots' marker plane (optional, 0.038)
    arena: [-1.0, 1.0, -0.75, 0.75]   # [m] x_min x_max y_min y_max (optional)
    references:                   # at least 3, not on one line
      - {id: 249, x: -0.95, y: -0.70, size: 0.10}      # [m]; yaw [rad] optional
      - {id: 248, x: 0.95, y: -0.70, size: 0.10}
      - {id: 247, x: 0.95, y: 0.70, size: 0.10, yaw: 0.0}
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from aes_ros.arena import arena_or_none
from aes_ros.markers import N_IDS, ReferenceMarker, RobotMarker, reference_ids
from aes_ros.params import ParameterError

#: The fewest reference markers a calibration accepts.
MIN_REFERENCES = 3


class CalibrationError(ValueError):
    """A calibration or layout that cannot be used; the message says what is wrong."""


# --- validation --------------------------------------------------------------------------


def yaml_number(data: Mapping[str, Any], key: str, where: str, *, positive: bool = False) -> float:
    if key not in data:
        raise CalibrationError(f"{where}{key}: missing (expected a number)")
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CalibrationError(f"{where}{key}: expected a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value) or (positive and value <= 0.0):
        kind = "a finite number > 0" if positive else "a finite number"
        raise CalibrationError(f"{where}{key}: expected {kind}, got {value!r}")
    return value


def yaml_array(
    data: Mapping[str, Any], key: str, shape: tuple[int, ...], where: str = ""
) -> np.ndarray:
    if len(shape) == 1:
        what = f"a list of {shape[0]} finite numbers"
    else:
        what = f"a {shape[0]}x{shape[1]} list of lists of finite numbers"
    if key not in data:
        raise CalibrationError(f"{where}{key}: missing (expected {what})")
    value = data[key]
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise CalibrationError(f"{where}{key}: expected {what}, got {value!r}") from None
    if arr.shape != shape or not np.all(np.isfinite(arr)):
        raise CalibrationError(f"{where}{key}: expected {what}, got {value!r}")
    return arr


def yaml_mapping(data: Any, what: str) -> Mapping[str, Any]:
    if not isinstance(data, Mapping):
        raise CalibrationError(f"{what}: expected a mapping of fields, got {type(data).__name__}")
    return data


def read_yaml(path: Path | str) -> Any:
    try:
        with open(path, encoding="utf-8") as f:
            return yaml.safe_load(f)
    except OSError as exc:
        raise CalibrationError(f"{path}: cannot read ({exc.strerror})") from exc
    except yaml.YAMLError as exc:
        raise CalibrationError(f"{path}: not YAML ({exc})") from exc


# --- the layout --------------------------------------------------------------------------


@dataclass(frozen=True)
class ArenaLayout:
    """What is known of the arena: reference markers, the robots' marker height, its extent.

    references : the reference markers lying on the floor.
    marker_height : height of the robots' marker plane [m].
    arena : (x_min, x_max, y_min, y_max) [m] or None.
    """

    references: tuple[ReferenceMarker, ...]
    marker_height: float = RobotMarker().height
    arena: tuple[float, float, float, float] | None = None

    def reference(self, marker_id: int) -> ReferenceMarker:
        """The reference marker with id ``marker_id`` (KeyError if none)."""
        for ref in self.references:
            if ref.marker_id == marker_id:
                return ref
        raise KeyError(marker_id)

    @property
    def ids(self) -> tuple[int, ...]:
        """The reference markers' ids."""
        return tuple(r.marker_id for r in self.references)


def parse_layout(data: Any, source: str = "layout") -> ArenaLayout:
    """An :class:`ArenaLayout` from parsed YAML, validated field by field."""
    data = yaml_mapping(data, source)
    height = (
        yaml_number(data, "marker_height", "", positive=True) if "marker_height" in data else None
    )
    arena = None
    if data.get("arena") is not None:
        box = yaml_array(data, "arena", (4,))
        try:  # the rule of the supervisor's arena (aes_ros.params)
            arena = arena_or_none(box.tolist()).bounds
        except ParameterError as exc:
            raise CalibrationError(str(exc)) from None
    refs = data.get("references")
    if not isinstance(refs, Sequence) or isinstance(refs, str):
        raise CalibrationError(
            "references: missing (expected a list of {id, x, y, size[, yaw]} mappings)"
        )
    if len(refs) < MIN_REFERENCES:
        raise CalibrationError(
            f"references: expected at least {MIN_REFERENCES} reference markers, got {len(refs)}"
        )
    markers = []
    for k, item in enumerate(refs):
        where = f"references[{k}]."
        item = yaml_mapping(item, f"references[{k}]")
        if "id" not in item:
            raise CalibrationError(f"{where}id: missing (expected a marker id 0 … {N_IDS - 1})")
        marker_id = item["id"]
        if isinstance(marker_id, bool) or not isinstance(marker_id, int):
            raise CalibrationError(f"{where}id: expected an integer, got {marker_id!r}")
        if not 0 <= marker_id < N_IDS:
            raise CalibrationError(f"{where}id: expected 0 … {N_IDS - 1}, got {marker_id}")
        yaw = yaml_number(item, "yaw", where) if "yaw" in item else 0.0
        markers.append(
            ReferenceMarker(
                marker_id,
                yaml_number(item, "x", where),
                yaml_number(item, "y", where),
                yaml_number(item, "size", where, positive=True),
                yaw,
            )
        )
    ids = [m.marker_id for m in markers]
    twice = sorted({i for i in ids if ids.count(i) > 1})
    if twice:
        raise CalibrationError(f"references: ids {twice} appear more than once")
    kwargs = {} if height is None else {"marker_height": height}
    return ArenaLayout(tuple(markers), arena=arena, **kwargs)


def corner_layout(
    arena: Sequence[float], size: float = 0.06, outset: float = 0.05, **kwargs: Any
) -> ArenaLayout:
    """A layout with a reference marker of side ``size`` [m] off each corner of
    ``arena`` ``(x_min, x_max, y_min, y_max)`` [m], ``outset`` [m] outside it in x
    and y (where no robot drives over it), ids from :func:`reference_ids`; what the
    launch gives the simulated camera and the tracker (``kwargs``: marker_height)."""
    x0, x1, y0, y1 = (float(v) for v in arena)
    places = [(x0 - outset, y0 - outset), (x1 + outset, y0 - outset),
              (x1 + outset, y1 + outset), (x0 - outset, y1 + outset)]  # fmt: skip
    refs = tuple(
        ReferenceMarker(i, x, y, size) for i, (x, y) in zip(reference_ids(4), places, strict=True)
    )
    return ArenaLayout(refs, arena=(x0, x1, y0, y1), **kwargs)


def save_layout(layout: ArenaLayout, path: Path | str) -> Path:
    """Write ``layout`` as an ``arena.yaml`` that :func:`load_layout` reads back."""
    data: dict[str, Any] = {
        "marker_height": float(layout.marker_height),
        "references": [
            {
                "id": r.marker_id,
                "x": float(r.x),
                "y": float(r.y),
                "size": float(r.size),
                "yaw": float(r.yaw),
            }
            for r in layout.references
        ],
    }
    if layout.arena is not None:
        data["arena"] = [float(v) for v in layout.arena]
    path = Path(path)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def load_layout(path: Path | str) -> ArenaLayout:
    """The arena layout in the YAML file ``path`` (see the module docstring)."""
    try:
        return parse_layout(read_yaml(path), str(path))
    except CalibrationError as exc:
        raise CalibrationError(f"{path}: {exc}") from None


# --- the calibration ---------------------------------------------------------------------
