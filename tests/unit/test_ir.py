"""The simulated IR proximity sensors (aes_ros.ir): exact distances on a synthetic layout,
the response curve of the Mona driver's IR model, noise."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from aes_ros.ir import IR_ANGLES, cast_rays, mounting, ray_distances
from aes_ros.ir_readings import IrResponse, ir_ranges
from aes_ros.mona.geometry import MonaGeometry
from aes_ros.mona.sensors import IrModel

G = MonaGeometry()
R, A = G.body_radius, G.axle_offset
MAX = IrModel().max_range


def sensor(position, heading: float, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Sensor k's point on the rim and its ray's direction."""
    u = np.array([math.cos(heading + IR_ANGLES[k]), math.sin(heading + IR_ANGLES[k])])
    centre = np.asarray(position) + A * np.array([math.cos(heading), math.sin(heading)])
    return centre + R * u, u


def pose_with_centre(centre: np.ndarray, heading: float) -> np.ndarray:
    """The pose point of a robot whose body centre is ``centre``."""
    return centre - A * np.array([math.cos(heading), math.sin(heading)])


def test_a_lone_robot_sees_nothing():
    np.testing.assert_array_equal(ir_ranges([[0.3, -0.2]], [1.0]), np.full((1, 5), MAX))


@pytest.mark.parametrize("turn", [0.0, 0.7, -2.5])
def test_two_robots_facing_each_other_read_the_gap_between_their_rims(turn):
    gap = 0.063
    centre_distance = gap + 2 * R
    # A's body centre at c, B's at c + centre_distance ahead of A, B facing A; all turned.
    c = np.array([0.4, -1.1])
    u = np.array([math.cos(turn), math.sin(turn)])
    positions = np.array(
        [pose_with_centre(c, turn), pose_with_centre(c + centre_distance * u, turn + math.pi)]
    )
    ranges = ir_ranges(positions, [turn, turn + math.pi])
    assert ranges[:, 0] == pytest.approx([gap, gap], abs=1e-12)
    # the other sensors' rays pass beside a robot this far ahead
    assert ranges[:, 1:] == pytest.approx(MAX)


@pytest.mark.parametrize("k", range(5))
def test_each_sensor_looks_along_its_mounting_angle(k):
    heading, d = 0.3, 0.041
    s, u = sensor([0.0, 0.0], heading, k)
    # another robot whose centre lies on sensor k's ray, its rim d from the sensor
    other = pose_with_centre(s + (d + R) * u, -1.0)
    ranges = ir_ranges([[0.0, 0.0], other], [heading, -1.0])
    assert ranges[0, k] == pytest.approx(d, abs=1e-12)
    assert np.delete(ranges[0], k) == pytest.approx(MAX)


def test_a_wall_ahead():
    d = 0.05
    walls = [-1.0, A + R + d, -1.0, 1.0]  # x_max d ahead of sensor 0
    ranges = ir_ranges([[0.0, 0.0]], [0.0], walls=walls)[0]
    # the ±37° sensors sit R (1 − cos 37°) behind sensor 0 and look 37° askew; at ±67°
    # the wall is 0.19 m away: too far
    c = math.cos(IR_ANGLES[1])
    slant = (d + R * (1 - c)) / c
    expected = [d, slant, slant, MAX, MAX]
    assert ranges == pytest.approx(expected, abs=1e-12)


def test_a_robot_in_a_corner_and_one_through_a_wall():
    walls = [0.0, 1.0, 0.0, 1.0]
    # heading +45° into the corner (1, 1): the ±37° rays are 8° from the diagonal
    pose = pose_with_centre(np.array([0.93, 0.93]), math.pi / 4)
    ranges = ir_ranges([pose, [1.05, 0.5]], [math.pi / 4, 0.0], walls=walls)
    s1, u1 = sensor(pose, math.pi / 4, 1)
    assert ranges[0, 1] == pytest.approx((1.0 - s1[1]) / u1[1], abs=1e-12)  # meets y = 1
    s2, u2 = sensor(pose, math.pi / 4, 2)
    assert ranges[0, 2] == pytest.approx((1.0 - s2[0]) / u2[0], abs=1e-12)  # meets x = 1
    assert ranges[1] == pytest.approx(np.zeros(5))  # outside the arena: pressed to the wall


def test_a_circle_and_a_box():
    d, r = 0.03, 0.02
    s3, u3 = sensor([0.0, 0.0], 0.0, 3)
    circle = [*(s3 + (d + r) * u3), r]
    box = [A + R + 0.07, 0.5, -0.01, 0.01]  # a thin post 0.07 m ahead of sensor 0
    ranges = ir_ranges([[0.0, 0.0]], [0.0], circles=[circle], boxes=[box])[0]
    assert ranges == pytest.approx([0.07, MAX, MAX, d, MAX], abs=1e-12)
    # an obstacle pressed against the sensor reads 0
    inside = ir_ranges([[0.0, 0.0]], [0.0], boxes=[[A + R - 0.001, 0.2, -0.1, 0.1]])[0]
    assert inside[0] == 0.0
    c = math.cos(IR_ANGLES[1])
    assert inside[1:3] == pytest.approx((R * (1 - c) - 0.001) / c, abs=1e-12)


def reference(positions: np.ndarray, headings: np.ndarray) -> np.ndarray:
    """Robots only, every sensor against every other disc, in plain numpy."""
    centres = positions + A * np.stack([np.cos(headings), np.sin(headings)], -1)
    angle = headings[:, None] + IR_ANGLES  # (N, 5)
    u = np.stack([np.cos(angle), np.sin(angle)], -1)  # (N, 5, 2)
    s = centres[:, None] + R * u
    q = s[:, :, None] - centres[None, None]  # (N, 5, N, 2)
    b = np.einsum("iakx,iax->iak", q, u)
    c = (q**2).sum(-1) - R**2
    disc = b**2 - c
    with np.errstate(invalid="ignore"):
        t = np.where((b < 0) & (disc >= 0), -b - np.sqrt(disc), np.inf)
    t = np.where(c <= 0, 0.0, t)
    n = len(headings)
    t[np.arange(n), :, np.arange(n)] = np.inf  # not itself
    return np.minimum(t.min(-1), MAX)


@pytest.mark.parametrize(
    ("n", "spread"),
    [(1, 0.12), (7, 0.12), (100, 0.12), (100, 0.0), (300, 5.0)],
    ids=["1", "7", "100", "100 in a heap", "300 over a field with clusters"],
)
def test_the_kernel_equals_a_plain_numpy_reference(n, spread):
    rng = np.random.default_rng(n)
    positions = rng.uniform(0, 0.12 * math.sqrt(n), (n, 2))
    if spread:  # clusters scattered over a large field: the neighbour grid widens its cells
        positions[: n // 2] = rng.uniform(0, spread * 0.12 * n, (n // 2, 2))
    else:  # all piled up in one cell, pressed into each other
        positions *= 0.1
    headings = rng.uniform(-math.pi, math.pi, n)
    ranges = ir_ranges(positions, headings)
    assert ranges.shape == (n, 5)
    np.testing.assert_allclose(ranges, reference(positions, headings), atol=1e-12)
    if n >= 100:
        assert (ranges < MAX).sum() > 20  # a layout in which robots see each other
    if not spread:
        assert (ranges == 0.0).sum() > 100


@pytest.mark.parametrize("k", range(5))
@pytest.mark.parametrize("side", [1.0 - 1e-7, 1.0 + 1e-7], ids=["grazed", "passed by"])
def test_a_ray_that_grazes_a_robot_sees_it(k, side):
    """Only the rays whose line passes within a radius of another robot are cast at it
    (a test in the robot's frame); one that just grazes the other disc still sees it,
    one that just passes it does not."""
    heading = 0.3
    s, u = sensor([0.0, 0.0], heading, k)
    normal = np.array([-u[1], u[0]])
    other = s + 0.05 * u + side * R * normal  # the other centre, just beside the ray's line
    positions = np.array([[0.0, 0.0], pose_with_centre(other, 1.0)])
    ranges = ir_ranges(positions, [heading, 1.0])
    expected = reference(positions, np.array([heading, 1.0]))
    np.testing.assert_allclose(ranges, expected, atol=1e-12)
    assert (ranges[0, k] < MAX) == (side < 1.0)


def test_rays_from_the_kernels_cosines_are_the_rays_from_headings():
    """The offline kernel passes the cos and sin of the headings it already has
    (cast_rays); the distances are those of ray_distances to the bit."""
    rng = np.random.default_rng(5)
    positions = rng.uniform(0.0, 1.2, (100, 2))
    headings = rng.uniform(-math.pi, math.pi, 100)
    walls, circles, boxes = (
        np.array([0.0, 1.2, 0.0, 1.2]),
        np.array([[0.6, 0.6, 0.1]]),
        np.zeros((0, 4)),
    )
    a, b = np.empty((100, 5)), np.empty((100, 5))
    ray_distances(positions, headings, R, A, IR_ANGLES, MAX, walls, circles, boxes, a)
    cast_rays(
        positions, np.cos(headings), np.sin(headings), R, A, mounting(IR_ANGLES), MAX, walls,
        circles, boxes, b,
    )  # fmt: skip
    assert a.tobytes() == b.tobytes()
    assert (a < MAX).sum() > 50


def test_a_robot_lost_to_a_diverged_run_sees_nothing_and_is_not_seen():
    """A run whose gains diverge ends with robots at NaN or inf: they read nothing and are
    invisible, and the others read what they would read without them."""
    walls = (-1.0, 1.0, -1.0, 1.0)
    finite = np.array([[0.0, 0.0], [0.12, 0.0]])  # robot 1 right ahead of robot 0
    alone = ir_ranges(finite, [0.0, 0.0], walls=walls, circles=[(0.0, 0.5, 0.1)])
    for lost in ([math.nan, 0.0], [math.inf, 0.0], [0.05, -math.inf]):
        poses = np.array([finite[0], lost, finite[1]])
        got = ir_ranges(poses, [0.0, 0.3, 0.0], walls=walls, circles=[(0.0, 0.5, 0.1)])
        np.testing.assert_array_equal(got[[0, 2]], alone)
        np.testing.assert_array_equal(got[1], np.full(5, MAX))
    assert ir_ranges(np.zeros((0, 2)), np.zeros(0)).shape == (0, 5)
    assert (ir_ranges([[math.nan, 0.0]], [math.nan]) == MAX).all()


def test_the_kernel_is_callable_from_numba_code():
    @njit
    def front_readings(positions, headings):
        out = np.empty((len(headings), 5))
        ray_distances(
            positions,
            headings,
            R,
            A,
            IR_ANGLES,
            MAX,
            np.zeros(0),
            np.zeros((0, 3)),
            np.zeros((0, 4)),
            out,
        )
        return out[:, 0]

    front = front_readings(np.array([[0.0, 0.0], [0.2, 0.0]]), np.array([0.0, math.pi]))
    assert front == pytest.approx([0.2 - 2 * A - 2 * R] * 2)


@pytest.mark.parametrize("falling", [True, False])
def test_readings_go_through_a_whole_adc_count_of_the_drivers_ir_model(falling):
    model = IrModel(falling=falling)
    d = np.linspace(0.0, 0.12, 241)
    positions = np.array([[0.0, 0.0], [0.0, 0.0]])
    readings = np.empty_like(d)
    # one robot per distance: a box d ahead of sensor 0
    for i, di in enumerate(d):
        box = [A + R + di, 1.0, -0.001, 0.001]
        readings[i] = ir_ranges(
            positions[:1], [0.0], boxes=[box], response=IrResponse(model=model)
        )[0, 0]
    seen = d < model.max_range
    signal = model.offset + model.gain / np.maximum(d[seen], 1e-9)
    raw = np.clip(np.round(model.FULL_SCALE - signal if falling else signal), 0, 1023)
    np.testing.assert_allclose(readings[seen], model.range(raw), rtol=1e-12)
    assert readings[~seen] == pytest.approx(model.max_range)
    # off by at most half a count: |gain/(s ± 1/2 − offset) − gain/(s − offset)| = d d' / 2 gain
    inside = seen & (d > 0.011)
    d, reading = d[inside], readings[inside]
    assert np.all(np.abs(reading - d) <= 0.5 * d * reading / model.gain + 1e-12)
    assert readings.min() == pytest.approx(model.range(0 if falling else 1023))


def test_noise_has_its_sigma_is_seeded_and_leaves_nothing_seen_alone():
    # 200 robots in a row, 0.05 m apart rim to rim: sensor 0 sees the next one
    n, gap = 200, 0.05
    positions = np.stack([np.arange(n) * (gap + 2 * R), np.zeros(n)], -1)
    response = IrResponse(noise=0.004, quantise=False)
    first = ir_ranges(positions, np.zeros(n), response=response, rng=np.random.default_rng(5))
    again = ir_ranges(positions, np.zeros(n), response=response, rng=np.random.default_rng(5))
    np.testing.assert_array_equal(first, again)
    errors = first[:-1, 0] - gap
    assert abs(errors.mean()) < 0.001 and 0.0035 < errors.std() < 0.0045
    assert first[-1] == pytest.approx(MAX) and first[:, 3:] == pytest.approx(MAX)
    with pytest.raises(ValueError, match="rng"):
        ir_ranges(positions, np.zeros(n), response=response)
    with pytest.raises(ValueError, match="walls"):
        ir_ranges(positions, np.zeros(n), walls=[0.0, 1.0])
