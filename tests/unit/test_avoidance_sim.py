"""The avoidance term in the offline simulator: the kernel and the numpy path agree, w_o = 0
changes nothing, and the packaged `cluttered` scenario's swarm crosses its posts mostly
without touching them, where without the term every run touches them."""

from __future__ import annotations

import dataclasses
from importlib import resources

import numpy as np

from aes_ros import scenario
from aes_ros.obstacles import arrays
from aes_ros.simulator import BODY, simulate

CLUTTERED = str(resources.files("aes_ros").joinpath("scenarios/cluttered.yaml"))


def body_gaps(positions: np.ndarray, headings: np.ndarray, circles: np.ndarray) -> np.ndarray:
    """Closest approach [m] of any robot body to any post, per run: (B,)."""
    facing = np.stack([np.cos(headings), np.sin(headings)], axis=-1)
    centres = positions + BODY.axle_offset * facing  # (B, T, N, 2)
    dist = np.linalg.norm(centres[..., None, :] - circles[:, :2], axis=-1) - circles[:, 2]
    return (dist - BODY.body_radius).min(axis=(1, 2, 3))


def test_kernel_and_numpy_agree_with_the_term_on() -> None:
    sc = scenario.load(CLUTTERED, {"duration": 12.0, "walls": [-1.6, 0.6, -0.6, 0.6]})
    fast = simulate(sc, seeds=[3, 4], backend="numba")
    slow = simulate(sc, seeds=[3, 4], backend="numpy")
    np.testing.assert_allclose(fast.positions, slow.positions, rtol=0, atol=1e-9)
    assert body_gaps(fast.positions, fast.headings, arrays(sc.obstacles)[0]).min() < 0.1


def test_w_o_zero_is_the_run_without_sensors() -> None:
    """w_o = 0 casts no rays: the run equals one in a world without the posts' IR effect
    (contacts off, so the posts do nothing at all and the run is the plain sheet's)."""
    sc = scenario.load(CLUTTERED, {"duration": 5.0, "contacts": False, "w_o": 0.0})
    plain = sc.with_overrides({"obstacles": ""})
    a = simulate(sc, seeds=[1], backend="numba")
    b = simulate(plain, seeds=[1], backend="numba")
    np.testing.assert_array_equal(a.positions, b.positions)


def test_the_swarm_crosses_the_posts_keeping_off_them_only_with_the_term() -> None:
    seeds = list(range(16))
    sc = scenario.load(CLUTTERED)
    circles = arrays(sc.obstacles)[0]
    post_x = circles[:, 0].min() - circles[:, 2].max()
    results = {}
    for w_o in (sc.w_o, 0.0):
        run = simulate(sc.with_overrides({"w_o": w_o}), seeds=seeds)
        touched = body_gaps(run.positions, run.headings, circles) <= 1e-3  # within 1 mm
        past = (run.final_positions[..., 0] < post_x - 0.1).mean(axis=-1)  # (B,)
        results[w_o] = touched, past
    touched, past = results[sc.w_o]
    # On: most runs never come within 1 mm of a post, and the sheet gets past them.
    assert touched.sum() <= len(seeds) // 4, touched
    assert past.mean() >= 0.95, past
    # Off: the same swarms run into the posts in every run (contacts stop them).
    touched, past = results[0.0]
    assert touched.all(), touched


def test_ir_readings_are_held_between_casts_alike_in_both_backends() -> None:
    """The rays are cast every round(1/(ir_rate·Δt)) steps and held in between, as a robot
    holds its last reading: the kernel and the numpy path agree at any rate, and the rate
    changes the run."""
    sc = scenario.load(CLUTTERED, {"duration": 6.0})
    every_step = sc.with_overrides({"ir_rate": 1.0 / sc.dt})
    slow = sc.with_overrides({"ir_rate": 0.2 / sc.dt})  # every fifth step
    runs = {}
    for name, s in (("every step", every_step), ("every fifth", slow)):
        fast = simulate(s, seeds=[2], backend="numba")
        plain = simulate(s, seeds=[2], backend="numpy")
        np.testing.assert_allclose(fast.positions, plain.positions, rtol=0, atol=1e-9)
        runs[name] = fast.positions
    assert np.abs(runs["every step"] - runs["every fifth"]).max() > 1e-3


def test_a_run_that_diverges_with_the_term_on_goes_on_as_nan_alone() -> None:
    """Gains at the top of their ranges make the combined sheet blow up; with the IR term
    on, that run must end as NaN, as it does without the term, in both backends, and the
    stable run beside it in the batch must be the run it is alone (not a crash of the whole
    batch, as when the rays refused non-finite poses)."""
    sc = scenario.load("combined", {"duration": 15.0, "w_o": 4.0})
    wild = dataclasses.replace(sc.gains, alpha=10.0, beta=10.0, k=10.0)
    runs = {
        backend: simulate(sc, seeds=[5, 6], gains=[sc.gains, wild], backend=backend)
        for backend in ("numba", "numpy")
    }
    fast, slow = runs["numba"], runs["numpy"]
    assert not np.isfinite(fast.final_positions[1]).all()
    assert not np.isfinite(slow.final_positions[1]).all()
    np.testing.assert_allclose(fast.positions[0], slow.positions[0], rtol=0, atol=1e-9)
    alone = simulate(sc, seeds=[5], backend="numba")
    np.testing.assert_array_equal(fast.positions[0], alone.positions[0])
    assert np.isfinite(fast.positions[0]).all()
