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
for the command; it computes both per spring (:mod:`aes_ros.springs`: each spring
once, ± on its two robots) instead of per robot, so the two cost about what the one did, and it
computes the perceived one only when the camera updates (the frame is held in
between). The ring and the frame hold (x, y, cos θ, sin θ), so a heading's
cosine and sine are computed once, on the true state. Without perception the
kernel does exactly the float operations it did before perception existed.

The perception's random draws are made here too, by
:func:`aes_ros.xoshiro.camera_draws` at each camera update of a run, from the run's own
xoshiro256** states; each run draws in order on its core, so the numbers depend neither
on the batch nor on the number of threads.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from aes_ros.avoidance import AVOIDANCE_RANGE
from aes_ros.contacts import fill_body_centres, resolve_listed
from aes_ros.ir import cast_rays, cast_rays_listed
from aes_ros.kernel_bodies import IR_MOUNT, avoidance_term, list_cutoffs, ray_reach
from aes_ros.metrics import FORCE_EPS
from aes_ros.numba_cache import depend_on
from aes_ros.pair_list import kept_pairs
from aes_ros.springs import spring_forces
from aes_ros.xoshiro import camera_draws

#: Layout of the ``params`` vector passed to :func:`advance`.
PARAM_ORDER = (
    "alpha", "beta", "k", "v0", "w_l", "w_r", "d_r", "d_theta", "dt",
    "dir_x", "dir_y", "omega", "center_x", "center_y", "use_centroid", "noise",
    "clip", "max_linear_speed", "max_angular_speed",
    "perception_sigma", "perception_miss", "perception_delay_steps", "perception_period_steps",
    "noise_dt", "contacts", "body_radius", "axle_offset", "contact_iterations", "w_o",
    "ir_period_steps",
)  # fmt: skip


@njit(inline="always")
def _centroid(points: np.ndarray) -> tuple[float, float]:
    """Mean of ``points[:, 0]`` and ``points[:, 1]`` (``points``: (N, ≥2) [m]), summed in
    index order so that every run's result is the same to the bit."""
    n = points.shape[0]
    cx = 0.0
    cy = 0.0
    for i in range(n):
        cx += points[i, 0]
        cy += points[i, 1]
    return cx / n, cy / n


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
    camera_state: np.ndarray,
    bodies: tuple[np.ndarray, np.ndarray, np.ndarray],
    contact_out: np.ndarray,
    held_ranges: np.ndarray,
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
    springs : :func:`aes_ros.springs.spring_list` of the sheet (used with perception on).
    seen : (B, N, 4) the perceived frame x, y [m], cos θ, sin θ, updated; (B, 0, 4)
        with perception off (the robots see the true state).
    ring : (B, D+1, N, 4) the true states (x, y, cos θ, sin θ) of the last D+1
        steps, step t in slot t % (D+1), updated (before step D the slots not yet
        written hold the initial state); (B, 0, 0, 4) with perception off.
    camera_state : (B, 2, 4) uint64, each run's perception generators
        (:func:`aes_ros.perception.perception_state`), advanced by the draws of the
        camera updates among these steps (:func:`camera_draws`, N robot-frames each).
    bodies : walls (4,) or (0,), circles (M, 3), boxes (L, 4) [m] for the contacts and,
        with ``w_o`` > 0, the IR rays of the avoidance term (exact distances, no noise).
    contact_out : (B, C, 2) out, with ``contacts`` on: the overlaps resolved after each
        step and the smallest centre distance [m] after it
        (:func:`aes_ros.contacts.resolve_contacts`); untouched with contacts off.
    held_ranges : (B, N, 5) with ``w_o`` > 0, else (B, 0, 5): every robot's IR ranges [m],
        cast at the run steps that are multiples of ``ir_period_steps`` and held in
        between (as a robot holds its last reading), updated.
    """
    B, N = headings.shape
    K = neighbors.shape[1]
    record = pos_hist.shape[0] > 0
    perceive = seen.shape[1] > 0
    ends, spring_rest, mutual = springs
    walls, circles, boxes = bodies
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
        root_dt = math.sqrt(pb[23])  # Δt of the noise term, floored (model.noise_dt)
        amp_r = d_r / root_dt
        amp_t = d_theta / root_dt
        touching = pb[24] != 0.0
        radius, axle_offset, iterations = pb[25], pb[26], int(pb[27])
        w_o = pb[28]
        ir_period = int(pb[29])
        sensing = w_o > 0.0
        ranges = held_ranges[b]
        ray_c = np.empty(N if sensing else 0)  # the headings' cos and sin for the rays
        ray_s = np.empty(N if sensing else 0)
        ray_centres = np.empty((N if sensing else 0, 2))  # the rays' scratch space
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
        camera_z = np.zeros((M, 2))  # zeros: what a stream switched off contributes
        camera_u = np.zeros(M)
        view = seen[b]
        # with contacts: the new headings' cos and sin, taken for the body centres after
        # a step and kept for the next step (computed once; M2 = N, else 0)
        M2 = N if touching else 0
        trig_c = np.empty(M2)
        trig_s = np.empty(M2)
        body_x = np.empty(M2)
        body_y = np.empty(M2)
        have_trig = False
        # and the candidate pairs, kept over steps (aes_ros.contacts.resolve_listed)
        ref_x = np.full(M2, np.inf)  # inf: no list yet, the first step makes one
        ref_y = np.full(M2, np.inf)
        listed = np.empty((0, 2), np.int64)
        near, skin = list_cutoffs(radius, sensing)
        # and, with the rays on, the listed pairs close enough for them after the last
        # step's contacts (in_reach[:n_in_reach]; -1: not known, the rays take the list)
        reach = ray_reach(radius) if sensing else 0.0
        in_reach = np.empty((0, 2), np.int64)
        n_in_reach = -1
        if perceive:
            spring_forces(view, ends, spring_stiffness, spring_rest, mutual, seen_force)
        for step in range(n_steps):
            t = first_step + step
            cx, cy = _centroid(pos)
            if use_centroid:
                ox, oy = cx, cy
            else:
                ox, oy = pb[12], pb[13]
            if perceive:
                now = ring[b, t % ring_len]
                for i in range(N):
                    if have_trig:
                        c = trig_c[i]
                        s = trig_s[i]
                    else:
                        c = math.cos(head[i])
                        s = math.sin(head[i])
                    true_c[i] = c
                    true_s[i] = s
                    now[i, 0] = pos[i, 0]
                    now[i, 1] = pos[i, 1]
                    now[i, 2] = c
                    now[i, 3] = s
                spring_forces(pos, ends, spring_stiffness, spring_rest, mutual, true_force)
                if t % period == 0:  # a camera update: the state D steps ago, noised
                    camera_draws(camera_state[b], sigma_p > 0.0, miss_p > 0.0, camera_z, camera_u)
                    old = ring[b, (t + 1) % ring_len]
                    for i in range(N):
                        if t == 0 or camera_u[i] >= miss_p:
                            view[i, 0] = old[i, 0] + sigma_p * camera_z[i, 0]
                            view[i, 1] = old[i, 1] + sigma_p * camera_z[i, 1]
                            view[i, 2] = old[i, 2]
                            view[i, 3] = old[i, 3]
                    spring_forces(view, ends, spring_stiffness, spring_rest, mutual, seen_force)
            casting = sensing and t % ir_period == 0
            if casting and touching:  # every robot's IR ranges, cast in the true state
                candidates = listed  # the list the last step's resolve_listed returned
                if not have_trig:  # no centres and no list yet (this call's first step)
                    fill_body_centres(pos, head, axle_offset, trig_c, trig_s, body_x, body_y)
                    have_trig = True
                    listed = kept_pairs(body_x, body_y, listed, ref_x, ref_y, near, skin)
                    candidates = listed
                elif n_in_reach >= 0:  # ... or those of its pairs the rays can see along
                    candidates = in_reach[:n_in_reach]
                cast_rays_listed(
                    pos, trig_c, trig_s, radius, axle_offset, IR_MOUNT, AVOIDANCE_RANGE, walls,
                    circles, boxes, candidates, ranges, ray_centres,
                )  # fmt: skip
            elif casting:
                for i in range(N):
                    th = head[i]
                    c = math.cos(th)  # locals: one sincos call (see contacts.fill_body_centres)
                    s = math.sin(th)
                    ray_c[i] = c
                    ray_s[i] = s
                cast_rays(
                    pos, ray_c, ray_s, radius, axle_offset, IR_MOUNT, AVOIDANCE_RANGE, walls,
                    circles, boxes, ranges,
                )  # fmt: skip
            sox, soy = ox, oy  # the rotation centre the robots see
            if perceive and use_centroid:
                sox, soy = _centroid(view)
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
                elif have_trig:
                    c = trig_c[i]
                    s = trig_s[i]
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
                if sensing:  # avoidance: the robot's own sensors, its true heading
                    ax, ay = avoidance_term(ranges, i, w_o, c, s)
                    fx += ax
                    fy += ay
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
            if touching:  # aes_ros.contacts.resolve_contacts, its centres computed here
                fill_body_centres(pos, head, axle_offset, trig_c, trig_s, body_x, body_y)
                have_trig = True
                found, closest, listed, in_reach, n_in_reach = resolve_listed(
                    pos, body_x, body_y, radius, walls, circles, boxes, iterations,
                    listed, ref_x, ref_y, near, skin, reach, in_reach,
                )  # fmt: skip
                contact_out[b, step, 0] = found
                contact_out[b, step, 1] = closest


# Numba's cache checks this file only: an edit of the contact rule, the rays or the
# constants compiled in from these modules must compile the kernel again.
depend_on(
    advance, "aes_ros.avoidance", "aes_ros.contacts", "aes_ros.ir", "aes_ros.kernel_bodies",
    "aes_ros.metrics", "aes_ros.pair_list", "aes_ros.springs", "aes_ros.xoshiro",
)  # fmt: skip
