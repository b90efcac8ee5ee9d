"""The tuning cost J(α, β, k) (E10), Monte-Carlo averaged with common random numbers.

See docs/design.md#cost.

    J = (1/N_MC) Σ_{m=1}^{N_MC} Σ_{t=0}^{t_f} [ w_1 F^t + w_2 ψ^t ]

with F the total force (E9) and ψ the force alignment (E8) at every sampled
instant 0, Δt, …, t_f of run m (T+1 terms), w_1 = 1/N and w_2 = −1 by default.
Lower is better: a good swarm has small forces (the sheet is relaxed and the
drives are met) and robots pointing along their forces.

*Common random numbers*: every candidate is simulated with the same N_MC
seeds, i.e. the same initial states and the same noise streams, so that the
difference between two candidates is not drowned in Monte-Carlo noise.

*One batch*: :meth:`MonteCarloCost.__call__` takes k candidates and simulates
all k × N_MC runs in one call of :func:`aes_ros.simulator.simulate` (one
kernel call with per-run gains), which is what makes the paper-scale tuning
run (300 candidates × 10 runs of 100 robots × 30 s) take seconds.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence

import numpy as np

from aes_ros.model import Gains
from aes_ros.scenario import Scenario
from aes_ros.simulator import SimResult, simulate

#: The decision variables of the paper's tuning (docs/design.md#tcacs-options), in this order.
TUNED_GAINS = ("alpha", "beta", "k")


class NonFiniteCostWarning(RuntimeWarning):
    """A candidate's simulation blew up (NaN/inf); its cost counts as +inf."""


def run_costs(result: SimResult, w1: float, w2: float) -> np.ndarray:
    """Per-run cost Σ_t [w_1 F^t + w_2 ψ^t] (the summand of E10), shape (B,).

    Non-finite sums (an exploding run) are returned as they are (NaN or inf).
    """
    force = result.metric("total_force")
    psi = result.metric("alignment")
    with np.errstate(invalid="ignore", over="ignore"):
        return np.sum(w1 * force + w2 * psi, axis=-1)


def default_weights(n_robots: int) -> tuple[float, float]:
    """(w_1, w_2) = (1/N, −1), the paper's default weights (docs/design.md#cost)."""
    return 1.0 / n_robots, -1.0


class MonteCarloCost:
    """The batched cost J (E10) of gain candidates on one scenario.

    Parameters
    ----------
    scenario : the scenario (formation, command, noise, Δt, t_f); its other
        gains (v0, w_l, …) are kept, only ``names`` are replaced per candidate.
    n_mc : N_MC, the number of Monte-Carlo runs per candidate (10 in the paper).
    w1, w2 : weights of the total force and of the alignment; ``w1=None``
        means 1/N for the scenario's N.
    seeds : the N_MC seeds (common random numbers); default
        ``range(seed, seed + n_mc)``.
    seed : first seed when ``seeds`` is not given.
    names : the gain fields the columns of a candidate stand for.

    Calling the object with candidates ``X`` of shape (k, len(names)) returns
    J of each, shape (k,); all k·N_MC runs go through one ``simulate`` call.
    A candidate whose simulation is not finite costs +inf; the first such
    candidate raises one :class:`NonFiniteCostWarning`, later ones are only
    counted in ``n_nonfinite``. ``nfev`` counts candidates.
    """

    def __init__(
        self,
        scenario: Scenario,
        *,
        n_mc: int = 10,
        w1: float | None = None,
        w2: float = -1.0,
        seeds: Sequence[int] | None = None,
        seed: int = 0,
        names: Sequence[str] = TUNED_GAINS,
    ) -> None:
        n_robots = len(scenario.nominal_positions())
        if seeds is None:
            if int(n_mc) < 1:
                raise ValueError(f"n_mc: {n_mc} is not allowed; need an integer >= 1")
            seeds = range(int(seed), int(seed) + int(n_mc))
        self.seeds = [int(s) for s in seeds]
        if not self.seeds:
            raise ValueError("seeds: need at least one Monte-Carlo seed")
        gain_fields = {f.name for f in dataclasses.fields(Gains)}
        for name in names:
            if name not in gain_fields:
                raise ValueError(f"names: {name!r} is not a gain; allowed: {sorted(gain_fields)}")
        self.scenario = scenario
        self.names = tuple(names)
        self.n_robots = n_robots
        self.w1 = 1.0 / n_robots if w1 is None else float(w1)
        self.w2 = float(w2)
        for label, value in (("w1", self.w1), ("w2", self.w2)):
            if not np.isfinite(value):
                raise ValueError(f"{label}: {value!r} is not allowed; need a finite number")
        self.nfev = 0
        self.n_nonfinite = 0

    @property
    def n_mc(self) -> int:
        return len(self.seeds)

    def gains(self, x: Sequence[float]) -> Gains:
        """The scenario's gains with ``names`` replaced by the candidate ``x``."""
        return dataclasses.replace(
            self.scenario.gains, **{n: float(v) for n, v in zip(self.names, x, strict=True)}
        )

    def runs(self, X: np.ndarray) -> np.ndarray:
        """Per-run costs (k, N_MC) of candidates X (k, len(names)); NaN/inf kept."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if X.ndim != 2 or X.shape[1] != len(self.names):
            raise ValueError(
                f"X: need shape (k, {len(self.names)}) for {', '.join(self.names)}; got {X.shape}"
            )
        if len(X) == 0:
            return np.empty((0, self.n_mc))
        gains = [self.gains(x) for x in X for _ in self.seeds]
        with np.errstate(all="ignore"):
            result = simulate(self.scenario, self.seeds * len(X), gains=gains, record=False)
        return run_costs(result, self.w1, self.w2).reshape(len(X), self.n_mc)

    def __call__(self, X: np.ndarray) -> np.ndarray:
        """J (E10) of each candidate, shape (k,); non-finite -> +inf (one warning)."""
        J = self.runs(X).mean(axis=1)
        self.nfev += len(J)
        bad = ~np.isfinite(J)
        if bad.any():
            if self.n_nonfinite == 0:
                x = np.atleast_2d(np.asarray(X, dtype=float))[np.flatnonzero(bad)[0]]
                values = ", ".join(f"{n}={v:.4g}" for n, v in zip(self.names, x, strict=True))
                warnings.warn(
                    f"the simulation of candidate {values} is not finite (the sheet blew up); "
                    "its cost counts as +inf (further such candidates are only counted)",
                    NonFiniteCostWarning,
                    stacklevel=2,
                )
            self.n_nonfinite += int(bad.sum())
            J = np.where(bad, np.inf, J)
        return J
