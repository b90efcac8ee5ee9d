"""Property-based tests of the core functions: finite in, finite out, no division by zero."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from aes_ros import metrics, model, scenario, simulator
from aes_ros.model import MIN_NOISE_DT, Gains, SwarmCommand

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


# A robot node's Δt is the gap between two pose stamps: 1 ns apart, or minutes.
stamp_gaps = st.floats(1e-9, 1e3) | st.sampled_from([0.0, -0.05, float("nan"), float("inf")])


@settings(max_examples=300, deadline=None)
@given(
    dt=stamp_gaps,
    heading=angles,
    others=arrays(float, st.tuples(st.integers(0, 5), st.just(2)), elements=coords),
    seed=st.integers(0, 2**32 - 1),
)
def test_no_time_step_makes_the_noise_larger_than_at_the_minimum(dt, heading, others, seed) -> None:
    """Any Δt: finite commands, noise at most D/√MIN_NOISE_DT, clipped ones within limits."""
    gains = Gains(d_r=10.0, d_theta=10.0)  # the largest noise the parameters allow
    command = SwarmCommand(center=(0.0, 0.0), omega=0.3)
    args = (np.zeros(2), heading, others, np.full(len(others), 0.2), gains, command)
    quiet = model.robot_command(*args, dt=dt)
    noisy = model.robot_command(*args, dt=dt, rng=np.random.default_rng(seed))
    clipped = model.robot_command(*args, dt=dt, rng=np.random.default_rng(seed), limits=(0.13, 3.4))
    for out in (noisy, clipped):
        assert np.isfinite(out.linear) and np.isfinite(out.angular)
    assert abs(clipped.linear) <= 0.13 and abs(clipped.angular) <= 3.4
    _, _, xi_theta = model.draw_noise(np.random.default_rng(seed))
    amp = 1.0 / np.sqrt(MIN_NOISE_DT)  # |ξ̂_r| = 1
    slack = 1e-9 * (1.0 + abs(quiet.linear) + abs(quiet.angular))
    assert abs(noisy.linear - quiet.linear) <= gains.alpha * gains.d_r * amp + slack
    turn_bound = (gains.beta * gains.d_r + gains.d_theta * abs(float(xi_theta))) * amp
    assert abs(noisy.angular - quiet.angular) <= turn_bound + slack


def test_a_normal_time_step_is_not_changed_and_a_tiny_one_counts_as_the_minimum() -> None:
    assert model.noise_dt(0.05) == 0.05 and model.noise_dt(MIN_NOISE_DT) == MIN_NOISE_DT
    assert model.noise_dt(1e-9) == MIN_NOISE_DT and model.noise_dt(float("nan")) == MIN_NOISE_DT
    np.testing.assert_array_equal(model.noise_dt(np.array([1e-9, 0.05])), [MIN_NOISE_DT, 0.05])


def test_fused_kernel_floors_the_noise_time_step_like_numpy() -> None:
    """Δt below MIN_NOISE_DT: the kernel and the numpy path still give the same run."""
    sc = scenario.load("linear", {"dt": 1e-4, "duration": 0.05, "rows": 3, "cols": 4})
    fast = simulator.simulate(sc, [1], backend="numba")
    ref = simulator.simulate(sc, [1], backend="numpy")
    np.testing.assert_allclose(fast.positions, ref.positions, atol=1e-9)
