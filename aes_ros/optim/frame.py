"""The sampling frame of TCACS (docs/design.md#tcacs-step-5, #tcacs-step-6): the rotation
fitted to the promising points, and the weights of their spread along its axes."""

from __future__ import annotations

import numpy as np

#: How the promising points weigh in the spread σ (docs/design.md#tcacs-step-6).
WEIGHTINGS = ("roulette", "rank")


def spread_weights(
    costs: np.ndarray,
    distances: np.ndarray,
    weighting: str,
    gamma: float,
) -> np.ndarray:
    """Weights W_k of the P−1 promising points other than x* (docs/design.md#tcacs-step-6).

    Parameters
    ----------
    costs : (P−1,) y_k. distances : (P−1,) d_k, distance to x*.
    weighting : "roulette": W ∝ γ·(y_max − y_k)/Σ(y_max − y) + (1−γ)·(d_k − d_min)/Σ(d − d_min),
        each term uniform where its values are all equal;
        "rank": W ∝ γ·cost score + (1−γ)·distance score, the cost score running
        from P−1 (lowest cost) down to 1, the distance score from P−1
        (farthest) down to 1 (ties broken by list order).
    gamma : share of the cost term.

    Returns
    -------
    (P−1,) weights summing to 1.
    """
    y = np.asarray(costs, dtype=float)
    d = np.asarray(distances, dtype=float)
    count = len(y)
    if count == 0:
        return np.empty(0)
    if weighting == "roulette":
        finite = np.isfinite(y)
        y = np.where(finite, y, y[finite].max() if finite.any() else 0.0)
        cost_term = _proportional(y.max() - y)
        dist_term = _proportional(d - d.min())
    elif weighting == "rank":
        cost_term = np.empty(count)
        cost_term[np.argsort(y, kind="stable")] = np.arange(count, 0, -1)
        dist_term = np.empty(count)
        dist_term[np.argsort(-d, kind="stable")] = np.arange(count, 0, -1)
    else:
        raise ValueError(f"weighting: {weighting!r} is not allowed; use one of {WEIGHTINGS}")
    w = gamma * cost_term + (1.0 - gamma) * dist_term
    total = w.sum()
    return w / total if total > 0 else np.full(count, 1.0 / count)


def _proportional(values: np.ndarray) -> np.ndarray:
    """values / Σ values, or uniform when they are all equal (Σ = 0)."""
    total = values.sum()
    if not total > 0:
        return np.full(len(values), 1.0 / len(values))
    return values / total


def fit_frame(points: np.ndarray, m: float, rng: np.random.Generator) -> np.ndarray:
    """The rotation R (axes as rows) fitted to the promising points (docs/design.md#tcacs-step-5).

    Centre the points on their mean; for j = 1 … n−1 pick a centred point with
    probability ∝ ‖c‖^(2m), take its direction as axis u_j and deflate every
    centred point along it (Gram–Schmidt). The last axis is the unit vector
    orthogonal to the others with components summing to a positive number.

    points : (P, n). Returns an orthonormal (n, n) matrix.
    """
    points = np.asarray(points, dtype=float)
    n = points.shape[1]
    c = points - points.mean(axis=0)
    scale = max(float(np.abs(c).max()), 1e-300)
    axes: list[np.ndarray] = []
    for _ in range(n - 1):
        norms = np.linalg.norm(c, axis=1)
        usable = norms > 1e-12 * scale
        if usable.any():
            p = np.where(usable, norms, 0.0) ** (2.0 * m) * usable
            if not (np.isfinite(p).all() and p.sum() > 0):  # overflow/underflow of ‖c‖^(2m)
                p = np.where(usable, norms / norms.max(), 0.0) ** (2.0 * m) * usable
                if not p.sum() > 0:
                    p = usable.astype(float)
            pick = rng.choice(len(c), p=p / p.sum())
            u = c[pick] / norms[pick]
        else:  # every centred point is (numerically) zero: complete with basis vectors
            u = _next_basis_vector(axes, n)
        for a in axes:  # re-orthogonalise against round-off
            u = u - (u @ a) * a
        u = u / np.linalg.norm(u)
        axes.append(u)
        c = c - np.outer(c @ u, u)
    last = np.linalg.svd(np.array(axes).reshape(-1, n), full_matrices=True)[2][-1]
    if last.sum() < 0:
        last = -last
    return np.vstack([*axes, last])


def _next_basis_vector(axes: list[np.ndarray], n: int) -> np.ndarray:
    """The standard basis vector least covered by ``axes``, deflated against them."""
    residuals = np.eye(n)
    for a in axes:
        residuals = residuals - np.outer(residuals @ a, a)
    return residuals[int(np.argmax(np.linalg.norm(residuals, axis=1)))]
