"""What a sweep covers: axes from ``--param`` specs, grid or Latin-hypercube points (pure).

An axis is one scenario parameter (any numeric one of :data:`aes_ros.params.PARAMS`,
or ``robots``: the swarm size N, a near-square grid of N robots) and its values::

    alpha=0.01:0.2:20        20 values, evenly spaced from 0.01 to 0.2
    k=log:0.05:5:20          20 values, evenly spaced in log from 0.05 to 5
    robots=25,100,400        the values listed
    beta=0.1:2               a range only: for --lhs (a grid needs a count)

The points are the grid (every combination, the first axis slowest) or, with
``--lhs N``, N points of a Latin hypercube over the axes' ranges (log axes sampled
in log space) drawn with the sweep's seed. Integer parameters are rounded. A bad
spec raises :class:`SweepSpecError` naming the field and what is allowed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aes_ros.params import PARAMS, ParameterError

#: The swarm size as a sweep axis (a near-square grid of N robots, as ``--robots``).
ROBOTS = "robots"
ROBOTS_RANGE = (1, 100_000)
#: The most points one sweep may have (grid or ``--lhs``): beyond it a spec is a typo.
MAX_POINTS = 1_000_000


class SweepSpecError(ParameterError):
    """A sweep spec that cannot be run; the text names the field and what is allowed."""


@dataclass(frozen=True)
class Axis:
    """One swept parameter: its name, range and, for a grid, how many values.

    values : explicit values (a list spec), else None.
    """

    name: str
    low: float
    high: float
    count: int | None = None
    log: bool = False
    values: tuple[float, ...] | None = None

    @property
    def integer(self) -> bool:
        return self.name == ROBOTS or PARAMS[self.name].kind == "int"

    def grid(self) -> np.ndarray:
        """The axis's values for a grid sweep."""
        if self.values is not None:
            out = np.array(self.values, dtype=float)
        elif self.count is None:
            raise SweepSpecError(
                f"{self.name}: a grid needs a count ({self.name}=low:high:n); "
                "a range alone is for --lhs"
            )
        elif self.log:
            out = np.geomspace(self.low, self.high, self.count)
        else:
            out = np.linspace(self.low, self.high, self.count)
        return self._cast(out)

    def scale(self, unit: np.ndarray) -> np.ndarray:
        """Map samples in [0, 1) onto the axis's range (log axes in log space)."""
        if self.values is not None:
            index = np.minimum((unit * len(self.values)).astype(int), len(self.values) - 1)
            return self._cast(np.array(self.values, dtype=float)[index])
        if self.log:
            out = np.exp(np.log(self.low) + unit * (np.log(self.high) - np.log(self.low)))
        else:
            out = self.low + unit * (self.high - self.low)
        return self._cast(out)

    def _cast(self, values: np.ndarray) -> np.ndarray:
        return np.round(values) if self.integer else values


def allowed_names() -> list[str]:
    """Parameters a sweep may vary: the numeric scenario parameters and ``robots``."""
    return [ROBOTS] + [n for n, p in PARAMS.items() if p.kind in ("int", "float")]


def parse_axis(text: str) -> Axis:
    """One ``--param`` spec (module docstring)."""
    name, sep, spec = text.partition("=")
    name = name.strip()
    if not sep or not spec.strip():
        raise SweepSpecError(f"--param {text!r}: need name=low:high:n, name=log:low:high:n or "
                             "name=v1,v2,…")  # fmt: skip
    if name not in allowed_names():
        raise SweepSpecError(
            f"--param {name}: not a parameter a sweep can vary; allowed: "
            f"{', '.join(allowed_names())}"
        )
    spec = spec.strip()
    if "," in spec:
        values = tuple(_number(name, v) for v in spec.split(",") if v.strip())
        if not values:
            raise SweepSpecError(f"--param {name}: the list of values is empty")
        for v in values:
            _check_range(name, v)
        return Axis(name, min(values), max(values), len(values), values=values)
    parts = spec.split(":")
    log = parts[0] == "log"
    if log:
        parts = parts[1:]
    if len(parts) not in (2, 3):
        raise SweepSpecError(f"--param {name}={spec}: need low:high:n (or low:high for --lhs)")
    low, high = _number(name, parts[0]), _number(name, parts[1])
    count = None
    if len(parts) == 3:
        try:
            count = int(parts[2])
        except ValueError:
            raise SweepSpecError(f"--param {name}: count {parts[2]!r} is not an integer") from None
        if count < 1:
            raise SweepSpecError(f"--param {name}: count {count}: the range is empty; need n >= 1")
        if count > MAX_POINTS:
            raise SweepSpecError(
                f"--param {name}: count {parts[2]:.40}: need 1 <= n <= {MAX_POINTS}"
            )
    if low > high:
        raise SweepSpecError(f"--param {name}: the range {low:g}:{high:g} is empty (low > high)")
    if count is not None and count > 1 and low == high:
        raise SweepSpecError(f"--param {name}: {count} values of one number {low:g}")
    if log and low <= 0:
        raise SweepSpecError(f"--param {name}: a log range needs low > 0, got {low:g}")
    _check_range(name, low)
    _check_range(name, high)
    return Axis(name, low, high, count, log)


def _number(name: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise SweepSpecError(f"--param {name}: {text.strip()!r} is not a number") from None
    if not math.isfinite(value):
        raise SweepSpecError(f"--param {name}: {text.strip()!r} is not finite")
    return value


def _check_range(name: str, value: float) -> None:
    low, high = ROBOTS_RANGE if name == ROBOTS else (PARAMS[name].low, PARAMS[name].high)
    if (low is not None and value < low) or (high is not None and value > high):
        raise SweepSpecError(
            f"--param {name}: {value:g} is out of range; allowed [{low:g}, {high:g}]"
        )


def points(axes: list[Axis], lhs: int | None = None, seed: int = 0) -> np.ndarray:
    """The sweep's points, (P, len(axes)): the grid, or ``lhs`` Latin-hypercube samples."""
    if not axes:
        raise SweepSpecError("--param: give at least one parameter to sweep")
    names = [a.name for a in axes]
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise SweepSpecError(f"--param {twice[0]}: given more than once")
    if lhs is not None:
        from scipy.stats import qmc

        if not 1 <= lhs <= MAX_POINTS:
            raise SweepSpecError(f"--lhs {str(lhs)[:40]}: need 1 to {MAX_POINTS} samples")
        unit = qmc.LatinHypercube(d=len(axes), seed=np.random.default_rng(seed)).random(lhs)
        return np.stack([a.scale(unit[:, j]) for j, a in enumerate(axes)], axis=1)
    size = math.prod(a.count or 1 for a in axes)
    if size > MAX_POINTS:
        raise SweepSpecError(f"--param: the grid has {size:.3g} points; at most {MAX_POINTS}")
    grids = [a.grid() for a in axes]
    mesh = np.meshgrid(*grids, indexing="ij")
    return np.stack([m.ravel() for m in mesh], axis=1)
