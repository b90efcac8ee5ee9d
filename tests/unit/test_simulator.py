"""The offline simulator: the paper's three setups behave as the paper says,
the fused kernel equals the numpy reference, seeds and batching are exact."""

from __future__ import annotations

import numpy as np
import pytest

from aes_ros import metrics, scenario, simulator

V_EXPECTED = 0.05 + 0.066 * 0.8  # v0 + α·w_l [m/s]


def second_half(result: simulator.SimResult) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centroid velocity (B, 2) and rotation rate (B,) over the second half of the run
    (after the initial alignment transient), and the mean heading order there."""
    h = len(result.times) // 2
    span = result.times[-1] - result.times[h]
    velocity = (result.centroid[:, -1] - result.centroid[:, h]) / span
    omega = metrics.rotation_angle(result.positions[:, h], result.positions[:, -1]) / span
    return velocity, omega, result.metric("heading_order")[:, h:].mean(axis=1)


@pytest.fixture(scope="module")
def linear() -> simulator.SimResult:
    return simulator.simulate(scenario.load("linear"), [0, 1, 2, 3])


def test_linear_moves_west_at_the_drive_speed_and_aligns(linear: simulator.SimResult) -> None:
    velocity, omega, order = second_half(linear)
    direction = np.degrees(np.arctan2(velocity[:, 1], velocity[:, 0]))
    assert np.all(np.abs(np.abs(direction) - 180.0) < 10.0), direction  # west
    speed = np.linalg.norm(velocity, axis=1)
    np.testing.assert_allclose(speed, V_EXPECTED, rtol=0.15)
    assert np.all(linear.metric("heading_order")[:, -1] > 0.9)
    assert np.all(order > 0.9)
    assert np.all(np.abs(omega) < 0.01)


@pytest.mark.parametrize("omega", [0.7, -0.7])
def test_rotation_turns_with_the_sign_of_omega_about_a_fixed_centroid(omega: float) -> None:
    result = simulator.simulate(scenario.load("rotation", {"omega": omega}), [0, 1, 2])
    _, turn, _ = second_half(result)
    assert np.all(np.sign(turn) == np.sign(omega)), turn  # ω > 0: counter-clockwise
    assert np.all(np.abs(turn) > 0.03)
    drift = np.linalg.norm(result.centroid[:, -1] - result.centroid[:, 0], axis=1)
    assert np.all(drift < 0.1), drift


def test_combined_moves_west_and_turns_clockwise_with_the_papers_omega() -> None:
    sc = scenario.load("combined")
    assert sc.omega == -0.7  # the paper's ω = 0.7 clockwise
    result = simulator.simulate(sc, [0, 1, 2])
    velocity, turn, _ = second_half(result)
    direction = np.degrees(np.arctan2(velocity[:, 1], velocity[:, 0]))
    assert np.all(np.abs(np.abs(direction) - 180.0) < 10.0), direction
    assert np.all(np.linalg.norm(velocity, axis=1) > 0.5 * V_EXPECTED)
    assert np.all(turn < -0.03), turn


def test_results_do_not_depend_on_the_time_step() -> None:
    """Δt in [0.01, 0.1] s gives the same motion within noise (docs/design.md#scenarios)."""
    stats = {}
    for dt in (0.01, 0.05, 0.1):
        result = simulator.simulate(scenario.load("linear", {"dt": dt}), list(range(6)))
        velocity, _, order = second_half(result)
        stats[dt] = (np.linalg.norm(velocity, axis=1).mean(), order.mean())
    speeds = np.array([s for s, _ in stats.values()])
    orders = np.array([o for _, o in stats.values()])
    assert np.ptp(speeds) < 0.05 * speeds.mean(), stats
    assert np.ptp(orders) < 0.03, stats


@pytest.mark.parametrize(
    "perception",
    [{}, {"perception_sigma": 0.01, "perception_delay": 0.15, "perception_rate": 10.0,
          "perception_miss": 0.1}],
    ids=["exact", "perceived"],
)  # fmt: skip
def test_a_batch_equals_its_single_runs(perception) -> None:
    sc = scenario.load("combined", {"duration": 5.0, "rows": 4, "cols": 5, **perception})
    seeds = [11, 12, 13]
    batch = simulator.simulate(sc, seeds)
    for b, seed in enumerate(seeds):
        single = simulator.simulate(sc, [seed])
        np.testing.assert_array_equal(batch.positions[b], single.positions[0])
        np.testing.assert_array_equal(batch.metrics[b], single.metrics[0])


def test_the_same_seed_reproduces_a_run_and_another_differs() -> None:
    sc = scenario.load("linear", {"duration": 3.0})
    a, b, c = (simulator.simulate(sc, [s]) for s in (5, 5, 6))
    np.testing.assert_array_equal(a.positions, b.positions)
    assert not np.allclose(a.positions[0, -1], c.positions[0, -1])


@pytest.mark.parametrize("setup", scenario.SETUPS)
@pytest.mark.parametrize("clip", [False, True])
def test_fused_kernel_equals_numpy_reference(setup: str, clip: bool) -> None:
    sc = scenario.load(setup, {"duration": 4.0, "clip": clip, "rows": 5, "cols": 7})
    fast = simulator.simulate(sc, [1, 2], backend="numba")
    ref = simulator.simulate(sc, [1, 2], backend="numpy")
    np.testing.assert_allclose(fast.positions, ref.positions, atol=1e-9)
    np.testing.assert_allclose(fast.metrics, ref.metrics, atol=1e-9)


def test_per_run_gains_match_separate_runs() -> None:
    sc = scenario.load("linear", {"duration": 3.0, "rows": 3, "cols": 3})
    other = sc.with_overrides({"alpha": 0.2, "k": 2.0})
    mixed = simulator.simulate(sc, [4, 4], gains=[sc.gains, other.gains])
    np.testing.assert_array_equal(mixed.positions[0], simulator.simulate(sc, [4]).positions[0])
    np.testing.assert_array_equal(mixed.positions[1], simulator.simulate(other, [4]).positions[0])


def test_clipping_keeps_speeds_within_the_robots_limits() -> None:
    sc = scenario.load("combined", {"duration": 5.0, "clip": True, "alpha": 2.0})
    result = simulator.simulate(sc, [0])
    step = np.linalg.norm(np.diff(result.positions[0], axis=0), axis=-1)
    assert step.max() <= sc.max_linear_speed * sc.dt + 1e-12


def test_noise_off_start_is_the_seeded_initial_state() -> None:
    sc = scenario.load("linear", {"rows": 3, "cols": 3, "duration": 1.0})
    pos, head = sc.initial_state(9)
    result = simulator.simulate(sc, [9], noise=False)
    np.testing.assert_array_equal(result.positions[0, 0], pos)
    np.testing.assert_array_equal(result.headings[0, 0], head)


def test_failed_robots_stop_where_they_are_and_pull_their_neighbours() -> None:
    # contacts off: a stopped robot would still be pushed by bodies; this is about its own drive
    sc = scenario.load("linear", {"contacts": False}).with_robots(25)
    sc = sc.with_overrides({"duration": 6.0})
    stop_at = simulator.failure_steps(2, 25, fraction=0.2, at=3.0, dt=sc.dt, seed=1)
    failed = np.flatnonzero(stop_at[0] < 10**9)
    assert len(failed) == 5
    res = simulator.simulate(sc, [1, 2], stop_at=stop_at)
    k = round(3.0 / sc.dt)
    moved = np.linalg.norm(res.positions[:, -1] - res.positions[:, k], axis=-1)
    assert np.all(moved[:, failed] == 0.0)  # not one step after the failure
    assert np.all(np.delete(moved, failed, axis=1) > 0.01)
    intact = simulator.simulate(sc, [1, 2])
    np.testing.assert_array_equal(res.positions[:, : k + 1], intact.positions[:, : k + 1])
    # the failed robots hold the sheet back: the swarm gets less far west than intact
    assert np.all(res.centroid[:, -1, 0] > intact.centroid[:, -1, 0])
    ref = simulator.simulate(sc, [1, 2], stop_at=stop_at, backend="numpy")
    np.testing.assert_allclose(res.positions, ref.positions, atol=1e-9)
