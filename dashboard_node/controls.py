"""What a viewer may ask the swarm to do, checked before anything is published (pure).

A control message is one JSON object (at most :data:`MAX_MESSAGE_BYTES`):

- ``{"type": "drive", "direction": [x, y]}``, ``{"type": "drive", "omega": w}`` or
  both: the swarm command, set as the supervisor's ``desired_direction`` and
  ``rotation_rate`` parameters (one atomic set of only the fields given, so that
  steering the direction never resets ω to a value the page last saw, and the
  other way round); v_d and ω within the ranges of ``direction`` and ``omega``;
- ``{"type": "enable", "enabled": true}``: ``/swarm/enable``;
- ``{"type": "gain", "name": "alpha", "value": 0.1}``: a parameter set on every
  robot node and the supervisor (one of :data:`dashboard_node.view.GAIN_NAMES`;
  finite; its range is the nodes' to check, and their reasons are shown);
- ``{"type": "sim", "action": "pause" | "resume" | "reset"}``: the bridge's services.

Anything else (not JSON, not an object, an unknown type or field, a wrong type,
NaN or infinity, out of range, too long) raises :class:`ControlError` with the
reason the page shows; nothing is published then. :class:`RateLimit` keeps a
viewer from flooding the swarm.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

from aes_ros.params import PARAMS, ParameterError
from dashboard_node.view import GAIN_NAMES

#: The longest control message accepted [bytes].
MAX_MESSAGE_BYTES = 4096
SIM_ACTIONS = ("pause", "resume", "reset")


class ControlError(ValueError):
    """A control message that is refused; the text says why."""


@dataclass(frozen=True)
class Drive:
    """The swarm command's parts a viewer changes; None: leave that part as it is."""

    direction: tuple[float, float] | None = None
    omega: float | None = None


@dataclass(frozen=True)
class Enable:
    enabled: bool


@dataclass(frozen=True)
class SetGain:
    name: str
    value: float


@dataclass(frozen=True)
class SimAction:
    action: str


Control = Drive | Enable | SetGain | SimAction
_FIELDS = {
    "drive": {"direction", "omega"},  # either or both
    "enable": {"enabled"},
    "gain": {"name", "value"},
    "sim": {"action"},
}


def parse_control(text: str | bytes) -> Control:
    """The control a viewer's message asks for; ControlError with the reason otherwise."""
    size = len(text.encode("utf-8", "surrogatepass") if isinstance(text, str) else text)
    if size > MAX_MESSAGE_BYTES:
        raise ControlError(f"message of {size} bytes; at most {MAX_MESSAGE_BYTES}")
    try:
        message = json.loads(text, parse_constant=_no_constant)
    except (ValueError, RecursionError) as exc:
        raise ControlError(f"not JSON: {exc}") from None
    if not isinstance(message, dict):
        raise ControlError("not a JSON object")
    kind = message.get("type")
    if not isinstance(kind, str) or kind not in _FIELDS:
        raise ControlError(f"type: {_show(kind)} is not one of {', '.join(_FIELDS)}")
    extra = set(message) - _FIELDS[kind] - {"type"}
    missing = _FIELDS[kind] - set(message)
    if kind == "drive" and missing != _FIELDS[kind]:
        missing = set()  # one of the two is enough
    if extra or missing:
        raise ControlError(
            f"{kind}: fields {sorted(missing)} missing, {sorted(extra)} unknown"
            if missing and extra
            else f"{kind}: {'missing' if missing else 'unknown'} field(s) "
            f"{', '.join(sorted(missing or extra))}"
        )
    if kind == "drive":
        return _drive(message)
    if kind == "enable":
        if not isinstance(message["enabled"], bool):
            raise ControlError("enabled: need true or false")
        return Enable(message["enabled"])
    if kind == "gain":
        name = message["name"]
        if not isinstance(name, str) or name not in GAIN_NAMES:
            raise ControlError(f"name: {_show(name)} is not one of {', '.join(GAIN_NAMES)}")
        return SetGain(name, _number(name, message["value"]))
    action = message["action"]
    if not isinstance(action, str) or action not in SIM_ACTIONS:
        raise ControlError(f"action: {_show(action)} is not one of {', '.join(SIM_ACTIONS)}")
    return SimAction(action)


def _drive(message: dict[str, Any]) -> Drive:
    direction = omega = None
    if "direction" in message:
        value = message["direction"]
        if not (isinstance(value, list) and len(value) == 2):
            raise ControlError("direction: need two numbers [x, y]")
        x, y = (_number("direction", v) for v in value)
        _in_range("direction", [x, y])
        direction = (x, y)
    if "omega" in message:
        omega = _number("omega", message["omega"])
        _in_range("omega", omega)
    return Drive(direction, omega)


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number JSON allows")


def _number(field: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ControlError(f"{field}: {_show(value)} is not a number")
    try:
        number = float(value)  # an integer of 400 digits does not fit a float
    except OverflowError:
        raise ControlError(f"{field}: {_show(value)} is too large") from None
    if not math.isfinite(number):
        raise ControlError(f"{field}: {_show(value)} is not finite")
    return number


def _show(value: Any, limit: int = 40) -> str:
    """``repr(value)``, cut to ``limit`` characters: a reason is read, not a copy."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _in_range(name: str, value: Any) -> None:
    try:
        PARAMS[name].validate(value)
    except ParameterError as exc:
        raise ControlError(str(exc)) from None


class RateLimit:
    """At most ``rate`` control messages per second on average, ``burst`` at once.

    >>> limit = RateLimit(rate=10.0, burst=2)
    >>> [limit.allow(now=0.0) for _ in range(3)]
    [True, True, False]
    """

    def __init__(self, rate: float = 10.0, burst: int = 20) -> None:
        self.rate, self.burst = rate, burst
        self._tokens = float(burst)
        self._at: float | None = None

    def allow(self, now: float) -> bool:
        if self._at is not None:
            self._tokens = min(self.burst, self._tokens + (now - self._at) * self.rate)
        self._at = now
        if self._tokens < 1.0:
            return False
        self._tokens -= 1.0
        return True
