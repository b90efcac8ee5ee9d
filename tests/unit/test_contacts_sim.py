"""Contacts in the offline simulator: contacts=false gives the outputs of before, both
backends agree with contacts on, and bodies never overlap deeper than 1 mm."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from aes_ros import scenario, simulator
from aes_ros.contact_measures import contacts_over_time
from aes_ros.metrics_csv import OLD_COLUMNS, metrics_table, read_metrics_csv
from aes_ros.obstacles import contact_arrays

DATA = Path(__file__).parents[1] / "data"
R, A = simulator.BODY.body_radius, simulator.BODY.axle_offset
MM = 1e-3


def _reference():
    spec = importlib.util.spec_from_file_location(
        "make_contacts_off_reference", DATA / "make_contacts_off_reference.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


REFERENCE = _reference()


@pytest.mark.parametrize("case", list(REFERENCE.CASES))
def test_contacts_off_is_bit_identical_to_before(case: str) -> None:
    stored = np.load(REFERENCE.PATH)
    for field, value in REFERENCE.compute(case).items():
        assert value.tobytes() == stored[f"{case}/{field}"].tobytes(), (case, field)


def crowded(**overrides: object) -> scenario.Scenario:
    """A sheet packed tighter than its bodies (spacing 7 cm < 8 cm) in walls, with a
    circle and a box at its edge."""
    return scenario.load(
        "combined",
        {
            "rows": 4,
            "cols": 5,
            "spacing": 0.07,
            "duration": 2.0,
            "walls": "-0.3,0.3,-0.25,0.25",
            "obstacles": "circle:-0.24,0.0,0.03;box:0.1,0.3,-0.25,-0.2",
            "contacts": True,
            **overrides,
        },
    )


@pytest.mark.parametrize("perceived", [{}, REFERENCE.PERCEIVED])
def test_both_backends_resolve_contacts_alike(perceived: dict) -> None:
    sc = crowded(**perceived)
    fast = simulator.simulate(sc, [0, 1], backend="numba")
    slow = simulator.simulate(sc, [0, 1], backend="numpy")
    np.testing.assert_allclose(fast.positions, slow.positions, atol=1e-9)
    np.testing.assert_allclose(fast.metrics, slow.metrics, atol=1e-7)
    np.testing.assert_array_equal(fast.contacts, slow.contacts)
    np.testing.assert_allclose(fast.min_distance, slow.min_distance, atol=1e-9)
    assert fast.contacts[:, 1:].sum() > 0  # the case does collide


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_with_contacts_bodies_stay_apart_and_inside(backend: str) -> None:
    sc = crowded()
    result = simulator.simulate(sc, [0], backend=backend)
    _, closest = contacts_over_time(result.positions[:, 1:], result.headings[:, 1:], R, A)
    assert closest.min() >= 2 * R - MM
    np.testing.assert_allclose(result.min_distance[:, 1:], closest, rtol=1e-12)
    c = result.positions + A * np.stack([np.cos(result.headings), np.sin(result.headings)], -1)
    assert (np.abs(c[:, 1:, :, 0]) <= 0.3 - R + 1e-9).all()  # inside the walls
    assert (np.abs(c[:, 1:, :, 1]) <= 0.25 - R + 1e-9).all()
    assert (np.hypot(c[:, 1:, :, 0] + 0.24, c[:, 1:, :, 1]) >= 0.03 + R - 1e-9).all()
    to_box = np.hypot(
        c[:, 1:, :, 0] - np.clip(c[:, 1:, :, 0], 0.1, 0.3),
        c[:, 1:, :, 1] - np.clip(c[:, 1:, :, 1], -0.25, -0.2),
    )
    assert (to_box >= R - 1e-9).all()


def test_without_contacts_bodies_overlap() -> None:
    result = simulator.simulate(crowded(contacts=False), [0])
    assert result.min_distance.min() < 2 * R - MM
    assert result.contacts.sum() > 0


def test_the_geometry_reaches_the_kernel() -> None:
    walls, circles, boxes = contact_arrays(crowded().values)
    assert walls.tolist() == [-0.3, 0.3, -0.25, 0.25]
    assert circles.tolist() == [[-0.24, 0.0, 0.03]]
    assert circles.shape == (1, 3) and boxes.shape == (1, 4)


def test_hundred_robots_at_50_hz_never_overlap_deeper_than_a_millimetre() -> None:
    """The combined setup, 100 robots, Δt = 0.02 s, 30 s: with contacts the bodies never
    overlap by more than 1 mm (measured afresh in every recorded state and in the
    metrics.csv columns); without, robots cross each other, so the test can fail."""
    sc = scenario.load("combined", {"dt": 0.02, "duration": 30.0})
    on = simulator.simulate(sc.with_overrides({"contacts": True}), [0])
    off = simulator.simulate(sc.with_overrides({"contacts": False}), [0])
    for result in (on, off):
        assert result.positions.shape == (1, 1501, 100, 2)
    _, closest = contacts_over_time(on.positions, on.headings, R, A)
    assert closest.min() >= 2 * R - MM
    np.testing.assert_allclose(on.min_distance[:, 1:], closest[:, 1:], rtol=1e-12)
    table = metrics_table(on.times, on.positions, on.headings, sc)
    assert table["min_centre_distance"].min() >= 2 * R - MM
    assert on.contacts_per_s[0] > 0  # they do touch
    assert np.mean(table["contacts_per_s"]) == pytest.approx(on.contacts_per_s[0], rel=0.2)
    _, crossing = contacts_over_time(off.positions, off.headings, R, A)
    assert crossing.min() < 2 * R - 10 * MM
    assert off.contacts_per_s[0] > 0


def test_metrics_csv_of_before_the_contact_columns_still_reads(tmp_path: Path) -> None:
    path = tmp_path / "metrics.csv"
    path.write_text(",".join(OLD_COLUMNS) + "\n0,1,1,2,0,0,0.1\n0.05,0.9,1,2,0.01,0,0.1\n")
    digest = read_metrics_csv(path)
    assert digest.n_rows == 2 and digest.last["centroid_x"] == 0.01
    assert np.isnan(digest.rows["min_centre_distance"]).all()
    assert np.isnan(digest.last["contacts_per_s"])
