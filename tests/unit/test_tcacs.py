"""TCACS (docs/design.md#tcacs): contracts, the steps of the algorithm, and the reference behaviour.

The validation test runs each reference function 25 times (the full 100-run
table is ``bench/bench_tcacs.py``). Tolerances: the success rate may fall at
most 0.15 below the reference (3 failures in 25 more than expected) and the
mean evaluation count must be within ±30 % of the reference (about 4 standard
errors at 25 runs); a broken spread, frame or tabu rule moves these by far more.
"""

from __future__ import annotations

import inspect
import itertools
import math

import numpy as np
import pytest

from aes_ros.optim import tcacs
from aes_ros.optim.benchmarks import BENCHMARKS
from aes_ros.optim.frame import fit_frame, spread_weights
from aes_ros.optim.tcacs import PAPER_OPTIONS, TCACSSolver, check_options, minimize
from aes_ros.optim.tcacs_options import default_options

REFERENCE = [name for name, b in BENCHMARKS.items() if b.ref_success is not None]


@pytest.mark.parametrize("name", REFERENCE)
def test_reference_behaviour(name: str) -> None:
    b = BENCHMARKS[name]
    runs = [
        minimize(b.f, b.bounds, **default_options(len(b.bounds)), max_evals=10_000, seed=s)
        for s in range(25)
    ]
    success = np.mean([b.success(r.fun) for r in runs])
    evals = np.mean([r.nfev for r in runs])
    assert success >= b.ref_success - 0.15, f"success {success:.2f} vs reference {b.ref_success}"
    assert 0.7 * b.ref_evals <= evals <= 1.3 * b.ref_evals, f"{evals:.0f} vs {b.ref_evals}"


def test_branin_minimum_found_in_most_runs_with_paper_options() -> None:
    """The paper's options (15 ants, roulette, γ = 0.5, m = 2) also solve Branin."""
    b = BENCHMARKS["branin"]
    funs = [minimize(b.f, b.bounds, max_evals=3000, seed=s).fun for s in range(10)]
    assert sum(b.success(f) for f in funs) >= 8


def test_nfev_counts_candidates_and_f_gets_one_batch_per_iteration() -> None:
    calls: list[int] = []

    def f(X: np.ndarray) -> np.ndarray:
        calls.append(len(X))
        return np.sum(X, axis=1)  # linear: never converges spatially with tol = 0

    res = minimize(f, [(0, 1), (0, 1), (0, 1)], max_evals=1000, tol=0.0, seed=0)
    assert res.nit == 67 and res.nfev == 1005  # round(1000 / 15) iterations
    assert calls == [15] * 67
    assert res.history_x.shape == (1005, 3) and res.history_fun.shape == (1005,)
    assert np.array_equal(np.bincount(res.history_nit)[1:], [15] * 67)
    res = minimize(f, [(0, 1), (0, 1)], max_evals=300, tol=0.0, seed=0)
    assert res.nfev == 300 and res.nit == 20 and res.status == 0 and res.success


def test_result_is_the_best_of_the_history() -> None:
    b = BENCHMARKS["goldstein_price"]
    res = minimize(b.f, b.bounds, max_evals=300, seed=3)
    i = int(np.argmin(res.history_fun))
    assert res.fun == res.history_fun[i]
    assert np.array_equal(res.x, res.history_x[i])
    lo, hi = np.array(b.bounds).T
    assert np.all((res.history_x >= lo) & (res.history_x <= hi))


def test_same_seed_same_run_other_seed_other_run() -> None:
    b = BENCHMARKS["hartmann3"]
    r1, r2 = (minimize(b.f, b.bounds, max_evals=300, seed=7) for _ in range(2))
    r3 = minimize(b.f, b.bounds, max_evals=300, seed=8)
    assert np.array_equal(r1.history_x, r2.history_x)
    assert not np.array_equal(r1.history_x, r3.history_x)


def test_equal_cost_keeps_the_earlier_point() -> None:
    res = minimize(lambda X: np.zeros(len(X)), [(0, 1), (0, 1)], max_evals=60, seed=0)
    assert np.array_equal(res.x, res.history_x[0])


def test_nan_costs_count_as_worst_and_do_not_crash() -> None:
    def f(X: np.ndarray) -> np.ndarray:
        y = np.sum((X - 0.3) ** 2, axis=1)
        return np.where(X[:, 0] > 0.6, np.nan, y)

    res = minimize(f, [(0, 1), (0, 1)], max_evals=600, seed=1)
    assert math.isfinite(res.fun) and res.fun < 1e-4
    assert np.all(np.isinf(res.history_fun[res.history_x[:, 0] > 0.6]))


def test_callback_sees_progress_and_can_stop() -> None:
    seen = []

    def cb(r) -> bool:
        seen.append((r.nit, r.nfev, r.fun))
        return r.nit == 3

    res = minimize(BENCHMARKS["branin"].f, BENCHMARKS["branin"].bounds, callback=cb, seed=0)
    assert [s[:2] for s in seen] == [(1, 15), (2, 30), (3, 45)]
    assert res.nit == 3 and res.status == 2 and not res.success
    assert all(a[2] >= b[2] for a, b in itertools.pairwise(seen))


def test_spatial_stop_rule() -> None:
    b = BENCHMARKS["sphere3"]
    res = minimize(b.f, b.bounds, **default_options(3), max_evals=10_000, tol=1e-4, seed=0)
    assert res.status == 1 and res.nfev < 10_000


# --- the steps --------------------------------------------------------------------------


@pytest.mark.parametrize("weighting", ["roulette", "rank"])
@pytest.mark.parametrize("gamma", [0.0, 0.3, 1.0])
def test_weights_sum_to_one_and_are_non_negative(weighting: str, gamma: float) -> None:
    rng = np.random.default_rng(0)
    for size in (1, 2, 9, 14):
        w = spread_weights(rng.normal(size=size), rng.uniform(size=size), weighting, gamma)
        assert w.shape == (size,)
        assert np.all(w >= 0) and w.sum() == pytest.approx(1.0)


def test_roulette_weights_by_hand() -> None:
    # costs 1, 2, 4 -> y_max - y = 3, 2, 0 -> 3/5, 2/5, 0
    # distances 1, 3, 2 -> d - d_min = 0, 2, 1 -> 0, 2/3, 1/3
    w = spread_weights(np.array([1.0, 2.0, 4.0]), np.array([1.0, 3.0, 2.0]), "roulette", 0.5)
    assert w == pytest.approx([0.5 * 3 / 5, 0.5 * 2 / 5 + 0.5 * 2 / 3, 0.5 * 1 / 3])
    # each term uniform where its values are all equal
    w = spread_weights(np.array([2.0, 2.0]), np.array([1.0, 3.0]), "roulette", 0.5)
    assert w == pytest.approx([0.25, 0.75])
    # a non-finite cost counts as the worst finite one (weight 0) instead of making all NaN
    w = spread_weights(np.array([1.0, 2.0, np.inf]), np.ones(3), "roulette", 1.0)
    assert w == pytest.approx([1.0, 0.0, 0.0])
    w = spread_weights(np.array([1.0, 3.0, 2.0, np.inf]), np.ones(4), "roulette", 1.0)
    assert w == pytest.approx([2 / 3, 0.0, 1 / 3, 0.0])


def test_rank_weights_by_hand() -> None:
    # cost scores 3 (lowest) … 1; distance scores 3 (farthest) … 1
    w = spread_weights(np.array([5.0, 1.0, 3.0]), np.array([2.0, 1.0, 3.0]), "rank", 0.5)
    cost_score, dist_score = np.array([1, 3, 2]), np.array([2, 1, 3])
    expected = 0.5 * cost_score + 0.5 * dist_score
    assert w == pytest.approx(expected / expected.sum())


def test_seeding_keeps_points_s0_apart_and_away_from_the_origin() -> None:
    solver = TCACSSolver(lambda X: X[:, 0], [(-1, 1), (-1, 1)], n_ants=10, seed=0)
    first = solver.seed_points()
    second = solver.seed_points()
    s0 = solver.s0
    assert s0 == pytest.approx((0.7 * 4 / 10) ** 0.5)
    assert np.all(np.linalg.norm(first, axis=1) >= s0)  # iteration 1: not within s0 of 0
    d = np.linalg.norm(first[:, None] - first[None], axis=2)[np.triu_indices(len(first), 1)]
    assert d.min() >= s0
    # iteration 2: each point is s0 from every point of iteration 1 it had not yet replaced
    for i, x in enumerate(second):
        assert np.all(np.linalg.norm(first[i:] - x, axis=1) >= s0)
        assert np.all(np.linalg.norm(second[:i] - x, axis=1) >= s0)


def test_seeding_retries_are_capped(monkeypatch: pytest.MonkeyPatch) -> None:
    """A box too small for n_ants points s0 apart still seeds (the reference would hang)."""
    monkeypatch.setattr(tcacs, "MAX_SEED_RETRIES", 50)
    solver = TCACSSolver(lambda X: X[:, 0], [(0, 1e-3), (0, 1e-3)], n_ants=5, seed=0)
    solver.s0 = 1.0  # no point of the box is 1 away from the origin
    assert solver.seed_points().shape == (5, 2)


def _solver_at_centre(tabu_radius: float) -> TCACSSolver:
    solver = TCACSSolver(lambda X: X[:, 0], [(-1, 1), (-1, 1)], n_ants=15, seed=0)
    solver.x_best = np.zeros(2)
    solver.sigma = np.array([0.3, 0.3])
    solver.tabu_x = np.array([[0.0, 0.0], [0.2, 0.0]])
    solver.r_tabu = tabu_radius
    return solver


def test_tabu_balls_reject_candidates() -> None:
    solver = _solver_at_centre(0.15)
    ants = np.vstack([solver.sample() for _ in range(20)])
    d = np.linalg.norm(ants[:, None] - solver.tabu_x[None], axis=2)
    assert d.min() >= 0.15
    free = _solver_at_centre(0.0)  # no tabu ball: the centre region is sampled
    ants = np.vstack([free.sample() for _ in range(20)])
    assert np.linalg.norm(ants, axis=1).min() < 0.15


def test_tabu_rejections_are_capped() -> None:
    """A tabu ball covering the box: after > 1000 rejections the next candidate is taken."""
    solver = _solver_at_centre(10.0)
    ants = solver.sample()
    assert ants.shape == (15, 2)
    assert np.all(np.abs(ants) <= 1)


def test_samples_stay_in_the_box_even_for_huge_sigma() -> None:
    solver = TCACSSolver(lambda X: X[:, 0], [(0, 1), (0, 1), (0, 1)], n_ants=15, seed=0)
    solver.x_best = np.zeros(3)  # a corner
    solver.sigma = np.full(3, 1e3)
    ants = solver.sample()
    assert np.all((ants >= 0) & (ants <= 1))


def test_lists_promising_best_tabu_worst_within_three_sigma() -> None:
    solver = TCACSSolver(lambda X: X[:, 0], [(-10, 10), (-10, 10)], n_ants=3, seed=0)
    X = np.array([[0.0, 0], [1, 0], [2, 0], [3, 0], [4, 0], [9, 0]])
    y = np.array([0.0, 1, 2, 3, 4, 9])
    solver.x_best = X[0]
    solver.update_lists(X, y, sigma_used=np.array([2.0, 2.0]))  # 3σ = 6: point 9 is out
    assert np.array_equal(solver.promising_f, [0, 1, 2])
    assert np.array_equal(solver.tabu_f, [3, 4])
    assert solver.r_tabu == pytest.approx(0.25 * 1.0)  # promising (2,0) to tabu (3,0)
    solver.update_lists(np.empty((0, 2)), np.empty(0), sigma_used=np.array([0.1, 0.1]))
    assert len(solver.tabu_f) == 0 and solver.r_tabu == math.inf


def test_frame_is_orthonormal_and_follows_the_promising_points() -> None:
    rng = np.random.default_rng(0)
    for n in (2, 3, 5):
        R = fit_frame(rng.normal(size=(10, n)), 2, rng)
        assert R @ R.T == pytest.approx(np.eye(n), abs=1e-12)
        assert R[-1].sum() > 0
    # points spread along (1, 1): the first axis is that direction (m large: the farthest)
    t = np.linspace(-1, 1, 9)
    pts = np.stack([t, t], axis=1) + 1e-3 * rng.normal(size=(9, 2))
    R = fit_frame(pts, 8, rng)
    assert abs(R[0] @ np.array([1, 1]) / np.sqrt(2)) == pytest.approx(1, abs=1e-3)
    # identical points: still an orthonormal frame
    R = fit_frame(np.ones((5, 3)), 2, rng)
    assert R @ R.T == pytest.approx(np.eye(3), abs=1e-12)


# --- bad input --------------------------------------------------------------------------


def _sphere(X: np.ndarray) -> np.ndarray:
    return np.sum(X**2, axis=1)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"bounds": [(1, 0), (0, 1)]}, "bounds"),
        ({"bounds": [(0, 0), (0, 1)]}, "bounds"),
        ({"bounds": []}, "bounds"),
        ({"bounds": [(0, 1)]}, "bounds"),
        ({"bounds": [(0, np.inf), (0, 1)]}, "bounds"),
        ({"max_evals": 10}, "max_evals"),
        ({"weighting": "wheel"}, "weighting"),
        ({"gamma": 1.5}, "gamma"),
        ({"n_ants": 1}, "n_ants"),
        ({"m": -1}, "m"),
        ({"tol": -1}, "tol"),
    ],
)
def test_bad_input_names_the_argument(kwargs: dict, field: str) -> None:
    args = {"bounds": [(0, 1), (0, 1)], **kwargs}
    with pytest.raises(ValueError, match=rf"^{field}:"):
        minimize(_sphere, **args)


def test_f_with_the_wrong_shape_is_reported() -> None:
    with pytest.raises(ValueError, match=r"^f:"):
        minimize(lambda X: np.zeros((len(X), 2)), [(0, 1), (0, 1)])


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"n_ants": 1}, "n_ants"),
        ({"n_ants": 2.5}, "n_ants"),
        ({"n_ants": True}, "n_ants"),
        ({"max_evals": 300.0}, "max_evals"),
        ({"max_evals": 14}, "max_evals"),
        ({"n_ants": 40, "max_evals": 39}, "max_evals"),
        ({"weighting": "wheel"}, "weighting"),
        ({"gamma": -0.1}, "gamma"),
        ({"gamma": math.nan}, "gamma"),
        ({"m": -1}, "m"),
        ({"m": math.inf}, "m"),
        ({"tol": -1e-9}, "tol"),
        ({"tol": math.nan}, "tol"),
    ],
)
def test_check_options_names_the_bad_option_and_minimize_uses_it(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=rf"^{field}:"):
        check_options(**kwargs)
    with pytest.raises(ValueError, match=rf"^{field}:"):
        minimize(_sphere, [(0, 1), (0, 1)], **kwargs)


def test_check_options_accepts_the_defaults_and_names_options_by_their_labels() -> None:
    check_options()
    check_options(**PAPER_OPTIONS, max_evals=15, tol=0.0)
    for n in (2, 3, 4, 6):
        check_options(**default_options(n))
    labels = {"n_ants": "--ants", "max_evals": "--evals"}
    with pytest.raises(ValueError, match=r"^--ants: 1 is not allowed"):
        check_options(n_ants=1, labels=labels)
    with pytest.raises(ValueError, match=r"^--evals: 10 is less than --ants \(15\)"):
        check_options(max_evals=10, labels=labels)
    with pytest.raises(ValueError, match=r"^gamma:"):  # options without a label keep their name
        check_options(gamma=2.0, labels=labels)


def test_paper_options_are_the_defaults_of_minimize_and_the_solver() -> None:
    assert dict(PAPER_OPTIONS) == {"n_ants": 15, "weighting": "roulette", "gamma": 0.5, "m": 2}
    assert default_options(4) == dict(PAPER_OPTIONS)
    for func in (minimize, TCACSSolver, check_options):
        params = inspect.signature(func).parameters
        assert {k: params[k].default for k in PAPER_OPTIONS} == dict(PAPER_OPTIONS), func
