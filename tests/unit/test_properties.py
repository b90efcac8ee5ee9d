"""Property-based tests of the core functions: finite in, finite out, no division by zero."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from aes_ros import metrics, model
from aes_ros.model import Gains, SwarmCommand

coords = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
angles = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)


@st.composite
def swarms(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    n = draw(st.integers(1, 6))
    k = draw(st.integers(1, 3))
    # Few distinct values make coincident robots likely.
    pos = draw(arrays(float, (n, 2), elements=st.sampled_from([0.0, 0.2, -0.2]) | coords))
    head = draw(arrays(float, (n,), elements=angles))
    neighbors = draw(arrays(np.int64, (n, k), elements=st.integers(-1, n - 1)))
    # 0 marks padding; real rest lengths are physical distances (>= 1 mm).
    rest = draw(arrays(float, (n, k), elements=st.just(0.0) | st.floats(1e-3, 5.0)))
    return pos, head, neighbors, rest


@settings(max_examples=200, deadline=None)
@given(swarm=swarms(), omega=angles, center=st.none() | st.tuples(coords, coords))
def test_finite_inputs_give_finite_forces_commands_and_metrics(swarm, omega, center) -> None:
    pos, head, neighbors, rest = swarm
    gains = Gains()
    cmd = SwarmCommand(direction=(-1.0, 0.5), omega=omega, center=center)
    with np.errstate(divide="raise", invalid="raise"):
        f = model.total_forces(pos, neighbors, rest, gains, cmd)
        u, w = model.motion_commands(f, head, gains, 0.05)
        new_pos, new_head = model.unicycle_step(pos, head, u, w, 0.05)
        values = [
            metrics.alignment_order(f, head),
            metrics.heading_order(head),
            metrics.total_force(f),
        ]
    for arr in (f, u, w, new_pos, new_head, *values):
        assert np.all(np.isfinite(arr))
    assert 0.0 <= values[0] <= 1.0 + 1e-12 and 0.0 <= values[1] <= 1.0 + 1e-12
    assert np.all((-np.pi <= new_head) & (new_head < np.pi))


@settings(max_examples=200, deadline=None)
@given(
    own=st.tuples(coords, coords),
    heading=angles,
    others=arrays(float, st.tuples(st.integers(0, 5), st.just(2)), elements=coords),
    seed=st.integers(0, 2**32 - 1),
)
def test_robot_command_is_finite_even_on_top_of_its_neighbours(own, heading, others, seed) -> None:
    others = np.vstack([others, [own]])  # one neighbour exactly on top of the robot
    rest = np.full(len(others), 0.2)
    out = model.robot_command(
        np.array(own), heading, others, rest, Gains(), SwarmCommand(center=(0.0, 0.0), omega=0.3),
        dt=0.05, rng=np.random.default_rng(seed), limits=(0.13, 3.4),
    )  # fmt: skip
    assert np.isfinite(out.linear) and np.isfinite(out.angular) and np.all(np.isfinite(out.force))
    assert abs(out.linear) <= 0.13 and abs(out.angular) <= 3.4
