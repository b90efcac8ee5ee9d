"""bench/bench_ros.py's contacts A/B: the same configurations with the scenario's
``contacts`` off and on, side by side, and issue #34's cost goal (CPU per robot-step with
contacts on within 10 % of off, same run)."""

from __future__ import annotations

import math
from typing import Any

from ros_rows import Row

#: The goal: CPU per robot-step with contacts on at most this much above off.
MAX_EXTRA = 0.10


def contacts_modes(text: str) -> list[bool | None]:
    """``--contacts``: '' (the scenario's own setting) or 'off', 'on', 'off,on'; raises
    ValueError naming the field and the allowed values."""
    if not text:
        return [None]
    modes = []
    for word in text.split(","):
        if word not in ("off", "on"):
            raise ValueError(f"--contacts: {word!r} is not allowed; use off, on or off,on")
        modes.append(word == "on")
    return modes


def contacts_lines(measured: list[tuple[Row, bool | None, dict[str, Any]]]) -> list[str]:
    """Each configuration measured with contacts off and on: CPU per robot-step of both,
    their ratio against the goal, and what /sim/stats said of the bodies (contacts per
    second, closest centre distance)."""
    groups: dict[tuple, dict[bool, list[tuple[Row, dict[str, Any]]]]] = {}
    for row, on, bodies in measured:
        if on is not None:
            key = (row.robots, row.rate, row.source, row.layout, row.discovery)
            groups.setdefault(key, {}).setdefault(on, []).append((row, bodies))
    lines = []
    for (robots, rate, source, layout, discovery), modes in groups.items():
        if len(modes) < 2:
            continue
        cpu = {on: [r.cpu_us_per_robot_step for r, _ in runs] for on, runs in modes.items()}
        off_us, on_us = _median(cpu[False]), _median(cpu[True])
        ratio = on_us / off_us if off_us > 0 else math.nan
        met = ratio <= 1.0 + MAX_EXTRA
        lines.append(f"{robots} robots at {rate:g} Hz ({source}, {layout}, {discovery}):")
        for on, runs in sorted(modes.items()):
            per_s = "/".join(f"{b.get('contacts_per_s', math.nan):.1f}" for _, b in runs)
            closest = "/".join(_mm(b.get("min_centre_distance_m")) for _, b in runs)
            us = "/".join(f"{v:.1f}" for v in cpu[on])
            lines.append(
                f"  contacts {'on ' if on else 'off'}: CPU {us} µs/robot-step; "
                f"{per_s} contacts/s; closest centres {closest} mm"
            )
        lines.append(
            f"  goal: on within {100 * MAX_EXTRA:.0f} % of off: {ratio:.3f}x: "
            f"{'met' if met else 'NOT met'}"
        )
    return lines


def _median(values: list[float]) -> float:
    ordered = sorted(values)
    return ordered[len(ordered) // 2] if ordered else math.nan


def _mm(metres: float | None) -> str:
    return "–" if metres is None else f"{1e3 * metres:.1f}"
