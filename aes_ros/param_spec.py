"""What one parameter is: :class:`ParamSpec` (name, default, kind, allowed range, unit,
description) and how a value is checked against it; :class:`ParameterError`, the error that
names the field and what it allows. The parameters themselves are :data:`aes_ros.params.PARAMS`.
"""

from __future__ import annotations

import array
import math
from dataclasses import dataclass
from typing import Any

from aes_ros import obstacles

#: What a vector parameter may be given as: rclpy hands double arrays over as array('d').
SEQUENCES = (list, tuple, array.array)


class ParameterError(ValueError):
    """A parameter value is missing, of the wrong type or out of range.

    The message always names the field and what is allowed.
    """


@dataclass(frozen=True)
class ParamSpec:
    """Definition of one parameter.

    ``kind`` is one of ``"float"``, ``"int"``, ``"bool"``, ``"str"``, ``"vec2"``
    (two floats), ``"center"`` (``"centroid"`` or two floats), ``"rect"`` (empty,
    or four floats x_min, x_max, y_min, y_max with x_min < x_max and y_min < y_max) or
    ``"obstacles"`` (circles and boxes, :mod:`aes_ros.obstacles`).
    ``low``/``high`` bound numbers (and every component of a ``vec2`` or ``rect``);
    ``choices`` lists allowed strings.
    """

    name: str
    default: Any
    kind: str
    description: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] = ()

    def allowed(self) -> str:
        """Human-readable statement of the allowed values."""
        if self.choices:
            return "one of " + ", ".join(self.choices)
        if self.kind == "bool":
            return "true or false"
        if self.kind == "str":
            return "a string"
        rng = f"[{self.low:g}, {self.high:g}]"
        if self.kind == "int":
            return f"an integer in {rng}"
        if self.kind == "vec2":
            return f"two numbers 'x,y', each in {rng}"
        if self.kind == "center":
            return f"'centroid' or two numbers 'x,y', each in {rng}"
        if self.kind == "rect":
            return (
                f"empty (none) or four numbers 'x_min,x_max,y_min,y_max', each in {rng}, "
                "x_min < x_max, y_min < y_max"
            )
        if self.kind == "obstacles":
            return (
                "empty (none) or circles and boxes 'circle:x,y,r;box:x_min,x_max,y_min,y_max' "
                "(YAML: a list of {circle: [x, y, r]} and {box: [x_min, x_max, y_min, y_max]}), "
                f"each number in {rng}, r > 0, x_min < x_max, y_min < y_max"
            )
        return f"a number in {rng}"

    def validate(self, value: Any) -> Any:
        """Return ``value`` converted to this parameter's type, or raise ParameterError."""
        try:
            return self._convert(value)
        except (TypeError, ValueError, OverflowError) as exc:
            raise ParameterError(
                f"{self.name}: {_show(value)} is not allowed ({exc}); expected {self.allowed()}"
            ) from None

    def _convert(self, value: Any) -> Any:
        if self.kind == "bool":
            if isinstance(value, bool):
                return value
            if isinstance(value, str) and value.lower() in ("true", "false", "1", "0"):
                return value.lower() in ("true", "1")
            raise ValueError("not a boolean")
        if self.kind == "str":
            value = str(value)
            if self.choices and value not in self.choices:
                raise ValueError("unknown choice")
            return value
        if self.kind == "center" and isinstance(value, str) and value == "centroid":
            return "centroid"
        if self.kind == "rect":
            return self._rect(value)
        if self.kind == "obstacles":
            return obstacles.parse(value, self.low, self.high)
        if self.kind in ("vec2", "center"):
            if isinstance(value, str):
                value = [v for v in value.replace("[", "").replace("]", "").split(",") if v]
            if not isinstance(value, SEQUENCES) or len(value) != 2:
                raise ValueError("need exactly two numbers")
            return (self._number(value[0], float), self._number(value[1], float))
        if self.kind == "int":
            if isinstance(value, float) and not value.is_integer():
                raise ValueError("not an integer")
            return self._number(value, int)
        return self._number(value, float)

    def _rect(self, value: Any) -> tuple[float, ...]:
        if value is None or (isinstance(value, str) and value.strip().lower() in ("", "none")):
            return ()
        if isinstance(value, str):
            value = [v for v in value.replace("[", "").replace("]", "").split(",") if v.strip()]
        if not isinstance(value, SEQUENCES) or len(value) not in (0, 4):
            raise ValueError("need four numbers or none")
        if len(value) == 0:
            return ()
        x_min, x_max, y_min, y_max = (self._number(v, float) for v in value)
        if not (x_min < x_max and y_min < y_max):
            raise ValueError("need x_min < x_max and y_min < y_max")
        return (x_min, x_max, y_min, y_max)

    def _number(self, value: Any, typ: type) -> Any:
        if isinstance(value, bool):
            raise ValueError("not a number")
        if typ is int:
            number = int(value) if not isinstance(value, str) else int(value.strip())
        else:
            try:
                number = float(value)
            except OverflowError:  # an integer beyond float's range
                raise ValueError("too large") from None
            if not math.isfinite(number):
                raise ValueError("not finite")
        if (self.low is not None and number < self.low) or (
            self.high is not None and number > self.high
        ):
            raise ValueError("out of range")
        return number


def _show(value: Any, limit: int = 40) -> str:
    """``repr(value)`` cut to ``limit`` characters, for a message that names it."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 1] + "…"
