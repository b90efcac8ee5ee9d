"""The shared contact rule (aes_ros.contacts): bodies end apart, inside walls, outside obstacles."""

from __future__ import annotations

import math

import numpy as np
import pytest

from aes_ros.contacts import CLOSE, NEAR, contact_geometry, resolve_contacts, resolve_listed
from aes_ros.mona.geometry import MonaGeometry
from aes_ros.pair_list import near_pairs

R = MonaGeometry().body_radius
A = MonaGeometry().axle_offset
MM = 1e-3
NO_PAIRS = np.empty((0, 2), np.int64)


def centres(positions: np.ndarray, headings: np.ndarray) -> np.ndarray:
    return positions + A * np.stack([np.cos(headings), np.sin(headings)], axis=-1)


def drive(positions, headings, speed, steps, dt=0.02, walls=None, circles=None, boxes=None):
    """Euler steps straight ahead at ``speed`` [m/s], contacts resolved after each."""
    w, c, b = contact_geometry(walls, circles, boxes)
    total = 0
    for _ in range(steps):
        positions[:, 0] += speed * dt * np.cos(headings)
        positions[:, 1] += speed * dt * np.sin(headings)
        found, closest = resolve_contacts(positions, headings, R, A, w, c, b, 4)
        total += found
    return total, closest


def test_two_discs_pushed_together_end_apart() -> None:
    pos = np.array([[-0.2, 0.0], [0.2, 0.0]])
    head = np.array([0.0, math.pi])
    total, closest = drive(pos, head, 0.1, 200)
    gap = np.linalg.norm(np.diff(centres(pos, head), axis=0))
    assert gap >= 2 * R - MM
    assert closest == pytest.approx(gap)
    assert total > 0  # they did meet
    assert head.tolist() == [0.0, math.pi]  # headings kept


def test_robot_driven_into_a_wall_stops_at_it() -> None:
    pos = np.array([[0.0, 0.0]])
    head = np.array([0.3])
    walls = (-0.5, 0.5, -0.5, 0.5)
    total, closest = drive(pos, head, 0.1, 300, walls=walls)
    c = centres(pos, head)[0]
    assert total > 0
    assert c[0] == pytest.approx(0.5 - R, abs=1e-9)  # at the wall, inside by its radius
    assert c[1] <= 0.5 - R + 1e-9
    assert math.isinf(closest)


@pytest.mark.parametrize(
    ("circles", "boxes"), [([(0.5, 0.0, 0.1)], None), (None, [(0.4, 0.6, -0.3, 0.3)])]
)
def test_robot_cannot_enter_an_obstacle(circles, boxes) -> None:
    pos = np.array([[0.0, 0.01]])
    head = np.array([0.0])
    for _ in range(300):
        drive(pos, head, 0.1, 1, circles=circles, boxes=boxes)
        c = centres(pos, head)[0]
        if circles is not None:
            assert np.hypot(c[0] - 0.5, c[1]) >= 0.1 + R - 1e-9
        else:
            assert c[0] <= 0.4 - R + 1e-9
    assert c[0] > 0.2  # it got there


def test_a_crowd_converges_without_deep_overlaps() -> None:
    rng = np.random.default_rng(3)
    pos = rng.uniform(-0.3, 0.3, (100, 2))
    head = rng.uniform(-math.pi, math.pi, 100)
    w, c, b = contact_geometry((-0.6, 0.6, -0.6, 0.6))
    for _ in range(50):  # the same state settled over steps, as in a run
        resolve_contacts(pos, head, R, A, w, c, b, 4)
    _, closest = resolve_contacts(pos, head, R, A, w, c, b, 4)
    ctr = centres(pos, head)
    d = np.linalg.norm(ctr[:, None] - ctr[None], axis=-1)[np.triu_indices(100, 1)]
    assert d.min() >= 2 * R - MM
    assert closest == pytest.approx(d.min())
    assert np.all(np.abs(ctr) <= 0.6 - R + 1e-9)


def test_no_overlap_leaves_positions_untouched_bit_for_bit() -> None:
    rng = np.random.default_rng(0)
    grid = np.stack(np.meshgrid(np.arange(10), np.arange(10)), -1).reshape(-1, 2) * 0.2
    pos = grid + rng.uniform(-0.01, 0.01, grid.shape)
    head = rng.uniform(-math.pi, math.pi, 100)
    w, c, b = contact_geometry((-1.0, 3.0, -1.0, 3.0), [(5.0, 5.0, 0.1)], [(6, 7, 6, 7)])
    for near in (False, True):  # no body near another; one pair 1 cm from touching
        if near:
            pos[1] = pos[0] + A * np.array([np.cos(head[0]), 0.0]) + [0.09, 0.0]
            pos[1] -= A * np.array([np.cos(head[1]), np.sin(head[1])])
            pos[1, 1] += A * np.sin(head[0])
        before = pos.copy()
        found, closest = resolve_contacts(pos, head, R, A, w, c, b, 4)
        assert found == 0
        assert pos.tobytes() == before.tobytes()
        ctr = centres(pos, head)
        d = np.linalg.norm(ctr[:, None] - ctr[None], axis=-1)[np.triu_indices(100, 1)]
        if near:  # the smallest distance, exact when below 3r
            assert closest == pytest.approx(0.09, abs=1e-12) and d.min() == pytest.approx(0.09)
        else:  # nothing within 3r: inf
            assert math.isinf(closest) and d.min() > 3 * R


def test_same_input_same_bits() -> None:
    rng = np.random.default_rng(1)
    pos = rng.uniform(-0.2, 0.2, (50, 2))
    head = rng.uniform(-math.pi, math.pi, 50)
    a, b = pos.copy(), pos.copy()
    w, c, bx = contact_geometry()
    assert resolve_contacts(a, head, R, A, w, c, bx, 4) == resolve_contacts(
        b, head, R, A, w, c, bx, 4
    )
    assert a.tobytes() == b.tobytes()


def test_bad_walls_are_refused() -> None:
    with pytest.raises(ValueError, match="walls"):
        contact_geometry((0.0, 1.0, 2.0))


@pytest.mark.parametrize(
    ("near", "skin"),
    [(NEAR * R, 0.5 * (NEAR - CLOSE) * R), (0.26, 0.04)],
    ids=["contacts' list", "the list the IR rays share"],
)
def test_a_list_kept_over_steps_gives_the_bits_of_a_fresh_one(near: float, skin: float) -> None:
    """The kernel keeps its candidate pairs over steps (resolve_listed), longer ones when
    the IR rays use them too; the bridge calls resolve_contacts, which makes them afresh:
    both must move the robots alike, bit for bit. The pairs it hands to the rays are every
    pair closer than their reach after the step, no more."""
    rng = np.random.default_rng(5)
    pos = rng.uniform(-0.4, 0.4, (60, 2))
    head = rng.uniform(-math.pi, math.pi, 60)
    w, c, b = contact_geometry((-0.5, 0.5, -0.5, 0.5), [(0.0, 0.0, 0.05)], [(0.2, 0.3, 0.2, 0.3)])
    kept, fresh = pos.copy(), pos.copy()
    ref_x, ref_y = np.full(60, np.inf), np.full(60, np.inf)
    pairs = np.empty((0, 2), np.int64)
    rebuilt = 0
    for _ in range(100):
        step = 0.004 * np.stack([np.cos(head), np.sin(head)], -1)  # 4 mm towards the heading
        kept += step
        fresh += step
        cx = kept[:, 0] + A * np.cos(head)
        cy = kept[:, 1] + A * np.sin(head)
        before = pairs
        k1, d1, pairs, _, _ = resolve_listed(
            kept, cx, cy, R, w, c, b, 8, pairs, ref_x, ref_y, near, skin, 0.0, NO_PAIRS
        )
        rebuilt += pairs is not before
        k2, d2 = resolve_contacts(fresh, head, R, A, w, c, b, 8)
        assert (k1, d1) == (k2, d2)
        assert kept.tobytes() == fresh.tobytes()
    assert 1 < rebuilt < 100  # the list was kept for some steps and remade for others


def test_the_pairs_handed_to_the_rays_are_those_within_their_reach() -> None:
    """With the IR rays on, the kernel's rays take their candidate pairs from the contact
    sweep that settled a step: every pair whose centres are closer than the rays' reach
    after the contacts, no more; none when no sweep met the final state."""
    rng = np.random.default_rng(6)
    pos = rng.uniform(-0.6, 0.6, (24, 2))
    head = rng.uniform(-math.pi, math.pi, 24)
    w, c, b = contact_geometry((-0.8, 0.8, -0.8, 0.8))
    near, skin, reach = 0.3, 0.06, 0.18
    ref_x, ref_y = np.full(24, np.inf), np.full(24, np.inf)
    pairs, within = np.empty((0, 2), np.int64), np.empty((0, 2), np.int64)
    i, j = np.triu_indices(24, 1)
    handed = touched = calm = 0
    for _ in range(50):
        pos += 0.004 * np.stack([np.cos(head), np.sin(head)], -1)
        cx = pos[:, 0] + A * np.cos(head)
        cy = pos[:, 1] + A * np.sin(head)
        found, _, pairs, within, n_within = resolve_listed(
            pos, cx, cy, R, w, c, b, 8, pairs, ref_x, ref_y, near, skin, reach, within
        )
        if n_within < 0:
            continue
        handed += 1
        touched += found > 0
        calm += found == 0
        dx, dy = cx[j] - cx[i], cy[j] - cy[i]
        close = dx * dx + dy * dy < reach * reach
        np.testing.assert_array_equal(within[:n_within], np.stack([i[close], j[close]], 1))
    assert handed > 40 and touched > 5 and calm > 5  # most settle, some after contacts
    _, _, _, _, n_within = resolve_listed(  # one sweep for a jam: the final state unmet
        pos, cx, cy, 1.0, w, c, b, 1, pairs, ref_x, ref_y, near, skin, reach, within
    )
    assert n_within == -1


def test_robots_far_apart_or_not_finite_are_handled() -> None:
    """A run whose gains diverge: robots kilometres apart or at NaN/inf. The grid stays
    small (no allocation of (distance / 4r)² cells), the finite robots still separate and
    the non-finite ones are left as they are."""
    pos = np.array([[0.0, 0.0], [0.05, 0.0], [1e12, -1e12], [np.nan, 0.0], [np.inf, 1.0]])
    head = np.zeros(5)
    before = pos.copy()
    w, c, b = contact_geometry((-1.0, 1.0, -1.0, 1.0), [(0.5, 0.5, 0.1)], [(0.6, 0.7, 0, 1)])
    found, closest = resolve_contacts(pos, head, R, A, w, c, b, 8)
    assert found >= 1  # the first two overlapped
    assert np.hypot(*(pos[1] - pos[0])) == pytest.approx(2 * R)
    assert closest == pytest.approx(2 * R)
    np.testing.assert_array_equal(pos[3:], before[3:])


@pytest.mark.parametrize("cutoff", [4 * R, 7 * R, 0.5])
def test_near_pairs_are_every_close_pair_in_order(cutoff: float) -> None:
    """The grid finds exactly the pairs a check of all pairs finds, in lexicographic
    order, also when robots pile up, spread far or are not finite."""
    rng = np.random.default_rng(11)
    for trial in range(60):
        n = int(rng.integers(1, 150))
        cx = rng.uniform(0.0, rng.uniform(0.05, 3.0), n)
        cy = rng.uniform(0.0, rng.uniform(0.01, 3.0), n)
        if trial % 5 == 0:
            cx[rng.integers(n)] = np.nan
        i, j = np.triu_indices(n, 1)
        close = np.hypot(cx[j] - cx[i], cy[j] - cy[i]) < cutoff  # NaN: not close
        expected = np.stack([i[close], j[close]], axis=1)
        np.testing.assert_array_equal(near_pairs(cx, cy, cutoff), expected)


def test_a_list_follows_a_swarm_that_turns_and_drives_as_a_body() -> None:
    """A sheet that rotates and translates keeps its list (the references follow the rigid
    motion), and the kept list still moves the robots as a fresh one does, bit for bit."""
    rng = np.random.default_rng(8)
    grid = np.stack(np.meshgrid(np.arange(8), np.arange(8)), -1).reshape(-1, 2) * 0.09
    pos = grid + rng.uniform(-0.005, 0.005, grid.shape)
    head = rng.uniform(-math.pi, math.pi, len(pos))
    w, c, b = contact_geometry()
    kept, fresh = pos.copy(), pos.copy()
    ref_x, ref_y = np.full(len(pos), np.inf), np.full(len(pos), np.inf)
    pairs = np.empty((0, 2), np.int64)
    turn = np.array([[math.cos(0.03), -math.sin(0.03)], [math.sin(0.03), math.cos(0.03)]])
    made = 0
    for _ in range(100):  # 3 rad and 1 m in all: every robot moves far beyond the skin
        jitter = rng.normal(0.0, 2e-4, pos.shape)
        kept = kept @ turn.T + [0.01, 0.0] + jitter
        fresh = fresh @ turn.T + [0.01, 0.0] + jitter
        head = head + 0.03
        cx = kept[:, 0] + A * np.cos(head)
        cy = kept[:, 1] + A * np.sin(head)
        before = pairs
        k1, d1, pairs, _, _ = resolve_listed(
            kept, cx, cy, R, w, c, b, 8, pairs, ref_x, ref_y, NEAR * R,
            0.5 * (NEAR - CLOSE) * R, 0.0, NO_PAIRS,
        )  # fmt: skip
        made += pairs is not before
        k2, d2 = resolve_contacts(fresh, head, R, A, w, c, b, 8)
        assert (k1, d1) == (k2, d2)
        assert kept.tobytes() == fresh.tobytes()
    assert made <= 10  # a list made afresh whenever a robot moved r/2 would be ~80
