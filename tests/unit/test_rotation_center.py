"""The rotation-centre rule (robot_node.rotation_center) hears two streams, the poses and
the supervisor's centres, each in its publisher's order but interleaved as the network
delivers them: its choice must depend on what was heard, never on that interleaving."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_node.rotation_center import CENTROID_MEMORY, RotationCenterRule

S = 1_000_000_000  # ns per second
Message = tuple[str, int, np.ndarray]  # ("poses" | "center", stamp [ns], (2,) point)


def run(rule: RotationCenterRule, messages: list[Message]) -> dict[int, np.ndarray]:
    """Feed ``messages`` in this order; x_c of the step of each poses message, by stamp
    (the first time it is heard: a repeat is answered too, but the first answer counts)."""
    used: dict[int, np.ndarray] = {}
    for kind, stamp, point in messages:
        if kind == "poses":
            rule.on_poses(stamp, point)  # as SwarmInputs: the rule first, then the robots
            used.setdefault(stamp, rule.center(point))
        else:
            rule.on_center(stamp, point)
    return used


def interleavings(poses: list[Message], centers: list[Message]):
    """Every merge of the two streams that keeps each stream's order."""
    n = len(poses) + len(centers)
    for slots in itertools.combinations(range(n), len(centers)):
        merged, p, c = [], iter(poses), iter(centers)
        for k in range(n):
            merged.append(next(c) if k in slots else next(p))
        yield merged


def test_a_centre_heard_before_any_poses_waits_for_them() -> None:
    """The failing order of tests/system/test_robot_node.py's lockstep test: the
    supervisor's first centroid (of the warm-up poses, 0.5 s) reaches the host before
    those poses, and its next one (1.0 s) only after the poses of 1.05 s. The old rule
    took the first for a fixed point and drove the 1.05 s step about the 1.0 s centroid
    (9e-6 m off the offline model after 40 steps)."""
    c0, c1 = np.array([0.1, 0.2]), np.array([0.08, 0.19])
    rule = RotationCenterRule(None)
    used = run(
        rule,
        [
            ("center", S // 2, c0.copy()),
            ("poses", S // 2, c0),
            ("poses", S, c0),
            ("poses", S + S // 20, c1),
            ("center", S, c0.copy()),
        ],
    )
    assert used[S + S // 20] is c1
    assert rule.follows_centroid


def test_every_interleaving_of_a_lockstep_start_uses_each_poses_own_centroid() -> None:
    """All 20 orders of the warm-up and the first two steps, as the test's host may
    hear them: each step's x_c is its own poses' centroid."""
    stamps = [S // 2, S, S + S // 20]
    centroids = [np.array([0.1, 0.2]), np.array([0.1, 0.2]), np.array([0.08, 0.19])]
    poses = [("poses", s, c) for s, c in zip(stamps, centroids, strict=True)]
    centers = [("center", s, c.copy()) for s, c in zip(stamps, centroids, strict=True)]
    for order in interleavings(poses, centers):
        used = run(RotationCenterRule(None), order)
        for s, c in zip(stamps, centroids, strict=True):
            assert used[s] is c, [(kind, stamp) for kind, stamp, _ in order]


@st.composite
def live_centroid_streams(draw):
    """Poses (increasing stamps, some repeated as the lockstep test does), the
    supervisor's live centroids of some of them, and one interleaving."""
    n = draw(st.integers(1, CENTROID_MEMORY))
    stamps = sorted(draw(st.sets(st.integers(0, 40), min_size=n, max_size=n)))
    xy = st.tuples(st.integers(-9, 9), st.integers(-9, 9)).map(lambda t: np.array(t, float))
    steps = [("poses", stamp * S // 20, draw(xy)) for stamp in stamps]
    poses = [step for step in steps for _ in range(draw(st.integers(1, 2)))]
    centers = [("center", stamp, c.copy()) for _, stamp, c in steps if draw(st.booleans())]
    order = draw(st.permutations(["poses"] * len(poses) + ["center"] * len(centers)))
    streams = {"poses": iter(poses), "center": iter(centers)}
    return [next(streams[kind]) for kind in order]


@settings(max_examples=300, deadline=None)
@given(messages=live_centroid_streams())
def test_live_centroids_in_any_interleaving_give_each_step_its_own_centroid(messages) -> None:
    """A supervisor that follows the live centroid, heard in any interleaving with the
    poses: every step is about its own poses' centroid, as in the offline model."""
    used = run(RotationCenterRule(None), messages)
    for kind, stamp, centroid in messages:
        if kind == "poses":
            assert used[stamp] is centroid


def in_force(
    default: np.ndarray | None, poses: list[Message], centers: list[Message]
) -> np.ndarray | None:
    """The rule's specification: x_c for a step with the newest of ``poses`` after
    hearing ``poses`` and ``centers`` (each in its stream's order) in any interleaving.

    The newest centre that the poses reach is in force: the live centroid if the poses
    of its stamp were heard and match it, a fixed point if the poses passed its stamp
    without them; a centre ahead of every poses heard is not decided yet."""
    heard = {stamp: c for _, stamp, c in poses}
    last, centroid = poses[-1][1], poses[-1][2]
    for _, stamp, point in reversed(centers):
        if stamp in heard:
            return centroid if np.array_equal(heard[stamp], point) else point
        if stamp < last:
            return point
    return centroid if default is None else default


@st.composite
def any_streams(draw):
    """The rule's default; poses (increasing stamps, some repeated); centres in any
    stamp order (live centroids of some poses, other points: fixed, or the centroid of
    poses this process lost); and one interleaving."""
    default = draw(st.none() | st.just(np.array([7.0, -7.0])))
    n = draw(st.integers(1, CENTROID_MEMORY))
    stamps = sorted(draw(st.sets(st.integers(0, 12), min_size=n, max_size=n)))
    poses: list[Message] = []
    for stamp in stamps:
        xy = np.array(draw(st.tuples(st.integers(-3, 3), st.integers(-3, 3))), dtype=float)
        poses += [("poses", stamp, xy)] * draw(st.integers(1, 2))
    centers: list[Message] = []
    for _ in range(draw(st.integers(0, CENTROID_MEMORY))):
        if draw(st.booleans()):
            _, stamp, c = draw(st.sampled_from(poses))
            centers.append(("center", stamp, c.copy()))
        else:
            xy = draw(st.tuples(st.integers(-3, 3), st.integers(-3, 3)))
            centers.append(("center", draw(st.integers(0, 14)), np.array(xy, dtype=float)))
    order = draw(st.permutations(["poses"] * len(poses) + ["center"] * len(centers)))
    streams = {"poses": iter(poses), "center": iter(centers)}
    return default, [next(streams[kind]) for kind in order]


@settings(max_examples=500, deadline=None)
@given(case=any_streams())
def test_the_centre_in_force_is_a_function_of_what_was_heard(case) -> None:
    """After every message, whatever the interleaving, x_c is that of in_force() over
    the poses and centres heard so far (for robots without poses: the newest centre)."""
    default, messages = case
    rule = RotationCenterRule(default)
    heard: dict[str, list[Message]] = {"poses": [], "center": []}
    for message in messages:
        kind, stamp, point = message
        if kind == "poses":
            rule.on_poses(stamp, point)
        else:
            rule.on_center(stamp, point)
        heard[kind].append(message)
        newest = heard["center"][-1][2] if heard["center"] else default
        assert same(rule.center(None), newest)
        if heard["poses"]:
            want = in_force(default, heard["poses"], heard["center"])
            got = rule.center(heard["poses"][-1][2])
            assert same(got, want), (got, want)


def same(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    return a is b or (a is not None and b is not None and np.array_equal(a, b))
