"""The avoidance term in the control law (aes_ros.model): off (w_o = 0 or no ranges) it
changes nothing, bit for bit; on, it keeps a robot driven at a wall off the wall."""

from __future__ import annotations

import numpy as np
import pytest

from aes_ros import model
from aes_ros.avoidance import AVOIDANCE_RANGE, avoidance_force
from aes_ros.ir_readings import ir_ranges
from aes_ros.model import Gains, SwarmCommand, robot_command
from aes_ros.mona.geometry import MonaGeometry
from aes_ros.robot_batch import RobotInput, evaluate_robots


def reference(job: RobotInput) -> tuple[float, float, np.ndarray]:
    """E1–E6 composed from the building blocks, without any avoidance term."""
    offsets = job.neighbor_positions - job.position
    force = model.spring_force(offsets, job.rest_lengths, job.gains.k)
    force = force + model.linear_force(job.command.direction, job.gains.w_l)
    if job.command.omega != 0.0:
        center = job.position if job.command.center is None else job.command.center
        omega = job.command.omega
        force = force + model.rotation_forces(job.position[None], center, omega, job.gains.w_r)[0]
    noise = model.draw_noise(job.rng) if job.rng is not None else None
    u, w = model.motion_commands(force, np.asarray(job.heading), job.gains, job.dt, noise)
    if job.limits is not None:
        u, w = model.clip_commands(u, w, *job.limits)
    return float(u), float(w), force


def random_jobs(seed: int, n: int, w_o: float, sensors: bool) -> list[RobotInput]:
    """``n`` robots' inputs; every other one with IR ranges if ``sensors``."""
    rng = np.random.default_rng(seed)
    jobs = []
    for r in range(n):
        k = int(rng.integers(0, 6))
        gains = Gains(
            alpha=rng.uniform(0.0, 1.0),
            beta=rng.uniform(0.0, 2.0),
            k=rng.uniform(0.0, 3.0),
            d_r=0.5 * (r % 3 > 0),
            d_theta=0.02 * (r % 2),
            w_o=w_o,
        )
        omega = float(rng.uniform(-1.0, 1.0)) * (r % 4 > 0)
        center = None if r % 5 == 0 else tuple(rng.uniform(-1.0, 1.0, 2))
        jobs.append(
            RobotInput(
                position=rng.uniform(-1.0, 1.0, 2),
                heading=float(rng.uniform(-4.0, 4.0)),
                neighbor_positions=rng.uniform(-1.0, 1.0, (k, 2)),
                rest_lengths=rng.uniform(0.1, 0.3, k),
                gains=gains,
                command=SwarmCommand(tuple(rng.uniform(-1.0, 1.0, 2)), omega, center),
                dt=0.05,
                rng=np.random.default_rng([seed, r]) if r % 3 or r % 2 else None,
                limits=None if r % 3 else (0.13, 3.4),
                ir_ranges=rng.uniform(0.0, 0.12, 5) if sensors and r % 2 == 0 else None,
            )
        )
    return jobs


@pytest.mark.parametrize("n", [1, 7, 30])
@pytest.mark.parametrize("w_o, sensors", [(0.0, True), (0.0, False), (4.0, False)])
def test_off_is_bit_identical_to_the_law_without_the_term(
    n: int, w_o: float, sensors: bool
) -> None:
    expected = [reference(job) for job in random_jobs(n, n, w_o, sensors)]
    one_by_one = [robot_command(*job.arguments()) for job in random_jobs(n, n, w_o, sensors)]
    batched = evaluate_robots(random_jobs(n, n, w_o, sensors))
    for (u, w, force), single, batch in zip(expected, one_by_one, batched, strict=True):
        for result in (single, batch):
            assert (result.linear, result.angular) == (u, w)
            np.testing.assert_array_equal(result.force, force)


@pytest.mark.parametrize("n", [1, 7, 30])
def test_on_adds_the_repulsion_and_a_batch_equals_one_by_one(n: int) -> None:
    jobs = random_jobs(n, n, 3.0, True)
    one_by_one = [robot_command(*job.arguments()) for job in jobs]
    batched = evaluate_robots(random_jobs(n, n, 3.0, True))
    for job, single, batch in zip(jobs, one_by_one, batched, strict=True):
        assert (single.linear, single.angular) == (batch.linear, batch.angular)
        np.testing.assert_array_equal(single.force, batch.force)
        _, _, without = reference(job)
        if job.ir_ranges is not None:
            repulsion = avoidance_force(job.ir_ranges, job.heading, 3.0)
            np.testing.assert_allclose(single.force, without + repulsion, rtol=0, atol=1e-12)
        else:
            np.testing.assert_array_equal(single.force, without)


def drive_at_wall(w_o: float, heading: float) -> tuple[float, float, float]:
    """One robot driven (v_d = +x) at a wall at x = 0.5 m, no noise, its IR ranges cast
    every step; the closest its body came to the wall [m], its final x [m] and heading."""
    geometry = MonaGeometry()
    walls = np.array([-5.0, 0.5, -5.0, 5.0])
    gains = Gains(d_r=0.0, d_theta=0.0, w_o=w_o)
    command = SwarmCommand(direction=(1.0, 0.0), omega=0.0, center=(0.0, 0.0))
    position, theta = np.array([0.0, 0.0]), heading
    closest = np.inf
    for _ in range(400):  # 20 s at 20 Hz
        ranges = ir_ranges(position[None], np.array([theta]), walls=walls)[0]
        result = robot_command(
            position, theta, np.zeros((0, 2)), np.zeros(0), gains, command, 0.05,
            limits=(0.13, 3.4), ir_ranges=ranges,
        )  # fmt: skip
        positions, headings = model.unicycle_step(
            position[None], np.array([theta]), np.array([result.linear]),
            np.array([result.angular]), 0.05,
        )  # fmt: skip
        position, theta = positions[0], float(headings[0])
        rim = position[0] + geometry.axle_offset * np.cos(theta) + geometry.body_radius
        closest = min(closest, 0.5 - rim)
    return closest, float(position[0]), theta


@pytest.mark.parametrize("heading", [0.0, 0.4, -0.9])
def test_a_robot_driven_at_a_wall_stays_off_it_only_with_the_term(heading: float) -> None:
    closest, _, theta = drive_at_wall(3.0, heading)
    assert 0.0 < closest < AVOIDANCE_RANGE  # it came near, saw the wall, kept off
    if heading != 0.0:  # met obliquely, it turned along the wall
        assert abs(np.cos(theta)) < 0.05
    closest, x, _ = drive_at_wall(0.0, heading)
    assert closest < 0.0 and x > 0.5  # without: straight through (no contacts here)
