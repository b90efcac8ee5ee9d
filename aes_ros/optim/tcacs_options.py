"""The options of TCACS (:mod:`aes_ros.optim.tcacs`): the paper's, the reference's
defaults by dimension, and the checks of the options and the bounds that the minimiser
and the command line share (docs/design.md#tcacs-options)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from types import MappingProxyType
from typing import Any

import numpy as np

from aes_ros.optim.frame import WEIGHTINGS

#: The paper's options (docs/design.md#tcacs-options), the defaults of :func:`minimize`, of the
#: tuning and of ``aes-swarm optimize``; also the reference's defaults for n >= 4.
PAPER_OPTIONS: Mapping[str, Any] = MappingProxyType(
    {"n_ants": 15, "weighting": "roulette", "gamma": 0.5, "m": 2}
)
#: The paper's budget of cost evaluations (docs/design.md#tcacs-options).
DEFAULT_MAX_EVALS = 300
#: Default spatial convergence radius of the stop rule (docs/design.md#tcacs-step-7).
DEFAULT_TOL = 1e-4


def check_options(
    *,
    n_ants: int = PAPER_OPTIONS["n_ants"],
    weighting: str = PAPER_OPTIONS["weighting"],
    gamma: float = PAPER_OPTIONS["gamma"],
    m: float = PAPER_OPTIONS["m"],
    max_evals: int = DEFAULT_MAX_EVALS,
    tol: float = DEFAULT_TOL,
    labels: Mapping[str, str] | None = None,
) -> None:
    """Check the options of :func:`minimize`; raise ValueError naming the first bad one.

    Options left out take :func:`minimize`'s defaults. ``labels`` renames
    options in the messages, e.g. ``{"n_ants": "--ants"}`` for a command line;
    by default an option is called by its parameter name.

    Raises
    ------
    ValueError
        ``"<name>: …"`` when ``n_ants`` is not an integer >= 2, ``max_evals``
        is not an integer or is less than ``n_ants``, ``weighting`` is not one
        of :data:`WEIGHTINGS`, ``gamma`` is outside [0, 1], or ``m`` or ``tol``
        is negative or not finite.
    """
    name = {o: o for o in ("n_ants", "weighting", "gamma", "m", "max_evals", "tol")}
    name.update(labels or {})
    if isinstance(n_ants, bool) or not isinstance(n_ants, int | np.integer) or n_ants < 2:
        raise ValueError(f"{name['n_ants']}: {n_ants!r} is not allowed; need an integer >= 2")
    if isinstance(max_evals, bool) or not isinstance(max_evals, int | np.integer):
        raise ValueError(f"{name['max_evals']}: {max_evals!r} is not allowed; need an integer")
    if max_evals < n_ants:
        raise ValueError(
            f"{name['max_evals']}: {max_evals} is less than {name['n_ants']} ({n_ants}); "
            "need at least one iteration of ants"
        )
    if weighting not in WEIGHTINGS:
        raise ValueError(
            f"{name['weighting']}: {weighting!r} is not allowed; use one of {WEIGHTINGS}"
        )
    if not 0.0 <= gamma <= 1.0:
        raise ValueError(f"{name['gamma']}: {gamma!r} is not allowed; need a number in [0, 1]")
    if not (m >= 0 and math.isfinite(m)):
        raise ValueError(f"{name['m']}: {m!r} is not allowed; need a finite number >= 0")
    if not (tol >= 0 and math.isfinite(tol)):
        raise ValueError(f"{name['tol']}: {tol!r} is not allowed; need a finite number >= 0")


def n_iterations(max_evals: int, n_ants: int) -> int:
    """Iterations of a run: round(max_evals / n_ants), halves rounded up like the reference."""
    return max(1, math.floor(max_evals / n_ants + 0.5))


def default_options(n: int) -> dict[str, Any]:
    """The reference's default options for dimension n (docs/design.md#tcacs-reference).

    n < 4: 10 ants, rank weighting, γ = 1, m = 1; n >= 4: :data:`PAPER_OPTIONS`
    (15 ants, roulette, γ = 0.5, m = 2).
    """
    if n < 4:
        return {"n_ants": 10, "weighting": "rank", "gamma": 1.0, "m": 1}
    return dict(PAPER_OPTIONS)


def check_bounds(bounds: Sequence[tuple[float, float]]) -> tuple[np.ndarray, np.ndarray]:
    """The lower and upper bounds (n,) of ``bounds``, n >= 2 (low, high) pairs of finite
    numbers with low < high; ValueError naming what is wrong otherwise."""
    try:
        b = np.asarray(bounds, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"bounds: {bounds!r} is not a sequence of (low, high) pairs") from None
    if b.size == 0:
        raise ValueError("bounds: empty; need one (low, high) pair per variable")
    if b.ndim != 2 or b.shape[1] != 2:
        raise ValueError(f"bounds: need a sequence of (low, high) pairs; got shape {b.shape}")
    if len(b) < 2:
        raise ValueError("bounds: TCACS needs n >= 2 variables; got n = 1")
    if not np.isfinite(b).all():
        raise ValueError("bounds: every low and high must be finite")
    bad = np.flatnonzero(b[:, 0] >= b[:, 1])
    if len(bad):
        i = int(bad[0])
        raise ValueError(
            f"bounds: variable {i} has low {b[i, 0]:g} >= high {b[i, 1]:g} (reversed or empty)"
        )
    return b[:, 0].copy(), b[:, 1].copy()
