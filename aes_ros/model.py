"""The Active Elastic Sheet model with the Raoufi extensions (docs/design.md#model, E1–E6).

Pure functions on arrays with leading batch axes: ``positions (..., N, 2)``
[m; odom], ``headings (..., N)`` [rad, counter-clockwise from +x]. The same
code runs for one robot, one swarm or a batch of B swarms.

:func:`robot_command` is the control law of one robot. The ROS robot node calls
exactly this function with its own pose and its neighbours' positions (for many robots
at once, through :mod:`aes_ros.robot_batch`, to the same bits); the offline simulator
calls the same building blocks for every robot at once.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from aes_ros.avoidance import avoidance_force
from aes_ros.params import PARAMS


@dataclass(frozen=True)
class Gains:
    """Gains and noise strengths (docs/design.md#scenarios defaults: the paper's Table 1)."""

    alpha: float = PARAMS["alpha"].default
    beta: float = PARAMS["beta"].default
    k: float = PARAMS["k"].default
    v0: float = PARAMS["v0"].default
    w_l: float = PARAMS["w_l"].default
    w_r: float = PARAMS["w_r"].default
    d_r: float = PARAMS["d_r"].default
    d_theta: float = PARAMS["d_theta"].default
    w_o: float = PARAMS["w_o"].default

    @classmethod
    def from_mapping(cls, values: dict) -> Gains:
        """Pick the gain fields out of a larger mapping (e.g. a scenario)."""
        return cls(**{f.name: float(values[f.name]) for f in fields(cls) if f.name in values})


#: The fields of :class:`Gains`: every gain and noise strength a robot node declares.
GAIN_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(Gains))

#: Smallest Δt [s] the noise term is scaled with (docs/model.md, Noise). A robot
#: node's Δt is the gap between two pose stamps, which may be 1 ns; D/√Δt would then
#: be 7000 times its size at 20 Hz.
MIN_NOISE_DT = 1e-3


def noise_dt(dt: float | np.ndarray) -> float | np.ndarray:
    """Δt for the noise term: ``dt``, or :data:`MIN_NOISE_DT` where it is smaller or NaN."""
    if isinstance(dt, float):
        return dt if dt >= MIN_NOISE_DT else MIN_NOISE_DT
    return np.fmax(dt, MIN_NOISE_DT)


@dataclass(frozen=True)
class SwarmCommand:
    """What the supervisor tells every robot (docs/design.md#extensions, #ros-interface).

    direction : v_d, world frame; its length scales the drive, (0, 0) switches it off.
    omega : rotation rate ω [rad/s], counter-clockwise positive.
    center : x_c [m]; None means the live centroid of the swarm.
    """

    direction: tuple[float, float] = (-1.0, 0.0)
    omega: float = 0.0
    center: tuple[float, float] | None = None


def spring_force(offsets: np.ndarray, rest_lengths: np.ndarray, k: float) -> np.ndarray:
    """Spring force on one robot from its neighbours (E1).

    f = Σ_j (k / l_ij)(|r_ij| - l_ij) r_ij / |r_ij|,  r_ij = x_j - x_i.

    A stretched spring pulls toward the neighbour, a compressed one pushes away.
    Slots with ``rest_lengths <= 0`` (padding) and coincident robots
    (|r_ij| = 0, direction undefined) contribute nothing.

    Parameters
    ----------
    offsets : (..., K, 2) r_ij [m].
    rest_lengths : (..., K) l_ij [m].
    k : stiffness.

    Returns
    -------
    (..., 2) force.
    """
    dist = np.sqrt(np.sum(offsets * offsets, axis=-1))
    active = (rest_lengths > 0) & (dist > 0)
    safe_rest = np.where(active, rest_lengths, 1.0)
    safe_dist = np.where(active, dist, 1.0)
    scale = np.where(active, k / safe_rest * (dist - rest_lengths) / safe_dist, 0.0)
    return np.sum(scale[..., None] * offsets, axis=-2)


def spring_forces(
    positions: np.ndarray, neighbors: np.ndarray, rest_lengths: np.ndarray, k: float
) -> np.ndarray:
    """Spring force on every robot (E1).

    positions : (..., N, 2) [m]; neighbors : (N, K) ids, -1 padded;
    rest_lengths : (N, K) [m]. Returns (..., N, 2).
    """
    offsets = positions[..., neighbors, :] - positions[..., :, None, :]
    return spring_force(offsets, np.where(neighbors >= 0, rest_lengths, 0.0), k)


def linear_force(direction: np.ndarray, w_l: float) -> np.ndarray:
    """Linear drive, the same for every robot (E2): f_lin = w_l v_d. Returns (..., 2)."""
    return w_l * np.asarray(direction, dtype=float)


def rotation_forces(
    positions: np.ndarray, center: np.ndarray, omega: float, w_r: float
) -> np.ndarray:
    """Rotation about x_c (E3): f_rot,i = w_r ω (-(y_i - y_c), x_i - x_c).

    ω > 0 turns counter-clockwise (the paper's sign is the opposite).
    positions : (..., N, 2); center : (..., 2). Returns (..., N, 2).
    """
    rel = positions - np.asarray(center)[..., None, :]
    return (w_r * omega) * np.stack([-rel[..., 1], rel[..., 0]], axis=-1)


def centroid(positions: np.ndarray) -> np.ndarray:
    """Centroid (..., 2) of positions (..., N, 2)."""
    return positions.mean(axis=-2)


def total_forces(
    positions: np.ndarray,
    neighbors: np.ndarray,
    rest_lengths: np.ndarray,
    gains: Gains,
    command: SwarmCommand,
) -> np.ndarray:
    """Noise-free total force on every robot (E4): f = f_spring + f_lin + f_rot.

    The rotation centre is ``command.center`` or, if None, the live centroid of
    each swarm in the batch. Returns (..., N, 2).
    """
    center = centroid(positions) if command.center is None else np.asarray(command.center)
    force = spring_forces(positions, neighbors, rest_lengths, gains.k)
    force += linear_force(command.direction, gains.w_l)
    if command.omega != 0.0:
        force += rotation_forces(positions, center, command.omega, gains.w_r)
    return force


Noise = tuple[np.ndarray, np.ndarray, np.ndarray]
"""One step's noise: the unit vector ξ̂_r as (x, y) components, and ξ_θ."""


def draw_noise(
    rng: np.random.Generator, shape: tuple[int, ...] = (), out: Noise | None = None
) -> Noise:
    """Noise for ``shape`` robot-steps (docs/design.md#motion).

    The angle of ξ̂_r is uniform in [-π, π) and ξ_θ ~ N(0, 1), independent.
    Draws all angles, then all normals, from ``rng``. The unit vector's
    components are evaluated in float32 (10× faster than float64 trig here; an
    error of 1e-7 in a random direction is harmless) and stored as float64.
    Both the simulator and the robot nodes draw through here, so a seed means
    the same thing everywhere.

    Returns (xi_x, xi_y, xi_theta), float64 arrays of ``shape`` (``out`` if given).
    """
    if out is None:
        out = (np.empty(shape), np.empty(shape), np.empty(shape))
    angles = rng.random(size=shape)
    rng.standard_normal(out=out[2])
    unit_noise(angles, out[0], out[1])
    return out


def unit_noise(uniforms: np.ndarray, xi_x: np.ndarray, xi_y: np.ndarray) -> None:
    """Fill ξ̂_r's components ``xi_x``, ``xi_y`` from ``uniforms`` in [0, 1) (consumed:
    scaled in place to the angle); all three of the same shape.

    Split from :func:`draw_noise` so that many generators' draws (one per robot
    of a process) are turned into unit vectors in one call, with the same result.
    """
    angles = uniforms
    angles *= 2.0 * np.pi
    angles -= np.pi
    angles32 = angles.astype(np.float32)
    np.cos(angles32, out=xi_x, casting="unsafe")
    np.sin(angles32, out=xi_y, casting="unsafe")


def motion_commands(
    forces: np.ndarray,
    headings: np.ndarray,
    gains: Gains,
    dt: float,
    noise: Noise | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Forward speed and turn rate from the force (E5, E6).

    g = f + (D_r/√Δt) ξ̂_r;  u = v_0 + α g·n̂;  ω = β g·n̂⊥ + (D_θ/√Δt) ξ_θ,
    with Δt no smaller than :data:`MIN_NOISE_DT` (:func:`noise_dt`), so no Δt
    makes the noise larger than D/√(1 ms).

    Parameters
    ----------
    forces : (..., N, 2) noise-free force f (E4), world frame.
    headings : (..., N) θ [rad].
    gains : α, β, v_0, D_r, D_θ.
    dt : Δt [s]; scales the noise (floored at :data:`MIN_NOISE_DT`).
    noise : (xi_x, xi_y, xi_theta) from :func:`draw_noise`, or None for no noise.

    Returns
    -------
    u : (..., N) forward speed [m/s]; turn_rate : (..., N) [rad/s].
    """
    gx, gy = forces[..., 0], forces[..., 1]
    turn_noise = 0.0
    if noise is not None:
        xi_x, xi_y, xi_theta = noise
        root_dt = np.sqrt(noise_dt(dt))
        amp = gains.d_r / root_dt
        gx = gx + amp * xi_x
        gy = gy + amp * xi_y
        turn_noise = gains.d_theta / root_dt * xi_theta
    c, s = np.cos(headings), np.sin(headings)
    u = gains.v0 + gains.alpha * (gx * c + gy * s)
    turn_rate = gains.beta * (-gx * s + gy * c) + turn_noise
    return u, turn_rate


def clip_commands(
    u: np.ndarray, turn_rate: np.ndarray, max_linear_speed: float, max_angular_speed: float
) -> tuple[np.ndarray, np.ndarray]:
    """Clip commands to the robot's limits (docs/design.md#mona), each axis independently.

    (``np.minimum(np.maximum(...))`` is ``np.clip`` without its dispatch overhead,
    a third of the cost for the robot nodes' scalars.)
    """
    return (
        np.minimum(np.maximum(u, -max_linear_speed), max_linear_speed),
        np.minimum(np.maximum(turn_rate, -max_angular_speed), max_angular_speed),
    )


def unicycle_step(
    positions: np.ndarray, headings: np.ndarray, u: np.ndarray, turn_rate: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """Explicit Euler step of the unicycle (E5, E6), using the heading before the step.

    Returns new positions (..., N, 2) and headings (..., N) wrapped to [-π, π).
    """
    step = (u * dt)[..., None] * np.stack([np.cos(headings), np.sin(headings)], axis=-1)
    return positions + step, wrap_angle(headings + turn_rate * dt)


def wrap_angle(theta: np.ndarray) -> np.ndarray:
    """Wrap angles [rad] to [-π, π)."""
    return (theta + np.pi) % (2.0 * np.pi) - np.pi


@dataclass(frozen=True)
class RobotCommand:
    """Output of the control law for one robot."""

    linear: float  #: forward speed u [m/s] -> cmd_vel.linear.x
    angular: float  #: turn rate [rad/s] -> cmd_vel.angular.z
    force: np.ndarray  #: noise-free force f_i (E4), world frame, (2,)


def robot_command(
    position: np.ndarray,
    heading: float,
    neighbor_positions: np.ndarray,
    rest_lengths: np.ndarray,
    gains: Gains,
    command: SwarmCommand,
    dt: float,
    rng: np.random.Generator | None = None,
    limits: tuple[float, float] | None = None,
    ir_ranges: np.ndarray | None = None,
) -> RobotCommand:
    """The control law of one robot (E1–E6): what a robot node publishes as ``cmd_vel``.

    Needs only the robot's own pose, its neighbours' *positions* (never their
    headings) and the swarm command.

    Parameters
    ----------
    position : (2,) own position [m; odom]. heading : own θ [rad].
    neighbor_positions : (K, 2) positions of the neighbours heard from [m].
    rest_lengths : (K,) their rest lengths l_ij [m].
    gains, command : model gains and the supervisor's command; ``command.center``
        must be set (the supervisor publishes the live centroid).
    dt : control period Δt [s] (scales the noise; below :data:`MIN_NOISE_DT`
        it counts as :data:`MIN_NOISE_DT`).
    rng : noise source; None switches noise off.
    limits : (max_linear_speed, max_angular_speed) to clip to, or None.
    ir_ranges : (5,) the robot's IR ranges [m] (:mod:`aes_ros.avoidance`), or None (no
        sensors); with ``gains.w_o > 0`` their repulsion joins f.
    """
    position = np.asarray(position, dtype=float)
    offsets = np.asarray(neighbor_positions, dtype=float).reshape(-1, 2) - position
    force = spring_force(offsets, np.asarray(rest_lengths, dtype=float), gains.k)
    force = force + linear_force(command.direction, gains.w_l)
    if command.omega != 0.0:
        center = position if command.center is None else command.center
        force = force + rotation_forces(position[None, :], center, command.omega, gains.w_r)[0]
    if ir_ranges is not None and gains.w_o > 0.0:
        force = force + avoidance_force(ir_ranges, heading, gains.w_o)
    noise = draw_noise(rng) if rng is not None else None
    u, turn_rate = motion_commands(force, np.asarray(heading, dtype=float), gains, dt, noise)
    if limits is not None:
        u, turn_rate = clip_commands(u, turn_rate, *limits)
    return RobotCommand(float(u), float(turn_rate), force)
