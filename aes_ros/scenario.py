"""Scenarios: the paper's three setups as editable YAML files (docs/design.md#scenarios).

A scenario is a flat mapping of the parameters in :data:`aes_ros.params.PARAMS`.
The packaged files ``aes_ros/scenarios/{linear,rotation,combined}.yaml`` hold
the paper's Table 1; users copy one, edit it, and pass it by path. Any value
can then be overridden (``--set name=value`` on the CLI).
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from aes_ros import formations
from aes_ros.model import Gains, SwarmCommand
from aes_ros.params import PARAMS, ParameterError, validate_params

SETUPS = ("linear", "rotation", "combined")
#: Every packaged scenario a name loads: the paper's setups and ``cluttered`` (posts across
#: the path, obstacle avoidance on; docs/model.md, "Obstacle avoidance").
PACKAGED = (*SETUPS, "cluttered")


@dataclass(frozen=True)
class Scenario:
    """A validated scenario: every parameter of PARAMS, by name."""

    values: dict[str, Any]

    def __getattr__(self, name: str) -> Any:
        if name == "values" or name.startswith("__"):
            # not set yet (unpickling, copying): no recursion into self.values
            raise AttributeError(name)
        try:
            return self.values[name]
        except KeyError:
            raise AttributeError(name) from None

    def with_overrides(self, overrides: dict[str, Any], source: str = "") -> Scenario:
        """A copy with some values replaced (validated)."""
        return Scenario({**self.values, **validate_params(overrides, source)})

    @property
    def gains(self) -> Gains:
        return Gains.from_mapping(self.values)

    @property
    def command(self) -> SwarmCommand:
        center = self.rotation_center
        return SwarmCommand(
            direction=tuple(self.direction),
            omega=self.omega,
            center=None if center == "centroid" else tuple(center),
        )

    @property
    def n_steps(self) -> int:
        """Number of Euler steps to cover ``duration``."""
        return round(self.duration / self.dt)

    def nominal_positions(self) -> np.ndarray:
        """The formation's nominal positions (N, 2) [m]."""
        if self.formation == "grid":
            return formations.square_grid(self.rows, self.cols, self.spacing)
        if self.formation == "hex":
            return formations.hexagonal_sheet(self.rings, self.spacing)
        if not self.formation_file:
            raise ParameterError("formation_file: required when formation is 'csv'")
        return formations.from_csv(self.formation_file)

    def with_robots(self, n: int) -> Scenario:
        """The same scenario on a grid of ``n`` robots: rows x cols with rows the
        largest divisor of n not above sqrt(n) (16 -> 4x4, 100 -> 10x10, 12 -> 3x4)."""
        if n < 1:
            raise ParameterError(f"num_robots: {n} is not allowed; need an integer >= 1")
        rows = max(r for r in range(1, int(np.sqrt(n)) + 1) if n % r == 0)
        return self.with_overrides({"formation": "grid", "rows": rows, "cols": n // rows})

    def initial_state(self, seed: int) -> tuple[np.ndarray, np.ndarray]:
        """Start of the run with this seed: positions (N, 2) [m], headings (N,) [rad].

        Identical to the start of :func:`aes_ros.simulator.simulate` with the
        same seed, so the ROS system and the offline simulator can begin alike.
        """
        return formations.perturbed_start(
            self.nominal_positions(), self.spacing, self.perturbation, np.random.default_rng(seed)
        )

    def sheet(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nominal positions (N, 2), neighbours (N, K) and rest lengths (N, K)."""
        nominal = self.nominal_positions()
        neighbors, rest = formations.neighbor_table(nominal, self.neighbor_factor * self.spacing)
        return nominal, neighbors, rest


def defaults() -> dict[str, Any]:
    return {name: spec.default for name, spec in PARAMS.items()}


def load(setup_or_path: str | Path, overrides: dict[str, Any] | None = None) -> Scenario:
    """Load a packaged setup by name or a scenario file by path, then apply overrides.

    Raises ParameterError naming the file and the offending key.
    """
    text, source = _read(setup_or_path)
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise ParameterError(f"{source}: not valid YAML{where}") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ParameterError(f"{source}: expected a mapping of parameter: value")
    scenario = Scenario({**defaults(), **validate_params(data, source)})
    if overrides:
        scenario = scenario.with_overrides(overrides, "--set")
    return scenario


def _read(setup_or_path: str | Path) -> tuple[str, str]:
    name = str(setup_or_path)
    if name in PACKAGED:
        return resources.files("aes_ros").joinpath(f"scenarios/{name}.yaml").read_text(), name
    path = Path(name)
    if not path.suffix:
        raise ParameterError(f"setup: unknown setup {name!r}; allowed: {', '.join(PACKAGED)}")
    try:
        return path.read_text(), str(path)
    except OSError as exc:
        raise ParameterError(f"scenario: cannot read {name!r} ({exc.strerror})") from None


def parse_assignments(items: list[str]) -> dict[str, Any]:
    """Parse ``name=value`` strings from the CLI (values stay strings; validated later)."""
    out: dict[str, Any] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise ParameterError(f"--set: {item!r} is not of the form name=value")
        out[name.strip()] = value.strip()
    return out
