"""Many robots' commands in one call, as a process running many robots needs them.

A robot host (``aes-robot-host``) acts on one ``/swarm/poses`` message for all its robots.
:func:`evaluate_robots` takes each robot's arguments of :func:`aes_ros.model.robot_command`
(a :class:`RobotInput`) and evaluates them together with :func:`robot_commands`, the same
E1–E6 functions on (R, ...) arrays, so the numpy work is done once per message instead of
once per robot; the commands are those of :func:`aes_ros.model.robot_command`, bit for bit.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from aes_ros.avoidance import N_IR, avoidance_force
from aes_ros.model import (
    GAIN_FIELDS,
    Gains,
    Noise,
    RobotCommand,
    SwarmCommand,
    clip_commands,
    linear_force,
    motion_commands,
    robot_command,
    rotation_forces,
    spring_force,
    unit_noise,
)


@dataclass
class RobotInput:
    """The arguments of :func:`robot_command` for one robot and one step."""

    position: np.ndarray  #: (2,) own position [m; odom]
    heading: float  #: own θ [rad]
    neighbor_positions: np.ndarray  #: (K, 2) positions of the neighbours heard from [m]
    rest_lengths: np.ndarray  #: (K,) their rest lengths l_ij [m]
    gains: Gains
    command: SwarmCommand  #: ``center`` None: no centre known (no rotation force)
    dt: float  #: control period Δt [s]
    rng: np.random.Generator | None  #: noise source; None: noise off
    limits: tuple[float, float] | None  #: (max_linear_speed, max_angular_speed) or None
    ir_ranges: np.ndarray | None = None  #: (5,) IR ranges [m], or None: no sensors

    def arguments(self) -> tuple:
        """Positional arguments of :func:`robot_command`."""
        return (
            self.position, self.heading, self.neighbor_positions, self.rest_lengths,
            self.gains, self.command, self.dt, self.rng, self.limits, self.ir_ranges,
        )  # fmt: skip


def robot_commands(
    positions: np.ndarray,
    headings: np.ndarray,
    neighbor_positions: np.ndarray,
    rest_lengths: np.ndarray,
    gains: Gains,
    directions: np.ndarray,
    omegas: np.ndarray,
    centers: np.ndarray,
    dt: np.ndarray,
    noise: Noise | None = None,
    limits: np.ndarray | None = None,
    ir_ranges: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`robot_command` for R robots at once, each with its own inputs.

    A process running many robots (``aes-robot-host``) evaluates them in one call:
    the same E1–E6 functions on (R, ...) arrays instead of R calls on scalars,
    which were the larger part of a robot's step. Gives bit for bit what R calls
    of :func:`robot_command` give with the same inputs (:func:`evaluate_robots`).

    Parameters
    ----------
    positions : (R, 2) own positions [m]. headings : (R,) θ [rad].
    neighbor_positions : (R, K, 2) [m], padded. rest_lengths : (R, K) l_ij [m];
        ``<= 0`` marks padding.
    gains : a :class:`Gains` whose fields are (R,) arrays.
    directions : (R, 2) v_d. omegas : (R,) ω [rad/s]. centers : (R, 2) x_c [m].
    dt : (R,) Δt [s].
    noise : (xi_x, xi_y, xi_theta), each (R,), drawn per robot with
        :func:`draw_noise` (zeros for a robot without noise), or None.
    limits : (R, 2) (max_linear_speed, max_angular_speed), ``inf`` = not clipped;
        None = nothing clipped.
    ir_ranges : (R, 5) IR ranges [m], NaN for a robot without sensors; None = none has.

    Returns
    -------
    u : (R,) [m/s]; turn_rate : (R,) [rad/s]; forces : (R, 2) noise-free f_i (E4).
    """
    offsets = neighbor_positions - positions[:, None, :]
    force = spring_force(offsets, rest_lengths, gains.k[:, None])
    force = force + linear_force(directions, gains.w_l[:, None])
    rotation = rotation_forces(positions[:, None, :], centers, 1.0, 1.0)[:, 0]
    rotation = (gains.w_r * omegas)[:, None] * rotation
    force = force + np.where((omegas != 0.0)[:, None], rotation, 0.0)
    if ir_ranges is not None:
        sensing = (gains.w_o > 0.0) & ~np.isnan(ir_ranges).all(axis=-1)
        avoid = force + avoidance_force(ir_ranges, headings, gains.w_o)
        force = np.where(sensing[:, None], avoid, force)
    u, turn_rate = motion_commands(force, headings, gains, dt, noise)
    if limits is not None:
        u, turn_rate = clip_commands(u, turn_rate, limits[:, 0], limits[:, 1])
    return u, turn_rate, force


@lru_cache(maxsize=256)
def _gain_values(gains: Gains) -> tuple[float, ...]:
    return tuple(getattr(gains, name) for name in GAIN_FIELDS)


def evaluate_robots(inputs: Sequence[RobotInput]) -> list[RobotCommand]:
    """:func:`robot_command` of every input, in one :func:`robot_commands` call.

    A process running many robots acts on one ``/swarm/poses`` message for all of
    them; evaluated together, the numpy work is done once per message instead of
    once per robot. Each robot's noise is still drawn from its own generator in
    the same order, so the commands are those of :func:`robot_command` for each
    input, bit for bit (tests/unit/test_model.py).
    """
    if len(inputs) <= 1:
        return [robot_command(*job.arguments()) for job in inputs]
    r = len(inputs)
    k = max(len(job.rest_lengths) for job in inputs)
    positions, headings = np.empty((r, 2)), np.empty(r)
    neighbors, rest = np.zeros((r, k, 2)), np.zeros((r, k))  # rest 0 = padding
    gain_rows = np.empty((r, len(GAIN_FIELDS)))
    directions, omegas, centers = np.empty((r, 2)), np.empty(r), np.empty((r, 2))
    dt, limits = np.empty(r), np.full((r, 2), np.inf)
    noise = (np.zeros(r), np.zeros(r), np.zeros(r))
    ir_ranges = None
    noisy, uniforms = [], []
    for row, job in enumerate(inputs):
        n = len(job.rest_lengths)
        positions[row] = job.position
        headings[row] = job.heading
        neighbors[row, :n] = job.neighbor_positions
        rest[row, :n] = job.rest_lengths
        gain_rows[row] = _gain_values(job.gains)
        command = job.command
        directions[row] = command.direction
        omegas[row] = command.omega
        centers[row] = job.position if command.center is None else command.center
        dt[row] = job.dt
        if job.limits is not None:
            limits[row] = job.limits
        if job.ir_ranges is not None:
            if ir_ranges is None:
                ir_ranges = np.full((r, N_IR), np.nan)
            ir_ranges[row] = job.ir_ranges
        if job.rng is not None:  # draws in draw_noise's order: angle, then ξ_θ
            noisy.append(row)
            uniforms.append(job.rng.random())
            noise[2][row] = job.rng.standard_normal()
    if noisy:
        xi_x, xi_y = np.empty(len(noisy)), np.empty(len(noisy))
        unit_noise(np.array(uniforms), xi_x, xi_y)
        noise[0][noisy], noise[1][noisy] = xi_x, xi_y
    gains = Gains(**{name: gain_rows[:, col] for col, name in enumerate(GAIN_FIELDS)})
    u, turn_rate, forces = robot_commands(
        positions, headings, neighbors, rest, gains, directions, omegas, centers, dt, noise, limits,
        ir_ranges,
    )  # fmt: skip
    return [
        RobotCommand(linear, angular, force)
        for linear, angular, force in zip(u.tolist(), turn_rate.tolist(), forces, strict=True)
    ]
