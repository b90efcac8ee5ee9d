"""Perception error (issue #25): robots act on a tracker's noisy, late, held frame;
off by default, and then every run is what it was before perception existed."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numba
import numpy as np
import pytest

from aes_ros import model, scenario, simulator
from aes_ros.params import ParameterError
from aes_ros.perception import (
    PerceptionSettings,
    PerceptionStream,
    camera_period_steps,
    delay_steps,
    draw_camera,
    perceived_frame,
    perception_state,
)
from aes_ros.springs import spring_list

DATA = Path(__file__).parents[1] / "data"
#: every perception parameter on (τ = 3 steps, a camera update every 2 steps at Δt 0.05 s)
CAMERA = {
    "perception_sigma": 0.01,
    "perception_delay": 0.15,
    "perception_rate": 10.0,
    "perception_miss": 0.1,
}


def _reference_module():
    spec = importlib.util.spec_from_file_location(
        "make_perception_off_reference", DATA / "make_perception_off_reference.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


REFERENCE = _reference_module()


@pytest.fixture(scope="module")
def reference() -> dict[str, np.ndarray]:
    with np.load(REFERENCE.PATH) as data:
        return dict(data)


@pytest.mark.parametrize("case", list(REFERENCE.CASES))
def test_perception_off_gives_bit_for_bit_what_the_simulator_gave_before(
    case: str, reference: dict[str, np.ndarray]
) -> None:
    for field, value in REFERENCE.compute(case).items():
        assert np.array_equal(value, reference[f"{case}/{field}"]), f"{case}: {field} changed"


def test_settings_that_cannot_change_the_frame_count_as_off(
    reference: dict[str, np.ndarray],
) -> None:
    """A 20 Hz camera at Δt = 0.05 s updates every step, and τ < Δt/2 rounds to no
    delay: with σ_p = 0 and no misses the robots see the truth, as before."""
    setup, overrides, backend = REFERENCE.CASES["combined"]
    sc = scenario.load(
        setup, {**REFERENCE.SMALL, **overrides, "perception_rate": 20, "perception_delay": 0.02}
    )
    assert not PerceptionSettings.from_mapping(sc.values).enabled(sc.dt)
    result = simulator.simulate(sc, list(REFERENCE.SEEDS), backend=backend)
    assert np.array_equal(result.positions, reference["combined/positions"])


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_position_noise_changes_what_robots_see_never_where_they_are(backend: str) -> None:
    """With α = β = 0 a robot drives at v_0 and turns with its actuation noise only,
    whatever it sees: noisy perception must leave the true motion bit for bit, and
    must not take a single draw from the run's own generator."""
    blind = {"alpha": 0.0, "beta": 0.0, "k": 0.0, "rows": 3, "cols": 4, "duration": 3.0}
    sc = scenario.load("combined", blind)
    exact = simulator.simulate(sc, [3, 4], backend=backend)
    noisy = simulator.simulate(
        sc.with_overrides({"perception_sigma": 0.02}), [3, 4], backend=backend
    )
    np.testing.assert_array_equal(noisy.positions, exact.positions)
    np.testing.assert_array_equal(noisy.headings, exact.headings)
    # with the paper's gains the same noise does change the motion
    steered = scenario.load("combined", {"rows": 3, "cols": 4, "duration": 3.0})
    a = simulator.simulate(steered, [3, 4])
    b = simulator.simulate(steered.with_overrides({"perception_sigma": 0.02}), [3, 4])
    assert np.abs(a.positions[:, -1] - b.positions[:, -1]).max() > 1e-3


def test_perceived_positions_carry_gaussian_noise_of_std_sigma_and_exact_headings() -> None:
    sigma, n_robots, n_frames = 0.003, 50, 400
    settings = PerceptionSettings(sigma=sigma)
    noise, _ = draw_camera(perception_state(0), settings, n_frames, n_robots)
    rng = np.random.default_rng(1)
    true_pos = rng.uniform(-1, 1, (n_frames, n_robots, 2))
    true_head = rng.uniform(-np.pi, np.pi, (n_frames, n_robots))
    held = (np.zeros_like(true_pos), np.zeros_like(true_head))
    missed = np.zeros((n_frames, n_robots), dtype=bool)
    pos, head = perceived_frame(true_pos, true_head, *held, noise, missed, sigma)
    error = (pos - true_pos).reshape(-1, 2)
    assert np.abs(error.mean(axis=0)).max() < 4 * sigma / np.sqrt(len(error))
    np.testing.assert_allclose(error.std(axis=0), sigma, rtol=0.03)
    assert abs(np.corrcoef(error.T)[0, 1]) < 0.03  # the axes are independent
    assert np.mean(np.abs(error) > 3 * sigma) == pytest.approx(0.0027, abs=0.001)  # tails
    np.testing.assert_array_equal(head, true_head)


def _steps_seen(settings: PerceptionSettings, n_steps: int, n_robots: int = 3) -> np.ndarray:
    """Feed a stream the state 'robot at x = step' and return the x it shows at each
    step (n_steps, n_robots): which step's state the robots see."""
    stream = PerceptionStream(settings, n_robots, 0.05, seed=0)
    seen = []
    for step in range(n_steps):
        positions = np.zeros((n_robots, 2))
        positions[:, 0] = step
        pos, head = stream.see(positions, np.full(n_robots, 0.001 * step), step)
        np.testing.assert_array_equal(head, 0.001 * pos[:, 0])  # pose from one instant
        seen.append(pos[:, 0])
    return np.array(seen)


def test_a_jump_appears_exactly_the_delay_later() -> None:
    stream = PerceptionStream(PerceptionSettings(delay=0.25), 2, 0.05, seed=0)
    assert stream.delay == 5
    shown = []
    for step in range(20):
        x = 0.0 if step < 10 else 1.0  # the robots jump at step 10
        pos, _ = stream.see(np.full((2, 2), x), np.zeros(2), step)
        shown.append(pos[0, 0])
    assert np.flatnonzero(np.array(shown) == 1.0)[0] == 15


def test_delay_shows_the_initial_state_first_and_the_rate_holds_frames() -> None:
    # τ = 0.15 s → D = 3; a 4 Hz camera at Δt = 0.05 s → an update every m = 5 steps
    seen = _steps_seen(PerceptionSettings(delay=0.15, rate=4.0), 23)
    steps = np.arange(23)
    update = steps // 5 * 5  # the last camera update at or before each step
    expected = np.maximum(update - 3, 0)
    np.testing.assert_array_equal(seen, np.repeat(expected[:, None], 3, axis=1))


def test_delay_and_rate_convert_to_whole_steps() -> None:
    assert [delay_steps(t, 0.05) for t in (0.0, 0.02, 0.05, 0.12, 2.0)] == [0, 0, 1, 2, 40]
    assert [camera_period_steps(f, 0.05) for f in (0.0, 20.0, 1000.0, 5.0, 3.0, 0.5)] == [
        1, 1, 1, 4, 7, 40,
    ]  # fmt: skip


def test_missed_robots_keep_their_last_pose_at_the_miss_rate() -> None:
    n_steps, n_robots, miss = 400, 50, 0.3
    seen = _steps_seen(PerceptionSettings(miss=miss), n_steps, n_robots)
    np.testing.assert_array_equal(seen[0], 0)  # the first frame shows every robot
    fresh = seen[1:] == np.arange(1, n_steps)[:, None]
    held = seen[1:] == seen[:-1]
    assert np.all(fresh | held)  # a robot shows its new pose or keeps the last one
    rate = 1.0 - fresh.mean()
    assert rate == pytest.approx(miss, abs=4 * np.sqrt(miss * (1 - miss) / fresh.size))
    # misses are independent: robots missed twice in a row as often as chance says
    twice = (~fresh[1:] & ~fresh[:-1]).mean()
    assert twice == pytest.approx(miss**2, abs=0.02)


def test_a_stream_sees_what_the_simulators_robots_see() -> None:
    """Fed a run's true states, :class:`PerceptionStream` for run ``seed`` gives the
    frames the simulator's robots acted on: their commands from that frame lead to
    the run's next true state."""
    # contacts off: the next state here is the Euler step alone (no bodies to resolve)
    sc = scenario.load(
        "combined", {"rows": 3, "cols": 4, "duration": 2.0, "contacts": False, **CAMERA}
    )
    seed = 7
    run = simulator.simulate(sc, [seed], noise=False)
    stream = PerceptionStream(PerceptionSettings.from_mapping(sc.values), 12, sc.dt, seed)
    for step in range(sc.n_steps):
        pos, head = run.positions[0, step], run.headings[0, step]
        seen_pos, seen_head = stream.see(pos, head, step)
        force = model.total_forces(seen_pos, run.neighbors, run.rest_lengths, sc.gains, sc.command)
        u, w = model.motion_commands(force, seen_head, sc.gains, sc.dt)
        next_pos, next_head = model.unicycle_step(pos, head, u, w, sc.dt)
        np.testing.assert_allclose(next_pos, run.positions[0, step + 1], atol=1e-12)
        np.testing.assert_allclose(next_head, run.headings[0, step + 1], atol=1e-12)


def test_noise_and_misses_are_separate_streams_drawn_alike_one_or_many_updates_at_a_time() -> None:
    """The draws of run ``seed``: switching misses on leaves the noise as it was (and
    the other way round), and :class:`PerceptionStream`, drawing an update at a time,
    shows the frames made of :func:`draw_camera`'s draws of all updates at once (the
    kernel calls the same draw function at each update)."""
    n_updates, n_robots, seed = 30, 5, 7
    both = PerceptionSettings(sigma=1.0, miss=0.3)
    noise, uniforms = draw_camera(perception_state(seed), both, n_updates, n_robots)
    alone = draw_camera(perception_state(seed), PerceptionSettings(sigma=1.0), n_updates, n_robots)
    np.testing.assert_array_equal(alone[0], noise)
    assert not alone[1].any()
    alone = draw_camera(perception_state(seed), PerceptionSettings(miss=0.3), n_updates, n_robots)
    np.testing.assert_array_equal(alone[1], uniforms)
    assert not alone[0].any()

    stream = PerceptionStream(both, n_robots, 0.05, seed)
    expected = np.zeros((n_robots, 2))
    for step in range(n_updates):
        pos, _ = stream.see(np.zeros((n_robots, 2)), np.zeros(n_robots), step)
        seen = (uniforms[step] >= both.miss) | (step == 0)
        expected[seen] = noise[step][seen]  # the truth is 0 and σ_p = 1: the frame is z
        np.testing.assert_array_equal(pos, expected)
    assert 0 < (uniforms[1:] < both.miss).sum() < uniforms[1:].size


def test_a_stream_wants_its_steps_in_order() -> None:
    stream = PerceptionStream(PerceptionSettings(delay=0.1), 2, 0.05, seed=0)
    stream.see(np.zeros((2, 2)), np.zeros(2), 0)
    with pytest.raises(ValueError, match="expected 1"):
        stream.see(np.zeros((2, 2)), np.zeros(2), 3)


@pytest.mark.parametrize("setup", scenario.SETUPS)
@pytest.mark.parametrize(
    "extra",
    [{}, {"clip": True, "rotation_center": "0.2,-0.1", "perception_rate": 0.0}],
    ids=["centroid", "fixed-centre-clip"],
)
def test_fused_kernel_equals_numpy_reference_with_perception(setup: str, extra: dict) -> None:
    sc = scenario.load(setup, {"duration": 4.0, "rows": 5, "cols": 7, **CAMERA, **extra})
    stop_at = simulator.failure_steps(2, 35, fraction=0.1, at=2.0, dt=sc.dt, seed=0)
    fast = simulator.simulate(sc, [1, 2], backend="numba", stop_at=stop_at)
    ref = simulator.simulate(sc, [1, 2], backend="numpy", stop_at=stop_at)
    np.testing.assert_allclose(fast.positions, ref.positions, atol=1e-9)
    np.testing.assert_allclose(fast.headings, ref.headings, atol=1e-9)
    np.testing.assert_allclose(fast.metrics, ref.metrics, atol=1e-9)


def test_with_perception_a_batch_is_the_same_on_any_number_of_threads() -> None:
    """(A batch equals its single runs, with perception too:
    tests/unit/test_simulator.py::test_a_batch_equals_its_single_runs.)"""
    sc = scenario.load("combined", {"duration": 3.0, "rows": 4, "cols": 5, **CAMERA})
    seeds = [11, 12, 13]
    batch = simulator.simulate(sc, seeds)
    again = simulator.simulate(sc, seeds)
    np.testing.assert_array_equal(again.positions, batch.positions)
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        one_thread = simulator.simulate(sc, seeds)
    finally:
        numba.set_num_threads(threads)
    np.testing.assert_array_equal(one_thread.positions, batch.positions)


@pytest.mark.parametrize(
    ("name", "value", "allowed"),
    [
        ("perception_sigma", "0.5", "[0, 0.1]"),
        ("perception_sigma", "-0.001", "[0, 0.1]"),
        ("perception_delay", "3", "[0, 2]"),
        ("perception_rate", "-1", "[0, 1000]"),
        ("perception_miss", "1.5", "[0, 0.99]"),
        ("perception_miss", "1", "[0, 0.99]"),
    ],
)
def test_out_of_range_values_are_rejected_naming_parameter_and_range(
    name: str, value: str, allowed: str
) -> None:
    with pytest.raises(ParameterError) as err:
        scenario.load("linear", scenario.parse_assignments([f"{name}={value}"]))
    assert name in str(err.value) and allowed in str(err.value)


def test_set_accepts_perception_like_any_parameter() -> None:
    overrides = scenario.parse_assignments(["perception_sigma=0.003", "perception_miss=0.01"])
    sc = scenario.load("linear", overrides)
    assert PerceptionSettings.from_mapping(sc.values) == PerceptionSettings(sigma=0.003, miss=0.01)
    assert PerceptionSettings.from_mapping(scenario.load("linear").values) == PerceptionSettings()


def test_the_kernel_lists_each_mutual_spring_once_and_keeps_one_way_links() -> None:
    neighbors = np.array([[1, 2], [0, -1], [-1, -1]])  # 0-1 mutual, 0 -> 2 one way
    rest = np.array([[0.2, 0.3], [0.2, 0.0], [0.0, 0.0]])
    ends, spring_rest, mutual = spring_list(neighbors, rest)
    assert ends.tolist() == [[0, 1], [0, 2]]
    assert spring_rest.tolist() == [0.2, 0.3]
    assert mutual.tolist() == [True, False]
