"""TCACS, the tabu continuous ant colony system (Karimi, Nobahari & Siarry 2010).

See docs/design.md#tcacs.

A box-constrained global minimiser for n >= 2 variables. It keeps the best
point found so far and samples each iteration's ants from a Gaussian centred
on it, in a rotated frame fitted to a list of good ("promising") points, while
refusing candidates inside small "tabu balls" around bad points. One
iteration's ants are evaluated as one batch: ``f`` maps ``(k, n)`` candidates
to ``(k,)`` costs, so the swarm simulator can run all ants (× all Monte-Carlo
runs) in one kernel call.

Public interface: :func:`minimize` (thin function) over :class:`TCACSSolver`
(the state machine). Their options, the check both share with the command line
(:func:`check_options`) and the paper's options (:data:`PAPER_OPTIONS`) are in
:mod:`aes_ros.optim.tcacs_options` and importable from here too. The rotated
sampling frame and its spread (steps 5–6) are in :mod:`aes_ros.optim.frame`,
the standard test functions it
is validated on are in :mod:`aes_ros.optim.benchmarks`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from scipy.optimize import OptimizeResult

from aes_ros.optim.frame import fit_frame, spread_weights
from aes_ros.optim.tcacs_options import (
    DEFAULT_MAX_EVALS,
    DEFAULT_TOL,
    PAPER_OPTIONS,
    check_bounds,
    check_options,
    n_iterations,
)

#: Seeding: retries per seed point before the last draw is accepted anyway (the
#: reference implementation has no cap and can hang).
MAX_SEED_RETRIES = 10_000
#: Sampling: consecutive tabu rejections after which the next candidate is accepted.
MAX_TABU_REJECTIONS = 1000
#: Sampling: Gaussian redraws to land in the box before the draw is clipped into it.
MAX_BOX_RETRIES = 10_000
#: Candidates drawn at once while sampling (only speeds the Python loop up).
_DRAW_BLOCK = 64


def minimize(
    f: Callable[[np.ndarray], np.ndarray],
    bounds: Sequence[tuple[float, float]],
    *,
    n_ants: int = PAPER_OPTIONS["n_ants"],
    weighting: str = PAPER_OPTIONS["weighting"],
    gamma: float = PAPER_OPTIONS["gamma"],
    m: float = PAPER_OPTIONS["m"],
    max_evals: int = DEFAULT_MAX_EVALS,
    tol: float = DEFAULT_TOL,
    seed: int | np.random.Generator | None = None,
    callback: Callable[[OptimizeResult], bool | None] | None = None,
) -> OptimizeResult:
    """Minimise ``f`` over a box with TCACS (docs/design.md#tcacs).

    Parameters
    ----------
    f : callable
        Batched objective: ``f(X)`` with ``X`` of shape ``(k, n)`` returns the
        ``(k,)`` costs. Each iteration's ants are passed in one call. NaN
        costs are treated as +inf (worst possible).
    bounds : sequence of (low, high)
        The box [a, b]; n = len(bounds) >= 2 and low < high for every variable.
    n_ants : int
        Ants per iteration; also the sizes P and T of the promising and tabu lists.
    weighting : {"roulette", "rank"}
        How the promising points weigh in the spread σ (docs/design.md#tcacs-step-6).
    gamma : float in [0, 1]
        Share of the cost term in the weights (the rest is the distance term).
    m : float >= 0
        The "PCA factor": axes are picked with probability ∝ ‖c‖^(2m).
        ``n_ants``, ``weighting``, ``gamma`` and ``m`` default to the paper's
        :data:`PAPER_OPTIONS` (15 ants, roulette, γ = 0.5, m = 2).
    max_evals : int >= n_ants
        Budget (default the paper's 300); the run has round(max_evals / n_ants)
        iterations, so ``nfev`` can exceed ``max_evals`` by up to n_ants / 2
        (1000 evaluations with 15 ants gives 67 iterations, 1005 evaluations).
    tol : float >= 0
        Spatial convergence radius: stop as soon as every promising point lies
        within ``tol`` of the best point.
    seed : None, int or numpy.random.Generator
        Source of all randomness; the same seed gives the same run.
    callback : callable, optional
        ``callback(intermediate_result)`` after every iteration, with ``x``,
        ``fun``, ``nit`` and ``nfev``; returning True stops the run.

    Returns
    -------
    OptimizeResult
        ``x`` (best point), ``fun`` (its cost), ``nfev`` (candidates
        evaluated, not calls of ``f``), ``nit`` (iterations), ``success``,
        ``status`` (0: budget used, 1: converged within ``tol``, 2: stopped by
        the callback), ``message``, and the history of every evaluation in
        order: ``history_x`` (nfev, n), ``history_fun`` (nfev,) and
        ``history_nit`` (nfev,), the iteration of each evaluation.

    Raises
    ------
    ValueError
        Naming the argument: bad bounds (empty, n = 1, reversed or not
        finite), a bad option (see :func:`check_options`), or ``f`` returning
        the wrong shape.

    Notes
    -----
    The algorithm follows docs/design.md#tcacs step by step (the authors' reference
    implementation): two seeding iterations of uniform points s₀ apart, then Gaussian
    sampling around x_best in a frame fitted to the promising points, outside the tabu
    balls. It deviates only where the reference is undefined or can hang (capped
    retries, zero-length axes, NaN costs; docs/design.md#tcacs-deviations), and draws
    all of an iteration's ants before evaluating any (one batch).

    References
    ----------
    .. [1] A. Karimi, H. Nobahari, P. Siarry, "Continuous ant colony system and
       tabu search algorithms hybridized for global minimization of continuous
       multi-minima functions", Comput. Optim. Appl. 45 (2010) 639–661.
    .. [2] M. Raoufi, A. E. Turgut, F. Arvin, "Self-organized collective motion
       with a simulated real robot swarm", TAROS 2019 (TCACS tuning of α, β, k).

    Examples
    --------
    >>> import numpy as np
    >>> from aes_ros.optim.tcacs import minimize
    >>> res = minimize(lambda X: np.sum(X**2, axis=1), [(-5, 5), (-5, 5)],
    ...                n_ants=10, weighting="rank", gamma=1.0, m=1,
    ...                max_evals=2000, seed=1)
    >>> bool(res.fun < 1e-6)
    True
    """
    solver = TCACSSolver(
        f,
        bounds,
        n_ants=n_ants,
        weighting=weighting,
        gamma=gamma,
        m=m,
        max_evals=max_evals,
        tol=tol,
        seed=seed,
        callback=callback,
    )
    return solver.solve()


class TCACSSolver:
    """The TCACS state machine behind :func:`minimize` (same parameters).

    State (docs/design.md#tcacs): ``x_best``/``f_best``; ``sigma`` (one value per rotated
    axis) and ``R`` (axes as rows); the promising and tabu lists
    (``promising_x``/``promising_f``, ``tabu_x``/``tabu_f``); ``r_tabu``.
    :meth:`solve` runs the whole optimisation; :meth:`sample` and
    :meth:`update_lists` are the steps, exposed for tests.
    """

    def __init__(
        self,
        f: Callable[[np.ndarray], np.ndarray],
        bounds: Sequence[tuple[float, float]],
        *,
        n_ants: int = PAPER_OPTIONS["n_ants"],
        weighting: str = PAPER_OPTIONS["weighting"],
        gamma: float = PAPER_OPTIONS["gamma"],
        m: float = PAPER_OPTIONS["m"],
        max_evals: int = DEFAULT_MAX_EVALS,
        tol: float = DEFAULT_TOL,
        seed: int | np.random.Generator | None = None,
        callback: Callable[[OptimizeResult], bool | None] | None = None,
    ) -> None:
        self.lower, self.upper = check_bounds(bounds)
        self.n = len(self.lower)
        check_options(
            n_ants=n_ants, weighting=weighting, gamma=gamma, m=m, max_evals=max_evals, tol=tol
        )
        self.f, self.callback = f, callback
        self.n_ants, self.weighting = int(n_ants), weighting
        self.gamma, self.m, self.tol = float(gamma), float(m), float(tol)
        self.max_evals = int(max_evals)
        self.n_iterations = n_iterations(self.max_evals, self.n_ants)
        self.rng = np.random.default_rng(seed)
        width = self.upper - self.lower
        #: Minimum distance between seed points, s₀ = (0.7·Π(b−a)/n_ants)^(1/n).
        self.s0 = (0.7 * float(np.prod(width)) / self.n_ants) ** (1.0 / self.n)
        self.sigma = 4.0 * width
        self.R = np.eye(self.n)
        self.r_tabu = math.inf
        self.x_best = np.full(self.n, np.nan)
        self.f_best = math.inf
        empty_x, empty_f = np.empty((0, self.n)), np.empty(0)
        self.promising_x, self.promising_f = empty_x, empty_f
        self.tabu_x, self.tabu_f = empty_x, empty_f
        self._seed_buffer = np.zeros((self.n_ants, self.n))
        self._history: list[tuple[np.ndarray, np.ndarray, int]] = []
        self.nfev = 0
        self.nit = 0

    # --- steps -------------------------------------------------------------
    def seed_points(self) -> np.ndarray:
        """One seeding iteration (docs/design.md#tcacs-step-2): n_ants uniform points, s₀ apart.

        A draw closer than s₀ to any slot of the buffer (earlier points of this
        iteration, and the slots not yet overwritten: the origin in iteration 1,
        the previous seeds in iteration 2) is redrawn, at most MAX_SEED_RETRIES
        times. Returns (n_ants, n); the buffer then holds these points.
        """
        buf = self._seed_buffer
        for i in range(self.n_ants):
            for _ in range(MAX_SEED_RETRIES):
                x = self.rng.uniform(self.lower, self.upper)
                if np.min(np.linalg.norm(buf - x, axis=1)) >= self.s0:
                    break
            buf[i] = x
        return buf.copy()

    def sample(self) -> np.ndarray:
        """Draw one iteration's ants around x_best (docs/design.md#tcacs-step-3): (n_ants, n).

        x = x_best + Rᵀ(σ ⊙ z), z ~ N(0, I), redrawn until inside the box; a
        candidate within r_tabu of a tabu point is rejected unless more than
        MAX_TABU_REJECTIONS candidates in a row were rejected.
        """
        ants = np.empty((self.n_ants, self.n))
        scaled_axes = self.sigma[:, None] * self.R  # rows σ_d u_d, so z @ this = Rᵀ(σ ⊙ z)
        check_tabu = len(self.tabu_x) > 0 and math.isfinite(self.r_tabu)
        i, rejections, box_misses = 0, 0, 0
        while i < self.n_ants:
            block = self.x_best + self.rng.standard_normal((_DRAW_BLOCK, self.n)) @ scaled_axes
            inside = np.all((block >= self.lower) & (block <= self.upper), axis=1)
            if check_tabu:
                dist = np.linalg.norm(block[:, None, :] - self.tabu_x[None], axis=2)
                tabu = np.any(dist < self.r_tabu, axis=1)
            else:
                tabu = np.zeros(_DRAW_BLOCK, dtype=bool)
            for x, ok, bad in zip(block, inside, tabu, strict=True):
                if not ok:
                    box_misses += 1
                    if box_misses < MAX_BOX_RETRIES:
                        continue
                    x = np.clip(x, self.lower, self.upper)  # deviation: capped redraws
                    bad = check_tabu and bool(
                        np.any(np.linalg.norm(self.tabu_x - x, axis=1) < self.r_tabu)
                    )
                box_misses = 0
                if bad and rejections <= MAX_TABU_REJECTIONS:
                    rejections += 1
                    continue
                ants[i] = x
                i, rejections = i + 1, 0
                if i == self.n_ants:
                    break
        return ants

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        """Evaluate one batch, record it, update x_best (strictly lower cost only)."""
        y = np.asarray(self.f(X), dtype=float)
        if y.shape != (len(X),):
            raise ValueError(f"f: returned shape {y.shape}; expected ({len(X)},) for {X.shape} X")
        y = np.where(np.isnan(y), np.inf, y)
        self.nfev += len(X)
        self._history.append((X.copy(), y.copy(), self.nit + 1))
        best = int(np.argmin(y))  # first of equal minima
        if y[best] < self.f_best:
            self.x_best, self.f_best = X[best].copy(), float(y[best])
        return y

    def update_lists(self, X: np.ndarray, y: np.ndarray, sigma_used: np.ndarray) -> None:
        """Promising and tabu lists and r_tabu from the ants (docs/design.md#tcacs-step-4).

        ``sigma_used`` is σ as used for this iteration's sampling; x_best must
        already include this iteration's update.
        """
        pool_x = np.vstack([X, self.tabu_x, self.promising_x])
        pool_f = np.concatenate([y, self.tabu_f, self.promising_f])
        order = np.argsort(pool_f, kind="stable")
        P = T = self.n_ants
        best, rest = order[:P], order[P:]
        near = np.all(np.abs(pool_x[rest] - self.x_best) < 3.0 * sigma_used, axis=1)
        tabu = rest[near][-T:] if T > 0 else rest[:0]
        self.promising_x, self.promising_f = pool_x[best], pool_f[best]
        self.tabu_x, self.tabu_f = pool_x[tabu], pool_f[tabu]
        if len(tabu):
            d = np.linalg.norm(self.promising_x[:, None] - self.tabu_x[None], axis=2)
            self.r_tabu = 0.25 * float(d.min())
        else:
            self.r_tabu = math.inf

    def update_frame(self) -> None:
        """Rotation R and spread σ from the promising list (docs/design.md#tcacs-step-5, 6)."""
        self.R = fit_frame(self.promising_x, self.m, self.rng)
        z = self.promising_x @ self.R.T
        x_star = self.promising_x[0]
        dist = np.linalg.norm(self.promising_x[1:] - x_star, axis=1)
        W = spread_weights(self.promising_f[1:], dist, self.weighting, self.gamma)
        self.sigma = np.sqrt(W @ (z[1:] - z[0]) ** 2)

    def converged(self) -> bool:
        """Stop rule (docs/design.md#tcacs-step-7): every promising point within tol of x_best."""
        if len(self.promising_x) == 0:
            return False
        return bool(np.all(np.linalg.norm(self.promising_x - self.x_best, axis=1) <= self.tol))

    # --- driver ------------------------------------------------------------
    def solve(self) -> OptimizeResult:
        """Run all iterations (or until convergence or the callback says stop)."""
        status = 0
        seeds: list[tuple[np.ndarray, np.ndarray]] = []
        while self.nit < self.n_iterations:
            sigma_used = self.sigma.copy()
            X = self.seed_points() if self.nit < 2 else self.sample()
            y = self.evaluate(X)
            self.nit += 1
            if self.nit <= 2:
                seeds.append((X, y))
            if self.nit >= 2:
                if self.nit == 2:  # the 2·n_ants seeds are the first pool
                    X = np.vstack([s[0] for s in seeds])
                    y = np.concatenate([s[1] for s in seeds])
                self.update_lists(X, y, sigma_used)
                if self.converged():
                    status = 1
                elif self.nit < self.n_iterations:
                    self.update_frame()
            if self.callback is not None and self.callback(self._intermediate()):
                status = 2 if status == 0 else status
            if status:
                break
        return self._result(status)

    def _intermediate(self) -> OptimizeResult:
        return OptimizeResult(x=self.x_best.copy(), fun=self.f_best, nit=self.nit, nfev=self.nfev)

    def _result(self, status: int) -> OptimizeResult:
        messages = {
            0: f"used the budget of {self.n_iterations} iterations",
            1: f"converged: every promising point within tol = {self.tol:g} of the best",
            2: "stopped by the callback",
        }
        if self._history:
            hx = np.vstack([h[0] for h in self._history])
            hf = np.concatenate([h[1] for h in self._history])
            hn = np.concatenate([np.full(len(h[1]), h[2]) for h in self._history])
        else:
            hx, hf, hn = np.empty((0, self.n)), np.empty(0), np.empty(0, dtype=int)
        return OptimizeResult(
            x=self.x_best.copy(),
            fun=self.f_best,
            nfev=self.nfev,
            nit=self.nit,
            success=status in (0, 1),
            status=status,
            message=messages[status],
            history_x=hx,
            history_fun=hf,
            history_nit=hn,
        )
