"""Fused numba kernel for the batched simulator (E1–E9 in one pass).

Same mathematics as the plain numpy path in :mod:`aes_ros.simulator`
(``backend="numpy"``), which the tests compare it with. One pass over the
robots of one run computes the spring force, the drives, the metrics and the
noisy Euler step without temporaries; runs are spread over the cores with
``prange``. Float64 throughout: float32 gained < 15 % in measurements and would
break the 1 mm agreement with the ROS system.

With perception error (:mod:`aes_ros.perception`) a run also keeps the perceived
frame and the true states of the last D+1 steps. Then it needs two spring
forces per robot and step, the true one for the metrics and the perceived one
for the command; it computes both per spring (each spring once, ± on its two
robots) instead of per robot, so the two cost about what the one did, and it
computes the perceived one only when the camera updates (the frame is held in
between). The ring and the frame hold (x, y, cos θ, sin θ), so a heading's
cosine and sine are computed once, on the true state. Without perception the
kernel does exactly the float operations it did before perception existed.
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
    "perception_sigma", "perception_miss", "perception_delay_steps", "perception_period_steps",
)  # fmt: skip


def spring_list(neighbors: np.ndarray, rest_lengths: np.ndarray) -> tuple[np.ndarray, ...]:
    """The sheet's springs for :func:`advance`: each spring once.

    neighbors : (N, K) int64, -1 padded; rest_lengths : (N, K) [m].
    Returns ends (S, 2) int64 (i, j), rest (S,) [m] and mutual (S,) bool: True when
    j also has i as a neighbour with the same rest length (the spring acts on both;
    listed once, with i < j), False for a one-way link (acts on i only).
    """
    i, slot = np.nonzero(neighbors >= 0)
    j = neighbors[i, slot]
    rest = rest_lengths[i, slot]
    n = max(len(neighbors), 1)
    key = dict(zip((i * n + j).tolist(), rest.tolist(), strict=True))
    mutual = np.array([key.get(b * n + a) == r for a, b, r in zip(i, j, rest, strict=True)])
    keep = ~mutual | (i < j)
    ends = np.stack([i[keep], j[keep]], axis=1).astype(np.int64)
    return ends, rest[keep].astype(float), mutual[keep]


@njit(inline="always")
def _spring_forces(
    frame: np.ndarray,
    ends: np.ndarray,
    stiffness: np.ndarray,
    rest: np.ndarray,
    mutual: np.ndarray,
    out: np.ndarray,
) -> None:
    """Spring forces (E1) on every robot from positions ``frame`` (N, ≥2) [m] into
    ``out`` (N, 2), a spring at a time; ``stiffness`` = k / l per spring."""
    out[:, :] = 0.0
    for e in range(ends.shape[0]):
        i = ends[e, 0]
        j = ends[e, 1]
        rx = frame[j, 0] - frame[i, 0]
        ry = frame[j, 1] - frame[i, 1]
        d = math.sqrt(rx * rx + ry * ry)
        if d > 0.0:
            scale = stiffness[e] * (d - rest[e]) / d
            out[i, 0] += scale * rx
            out[i, 1] += scale * ry
            if mutual[e]:
                out[j, 0] -= scale * rx
                out[j, 1] -= scale * ry


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
    springs: tuple[np.ndarray, np.ndarray, np.ndarray],
    seen: np.ndarray,
    ring: np.ndarray,
    camera_noise: np.ndarray,
    camera_uniforms: np.ndarray,
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
    springs : :func:`spring_list` of the sheet (used with perception on).
    seen : (B, N, 4) the perceived frame x, y [m], cos θ, sin θ, updated; (B, 0, 4)
        with perception off (the robots see the true state).
    ring : (B, D+1, N, 4) the true states (x, y, cos θ, sin θ) of the last D+1
        steps, step t in slot t % (D+1), updated (before step D the slots not yet
        written hold the initial state); (B, 0, 0, 4) with perception off.
    camera_noise : (B, R, N, 2) standard normals and camera_uniforms : (B, R, N)
        in [0, 1): the draws of the R camera updates among these steps
        (:func:`aes_ros.perception.draw_camera`).
    """
    B, N = headings.shape
    K = neighbors.shape[1]
    record = pos_hist.shape[0] > 0
    perceive = seen.shape[1] > 0
    ends, spring_rest, mutual = springs
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
        sigma_p, miss_p = pb[19], pb[20]
        ring_len = int(pb[21]) + 1
        period = int(pb[22])
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
        # with perception: per-spring stiffness, the true and perceived forces, the
        # true heading's cos and sin (M = N, else 0)
        M = N if perceive else 0
        spring_stiffness = np.empty(ends.shape[0] if perceive else 0)
        for e in range(spring_stiffness.shape[0]):
            spring_stiffness[e] = k / spring_rest[e] if spring_rest[e] > 0.0 else 0.0
        true_force = np.empty((M, 2))
        seen_force = np.empty((M, 2))
        true_c = np.empty(M)
        true_s = np.empty(M)
        view = seen[b]
        if perceive:
            _spring_forces(view, ends, spring_stiffness, spring_rest, mutual, seen_force)
        refresh = 0
        for step in range(n_steps):
            t = first_step + step
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
            if perceive:
                now = ring[b, t % ring_len]
                for i in range(N):
                    c = math.cos(head[i])
                    s = math.sin(head[i])
                    true_c[i] = c
                    true_s[i] = s
                    now[i, 0] = pos[i, 0]
                    now[i, 1] = pos[i, 1]
                    now[i, 2] = c
                    now[i, 3] = s
                _spring_forces(pos, ends, spring_stiffness, spring_rest, mutual, true_force)
                if t % period == 0:  # a camera update: the state D steps ago, noised
                    old = ring[b, (t + 1) % ring_len]
                    for i in range(N):
                        if t == 0 or camera_uniforms[b, refresh, i] >= miss_p:
                            view[i, 0] = old[i, 0] + sigma_p * camera_noise[b, refresh, i, 0]
                            view[i, 1] = old[i, 1] + sigma_p * camera_noise[b, refresh, i, 1]
                            view[i, 2] = old[i, 2]
                            view[i, 3] = old[i, 3]
                    refresh += 1
                    _spring_forces(view, ends, spring_stiffness, spring_rest, mutual, seen_force)
            sox, soy = ox, oy  # the rotation centre the robots see
            if perceive and use_centroid:
                sox = 0.0
                soy = 0.0
                for i in range(N):
                    sox += view[i, 0]
                    soy += view[i, 1]
                sox /= N
                soy /= N
            psi = 0.0
            total = 0.0
            sum_c = 0.0
            sum_s = 0.0
            for i in range(N):
                xi = pos[i, 0]
                yi = pos[i, 1]
                fx = 0.0
                fy = 0.0
                if perceive:
                    fx = true_force[i, 0]
                    fy = true_force[i, 1]
                else:
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
                if perceive:
                    c = true_c[i]
                    s = true_s[i]
                else:
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
                # the command: from the force the robot sees, along the heading it sees
                seen_c = c
                seen_s = s
                if perceive:
                    fx = seen_force[i, 0] + lin_x
                    fy = seen_force[i, 1] + lin_y
                    if rot != 0.0:
                        fx += -rot * (view[i, 1] - soy)
                        fy += rot * (view[i, 0] - sox)
                    seen_c = view[i, 2]
                    seen_s = view[i, 3]
                turn_noise = 0.0
                if noisy:
                    fx += amp_r * noise_x[b, step, i]
                    fy += amp_r * noise_y[b, step, i]
                    turn_noise = amp_t * normals[b, step, i]
                u = v0 + alpha * (fx * seen_c + fy * seen_s)
                w = beta * (-fx * seen_s + fy * seen_c) + turn_noise
                if clip:
                    u = min(max(u, -max_lin), max_lin)
                    w = min(max(w, -max_ang), max_ang)
                if t >= stop_at[b, i]:
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
