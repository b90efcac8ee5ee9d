"""Test functions of global minimisation, with TCACS's reference behaviour.

See docs/design.md#tcacs-reference.

Every function is vectorised like a TCACS objective: ``X`` of shape ``(k, n)``
gives the ``(k,)`` values. :data:`BENCHMARKS` pairs each with its box, its
minimum f* and, where the authors published it, the success rate and mean
evaluation count of their implementation; the tests and
``bench/bench_tcacs.py`` compare :func:`aes_ros.optim.tcacs.minimize` with them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


def branin(X: np.ndarray) -> np.ndarray:
    """Branin RCOS on [−5, 10] × [0, 15]; f* = 5/(4π) ≈ 0.397887 (three minima)."""
    x, y = X[:, 0], X[:, 1]
    b, c = 5.1 / (4 * np.pi**2), 5 / np.pi
    return (y - b * x**2 + c * x - 6) ** 2 + 10 * (1 - 1 / (8 * np.pi)) * np.cos(x) + 10


def goldstein_price(X: np.ndarray) -> np.ndarray:
    """Goldstein–Price on [−2, 2]²; f* = 3 at (0, −1)."""
    x, y = X[:, 0], X[:, 1]
    a = 1 + (x + y + 1) ** 2 * (19 - 14 * x + 3 * x**2 - 14 * y + 6 * x * y + 3 * y**2)
    b = 30 + (2 * x - 3 * y) ** 2 * (18 - 32 * x + 12 * x**2 + 48 * y - 36 * x * y + 27 * y**2)
    return a * b


def rosenbrock(X: np.ndarray) -> np.ndarray:
    """Rosenbrock; f* = 0 at (1, …, 1)."""
    return np.sum(100 * (X[:, 1:] - X[:, :-1] ** 2) ** 2 + (1 - X[:, :-1]) ** 2, axis=1)


def sphere(X: np.ndarray) -> np.ndarray:
    """De Jong's sphere; f* = 0 at the origin."""
    return np.sum(X**2, axis=1)


_H3_A = np.array([[3.0, 10, 30], [0.1, 10, 35], [3.0, 10, 30], [0.1, 10, 35]])
_H3_P = 1e-4 * np.array(
    [[3689, 1170, 2673], [4699, 4387, 7470], [1091, 8732, 5547], [381, 5743, 8828]]
)
_H6_A = np.array(
    [
        [10, 3, 17, 3.5, 1.7, 8],
        [0.05, 10, 17, 0.1, 8, 14],
        [3, 3.5, 1.7, 10, 17, 8],
        [17, 8, 0.05, 10, 0.1, 14],
    ]
)
_H6_P = 1e-4 * np.array(
    [
        [1312, 1696, 5569, 124, 8283, 5886],
        [2329, 4135, 8307, 3736, 1004, 9991],
        [2348, 1451, 3522, 2883, 3047, 6650],
        [4047, 8828, 8732, 5743, 1091, 381],
    ]
)
_HC = np.array([1.0, 1.2, 3.0, 3.2])


def _hartmann(X: np.ndarray, A: np.ndarray, P: np.ndarray) -> np.ndarray:
    inner = np.sum(A[None] * (X[:, None, :] - P[None]) ** 2, axis=2)
    return -np.sum(_HC * np.exp(-inner), axis=1)


def hartmann3(X: np.ndarray) -> np.ndarray:
    """Hartmann H3,4 on [0, 1]³; f* ≈ −3.86278."""
    return _hartmann(X, _H3_A, _H3_P)


def hartmann6(X: np.ndarray) -> np.ndarray:
    """Hartmann H6,4 on [0, 1]⁶; f* ≈ −3.32237."""
    return _hartmann(X, _H6_A, _H6_P)


_SHEKEL_A = np.array([[4.0, 4, 4, 4], [1, 1, 1, 1], [8, 8, 8, 8], [6, 6, 6, 6], [3, 7, 3, 7]])
_SHEKEL_C = np.array([0.1, 0.2, 0.2, 0.4, 0.4])


def shekel5(X: np.ndarray) -> np.ndarray:
    """Shekel S4,5 on [0, 10]⁴; f* ≈ −10.1532 at (4, 4, 4, 4)."""
    sq = np.sum((X[:, None, :] - _SHEKEL_A[None]) ** 2, axis=2)
    return -np.sum(1.0 / (sq + _SHEKEL_C), axis=1)


@dataclass(frozen=True)
class Benchmark:
    """A test function with its box, optimum and the reference behaviour (docs/design.md#tcacs)."""

    name: str
    f: Callable[[np.ndarray], np.ndarray]
    bounds: tuple[tuple[float, float], ...]
    f_star: float
    ref_success: float | None = None  #: success rate of the authors' code, or None
    ref_evals: float | None = None  #: its mean evaluations, or None

    def success(self, fun: float) -> bool:
        """|f − f*| < 1e-4·|f*| + 1e-6 (the reference's success criterion)."""
        return abs(fun - self.f_star) < 1e-4 * abs(self.f_star) + 1e-6


BENCHMARKS: dict[str, Benchmark] = {
    b.name: b
    for b in [
        Benchmark("branin", branin, ((-5, 10), (0, 15)), 5 / (4 * np.pi), 1.00, 420),
        Benchmark("goldstein_price", goldstein_price, ((-2, 2), (-2, 2)), 3.0, 0.97, 260),
        Benchmark("rosenbrock2", rosenbrock, ((-5, 10), (-5, 10)), 0.0, 1.00, 670),
        Benchmark("sphere3", sphere, ((-5.12, 5.12),) * 3, 0.0, 1.00, 390),
        Benchmark("hartmann3", hartmann3, ((0, 1),) * 3, -3.862782147820756, 0.99, 550),
        # Beyond the reference table: the n >= 4 defaults (15 ants, roulette, m = 2).
        Benchmark("shekel5", shekel5, ((0, 10),) * 4, -10.1531996790582),
        Benchmark("hartmann6", hartmann6, ((0, 1),) * 6, -3.322368011391339),
    ]
}
