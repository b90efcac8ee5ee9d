"""Fused numba kernel for the batched simulator (E1–E9 in one pass).

Same mathematics as the plain numpy path in :mod:`aes_ros.simulator`
(``backend="numpy"``), which the tests compare it with. One pass over the
robots of one run computes the spring force, the drives, the metrics and the
noisy Euler step without temporaries; runs are spread over the cores with
``prange``. Float64 throughout: float32 gained < 15 % in measurements and would
break the 1 mm agreement with the ROS system.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from aes_ros.metrics import FORCE_EPS

#: Layout of the ``params`` vector passed to :func:`advance`.
PARAM_ORDER = (
    "alpha", "beta", "k", "v0", "w_l", "w_r", "d_r", "d_theta", "dt",
    "dir_x", "dir_y", "omega", "center_x", "center_y", "use_centroid", "noise",
    "clip", "max_linear_speed", "max_angular_speed",
)  # fmt: skip


@njit(cache=True, fastmath=False, parallel=True)
def advance(
    positions: np.ndarray,
    headings: np.ndarray,
    neighbors: np.ndarray,
    rest_lengths: np.ndarray,
    params: np.ndarray,
    noise_x: np.ndarray,
    noise_y: np.ndarray,
    normals: np.ndarray,
    n_steps: int,
    metrics: np.ndarray,
    pos_hist: np.ndarray,
    head_hist: np.ndarray,
    stop_at: np.ndarray,
    first_step: int,
) -> None:
    """Advance every run by ``n_steps`` Euler steps in place.

    positions : (B, N, 2) [m], updated. headings : (B, N) [rad], updated.
    neighbors : (N, K) int64, -1 padded at the end of each row. rest_lengths : (N, K) [m].
    params : (B, P) per-run parameters, columns in PARAM_ORDER.
    noise_x, noise_y, normals : (B, C, N) noise for C >= n_steps steps: the
        sensing-noise unit vector ξ̂_r = (cos a, sin a) and ξ_θ.
    metrics : (B, C, 5) out: alignment, heading order, total force, centroid x, y
        of the state *before* each step.
    pos_hist : (B, C, N, 2) or (0, 0, 0, 2), head_hist : (B, C, N) or (0, 0, 0):
        the state before each step, when recording.
    stop_at : (B, N) int64: robot i of run b does not move (u = w = 0, a failed
        robot) from run step ``stop_at[b, i]`` on; its springs still act.
    first_step : the run step of this call's first step.
    """
    B, N = headings.shape
    K = neighbors.shape[1]
    record = pos_hist.shape[0] > 0
    two_pi = 2.0 * math.pi
    for b in prange(B):
        pb = params[b]
        alpha, beta, k, v0 = pb[0], pb[1], pb[2], pb[3]
        w_l, w_r, d_r, d_theta, dt = pb[4], pb[5], pb[6], pb[7], pb[8]
        lin_x, lin_y = w_l * pb[9], w_l * pb[10]
        rot = w_r * pb[11]
        use_centroid = pb[14] != 0.0
        noisy = pb[15] != 0.0
        clip = pb[16] != 0.0
        max_lin, max_ang = pb[17], pb[18]
        amp_r = d_r / math.sqrt(dt)
        amp_t = d_theta / math.sqrt(dt)
        stiffness = np.empty((N, K))  # k / l_ij, so the loop divides once per spring
        for i in range(N):
            for slot in range(K):
                rest = rest_lengths[i, slot]
                stiffness[i, slot] = k / rest if rest > 0.0 else 0.0
        new_pos = np.empty((N, 2))
        new_head = np.empty(N)
        pos = positions[b]
        head = headings[b]
        for step in range(n_steps):
            cx = 0.0
            cy = 0.0
            for i in range(N):
                cx += pos[i, 0]
                cy += pos[i, 1]
            cx /= N
            cy /= N
            if use_centroid:
                ox, oy = cx, cy
            else:
                ox, oy = pb[12], pb[13]
            psi = 0.0
            total = 0.0
            sum_c = 0.0
            sum_s = 0.0
            for i in range(N):
                xi = pos[i, 0]
                yi = pos[i, 1]
                fx = 0.0
                fy = 0.0
                for slot in range(K):
                    j = neighbors[i, slot]
                    if j < 0:
                        break
                    rx = pos[j, 0] - xi
                    ry = pos[j, 1] - yi
                    d = math.sqrt(rx * rx + ry * ry)
                    if d > 0.0:
                        scale = stiffness[i, slot] * (d - rest_lengths[i, slot]) / d
                        fx += scale * rx
                        fy += scale * ry
                fx += lin_x
                fy += lin_y
                if rot != 0.0:
                    fx += -rot * (yi - oy)
                    fy += rot * (xi - ox)
                th = head[i]
                c = math.cos(th)
                s = math.sin(th)
                fn = math.sqrt(fx * fx + fy * fy)
                total += fn
                psi += abs(fx * c + fy * s) / fn if fn > FORCE_EPS else 1.0
                sum_c += c
                sum_s += s
                if record:
                    pos_hist[b, step, i, 0] = xi
                    pos_hist[b, step, i, 1] = yi
                    head_hist[b, step, i] = th
                turn_noise = 0.0
                if noisy:
                    fx += amp_r * noise_x[b, step, i]
                    fy += amp_r * noise_y[b, step, i]
                    turn_noise = amp_t * normals[b, step, i]
                u = v0 + alpha * (fx * c + fy * s)
                w = beta * (-fx * s + fy * c) + turn_noise
                if clip:
                    u = min(max(u, -max_lin), max_lin)
                    w = min(max(w, -max_ang), max_ang)
                if first_step + step >= stop_at[b, i]:
                    u = 0.0
                    w = 0.0
                new_pos[i, 0] = xi + u * dt * c
                new_pos[i, 1] = yi + u * dt * s
                th = th + w * dt
                if th >= math.pi or th < -math.pi:  # rare: wrap to [-π, π)
                    th = (th + math.pi) % two_pi - math.pi
                new_head[i] = th
            metrics[b, step, 0] = psi / N
            metrics[b, step, 1] = math.sqrt(sum_c * sum_c + sum_s * sum_s) / N
            metrics[b, step, 2] = total
            metrics[b, step, 3] = cx
            metrics[b, step, 4] = cy
            pos[:, :] = new_pos
            head[:] = new_head
