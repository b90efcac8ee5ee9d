"""Physics and contracts of the AES model (E1–E9), without ROS."""

from __future__ import annotations

import numpy as np
import pytest

from aes_ros import formations, metrics, model
from aes_ros.model import Gains, SwarmCommand, robot_command
from aes_ros.robot_batch import RobotInput, evaluate_robots

QUIET = Gains(d_r=0.0, d_theta=0.0)


def test_stretched_spring_attracts_and_compressed_repels() -> None:
    rest = np.array([0.2])
    for dist, sign in [(0.3, +1), (0.1, -1)]:
        force = model.spring_force(np.array([[dist, 0.0]]), rest, k=1.0)
        assert np.sign(force[0]) == sign, f"spring at {dist} m should pull (+) / push (-)"
        assert force[1] == 0.0
        # magnitude (k/l)|d - l| (E1)
        assert force[0] == pytest.approx(sign * abs(dist - 0.2) / 0.2)


def test_perturbed_sheet_relaxes_instead_of_exploding() -> None:
    """A deformed sheet at rest (no drive, no noise, v0 = 0) must contract toward
    its rest lengths. With the paper's literal sign the springs would push
    stretched pairs apart and the elongation would grow without bound."""
    nominal = formations.square_grid(5, 5, 0.2)
    neighbors, rest = formations.neighbor_table(nominal, 0.202)
    rng = np.random.default_rng(3)
    pos = nominal + rng.uniform(-0.04, 0.04, nominal.shape)
    head = rng.uniform(-np.pi, np.pi, len(nominal))
    gains = Gains(alpha=0.066, beta=0.97, k=1.28, v0=0.0, d_r=0.0, d_theta=0.0)
    cmd = SwarmCommand(direction=(0.0, 0.0), omega=0.0)

    def elongation(p: np.ndarray) -> float:
        d = np.linalg.norm(p[neighbors] - p[:, None], axis=-1)
        return float(np.abs(np.where(neighbors >= 0, d - rest, 0.0)).sum())

    start = elongation(pos)
    for _ in range(2000):
        f = model.total_forces(pos, neighbors, rest, gains, cmd)
        u, w = model.motion_commands(f, head, gains, 0.05)
        pos, head = model.unicycle_step(pos, head, u, w, 0.05)
    assert elongation(pos) < 0.5 * start


def test_rigid_translation_is_a_fixed_point() -> None:
    """No noise, no drive, everyone aligned at rest lengths: nothing changes but a
    translation at v0, and ψ stays 1 (no force on anyone, E8's convention)."""
    nominal = formations.hexagonal_sheet(2, 0.2)
    neighbors, rest = formations.neighbor_table(nominal, 0.202)
    gains = Gains(d_r=0.0, d_theta=0.0)
    cmd = SwarmCommand(direction=(0.0, 0.0), omega=0.0)
    pos, head = nominal.copy(), np.full(len(nominal), 0.7)
    for _ in range(200):
        f = model.total_forces(pos, neighbors, rest, gains, cmd)
        assert metrics.alignment_order(f, head) == pytest.approx(1.0)
        u, w = model.motion_commands(f, head, gains, 0.05)
        np.testing.assert_allclose(u, gains.v0, atol=1e-12)
        pos, head = model.unicycle_step(pos, head, u, w, 0.05)
    shift = gains.v0 * 200 * 0.05 * np.array([np.cos(0.7), np.sin(0.7)])
    np.testing.assert_allclose(pos, nominal + shift, atol=1e-9)
    np.testing.assert_allclose(head, 0.7, atol=1e-12)


def test_two_agents_on_one_spring_keep_their_distance() -> None:
    pos = np.array([[0.0, 0.0], [0.2, 0.0]])
    head = np.array([0.3, 2.5])  # pointing in different directions
    neighbors = np.array([[1], [0]])
    rest = np.array([[0.2], [0.2]])
    cmd = SwarmCommand(direction=(0.0, 0.0), omega=0.0)
    dist = []
    for _ in range(3000):
        f = model.total_forces(pos, neighbors, rest, QUIET, cmd)
        u, w = model.motion_commands(f, head, QUIET, 0.05)
        pos, head = model.unicycle_step(pos, head, u, w, 0.05)
        dist.append(np.linalg.norm(pos[1] - pos[0]))
    assert max(dist) < 0.2 * 2.0, "the spring must hold the pair together"
    assert dist[-1] == pytest.approx(0.2, rel=0.01)
    assert metrics.heading_order(head) == pytest.approx(1.0, abs=1e-3)


def test_rotation_force_is_counter_clockwise_for_positive_omega() -> None:
    f = model.rotation_forces(np.array([[1.0, 0.0]]), np.zeros(2), omega=0.5, w_r=2.0)
    np.testing.assert_allclose(f, [[0.0, 1.0]])  # at +x, CCW points to +y


def test_robot_command_equals_the_swarm_computation() -> None:
    """The per-robot control law (what a ROS node calls) gives every robot the
    same command as the vectorised swarm step."""
    nominal = formations.square_grid(4, 4, 0.2)
    neighbors, rest = formations.neighbor_table(nominal, 0.202)
    rng = np.random.default_rng(0)
    pos = nominal + rng.uniform(-0.03, 0.03, nominal.shape)
    head = rng.uniform(-np.pi, np.pi, 16)
    center = tuple(pos.mean(axis=0))
    cmd = SwarmCommand(direction=(-1.0, 0.2), omega=-0.7, center=center)
    f = model.total_forces(pos, neighbors, rest, QUIET, cmd)
    u, w = model.motion_commands(f, head, QUIET, 0.05)
    for i in range(16):
        js = neighbors[i][neighbors[i] >= 0]
        out = model.robot_command(pos[i], head[i], pos[js], rest[i, : len(js)], QUIET, cmd, 0.05)
        assert out.linear == pytest.approx(u[i], abs=1e-12)
        assert out.angular == pytest.approx(w[i], abs=1e-12)
        np.testing.assert_allclose(out.force, f[i], atol=1e-12)


def test_robot_command_noise_is_seeded_and_clipping_applies() -> None:
    args = (np.zeros(2), 0.0, np.array([[0.3, 0.0]]), np.array([0.2]), Gains(), SwarmCommand())
    a = model.robot_command(*args, dt=0.05, rng=np.random.default_rng(7))
    b = model.robot_command(*args, dt=0.05, rng=np.random.default_rng(7))
    quiet = model.robot_command(*args, dt=0.05)
    assert (a.linear, a.angular) == (b.linear, b.angular)
    assert (a.linear, a.angular) != (quiet.linear, quiet.angular)
    clipped = model.robot_command(*args, dt=0.05, rng=np.random.default_rng(7), limits=(0.01, 0.02))
    assert abs(clipped.linear) <= 0.01 and abs(clipped.angular) <= 0.02


def test_coincident_robots_do_not_divide_by_zero() -> None:
    pos = np.zeros((2, 2))
    neighbors, rest = np.array([[1], [0]]), np.array([[0.2], [0.2]])
    with np.errstate(all="raise"):
        f = model.spring_forces(pos, neighbors, rest, 1.0)
        psi = metrics.alignment_order(f, np.zeros(2))
    assert np.all(np.isfinite(f)) and psi == 1.0


def test_metrics_on_known_configurations() -> None:
    head = np.array([0.0, 0.0, np.pi])
    assert metrics.heading_order(head) == pytest.approx(1 / 3)
    forces = np.array([[1.0, 0.0], [0.0, 2.0], [-3.0, 0.0]])
    # robot 0 along, robot 1 perpendicular, robot 2 against its force: |cos| = 1, 0, 1
    assert metrics.alignment_order(forces, head) == pytest.approx(2 / 3)
    assert metrics.total_force(forces) == pytest.approx(6.0)


def test_angular_velocity_recovers_a_rigid_rotation() -> None:
    pts = formations.square_grid(3, 4, 0.2) + np.array([1.0, -2.0])
    c = pts.mean(axis=0)
    angle = 0.1
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    moved = (pts - c) @ rot.T + c + np.array([0.05, 0.0])
    traj = np.stack([pts, moved])
    assert metrics.angular_velocity(traj, 0.5)[0] == pytest.approx(angle / 0.5)
    np.testing.assert_allclose(metrics.centroid_velocity(traj, 0.5)[0], [0.1, 0.0], atol=1e-12)


@pytest.mark.parametrize(("rows", "cols"), [(1, 7), (4, 4), (10, 10)])
def test_grid_neighbourhoods(rows: int, cols: int) -> None:
    nominal = formations.square_grid(rows, cols, 0.2)
    assert nominal.shape == (rows * cols, 2)
    np.testing.assert_allclose(nominal.mean(axis=0), 0.0, atol=1e-12)
    for factor, interior in [(1.01, 4), (1.5, 8)]:
        neighbors, rest = formations.neighbor_table(nominal, factor * 0.2)
        degree = (neighbors >= 0).sum(axis=1)
        if rows >= 3 and cols >= 3:
            assert degree.max() == interior
        # symmetric springs with the formation's distances
        for i, row in enumerate(neighbors):
            for slot, j in enumerate(row[row >= 0]):
                assert i in neighbors[j]
                assert rest[i, slot] == pytest.approx(np.linalg.norm(nominal[j] - nominal[i]))


def test_hexagonal_sheet_has_six_neighbours_inside() -> None:
    nominal = formations.hexagonal_sheet(3, 0.25)
    assert len(nominal) == 3 * 3 * 4 + 1
    neighbors, rest = formations.neighbor_table(nominal, 1.01 * 0.25)
    assert (neighbors >= 0).sum(axis=1).max() == 6
    np.testing.assert_allclose(rest[neighbors >= 0], 0.25)


def test_formation_from_csv(tmp_path) -> None:
    path = tmp_path / "f.csv"
    path.write_text("x,y\n0,0\n0.2,0\n0.4,0\n")
    nominal = formations.from_csv(path)
    np.testing.assert_allclose(nominal, [[0, 0], [0.2, 0], [0.4, 0]])
    neighbors, _ = formations.neighbor_table(nominal, 0.21)
    assert list((neighbors >= 0).sum(axis=1)) == [1, 2, 1]


def test_host_evaluates_its_robots_at_once_exactly_as_one_by_one() -> None:
    """``aes-robot-host`` evaluates all its robots in one batched call: the commands and
    forces are bit for bit those of robot_command() per robot, with neighbour counts,
    gains, noise, limits and rotation centres differing from robot to robot."""
    rng = np.random.default_rng(3)

    def jobs() -> list[RobotInput]:
        out = []
        for r in range(7):
            k = [0, 1, 3, 6, 4, 2, 6][r]
            gains = Gains(alpha=0.01 * (r + 1), beta=0.5 + r / 10, k=1.0 + r, d_r=0.1 * (r % 3))
            gains = Gains(**{**gains.__dict__, "d_theta": 0.02 * (r % 2)})
            noisy = gains.d_r > 0 or gains.d_theta > 0
            center = None if r == 4 else (0.3 * r, -0.2)
            out.append(
                RobotInput(
                    positions[r],
                    headings[r],
                    neighbours[r][:k],
                    rests[r][:k],
                    gains,
                    SwarmCommand((-1.0, 0.2 * r), [0.0, 0.4, -0.7][r % 3], center),
                    0.02 + 0.01 * r,
                    np.random.default_rng(r) if noisy else None,
                    (0.05, 1.0) if r % 2 else None,
                )
            )
        return out

    positions = rng.normal(size=(7, 2))
    headings = rng.uniform(-np.pi, np.pi, 7)
    neighbours = rng.normal(size=(7, 6, 2))
    rests = rng.uniform(0.1, 0.5, (7, 6))
    rests[3, 2] = 0.0  # a rest length latched on top of its neighbour
    batch_jobs, single_jobs = jobs(), jobs()
    for _ in range(3):  # each robot's generator advances alike, step after step
        batch = evaluate_robots(batch_jobs)
        single = [robot_command(*job.arguments()) for job in single_jobs]
        for a, b in zip(batch, single, strict=True):
            assert (a.linear, a.angular) == (b.linear, b.angular)
            assert np.array_equal(a.force, b.force)
    assert len({round(c.force[0], 9) for c in batch}) == 7  # the inputs really differ
