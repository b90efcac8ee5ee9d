"""The studies on sweeps (aes_ros.studies): their analysis functions, and one study end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest

from aes_ros.studies import pareto
from aes_ros.studies.common import Where, study_gain_sets
from aes_ros.studies.noise import breakdown


def test_pareto_front_keeps_exactly_the_points_nobody_beats() -> None:
    force = np.array([1.0, 2.0, 1.5, 0.5, 3.0, 1.0])
    psi = np.array([0.8, 0.9, 0.7, 0.6, 0.95, 0.85])
    front = pareto.pareto_front(force, psi)
    assert front.tolist() == [False, True, False, True, True, True]
    for i in np.flatnonzero(front):  # no point is at least as good in both and better in one
        beats = (force <= force[i]) & (psi >= psi[i]) & ((force < force[i]) | (psi > psi[i]))
        assert not beats.any()


def test_the_weight_ratio_moves_the_optimum_along_the_front() -> None:
    force = np.array([0.5, 1.0, 2.0])
    psi = np.array([0.5, 0.8, 0.9])
    picks = pareto.optimum_along_weights(force, psi, np.array([0.01, 0.5, 100.0]))
    assert picks.tolist() == [2, 1, 0]  # alignment first … force first


def test_breakdown_noise_interpolates_where_order_crosses_one_half() -> None:
    noise = np.array([0.1, 1.0, 10.0])
    assert breakdown(noise, np.array([0.9, 0.7, 0.3])) == pytest.approx(10**0.5)
    assert np.isnan(breakdown(noise, np.array([0.9, 0.8, 0.7])))
    assert breakdown(noise, np.array([0.4, 0.3, 0.2])) == 0.0


def test_the_tuning_studys_gain_sets_are_read() -> None:
    labels = [g.label for g in study_gain_sets()]
    assert labels[0].startswith("untuned") and labels[1].startswith("paper")
    assert any(label.startswith("TCACS, weights (1/N, −1)") for label in labels)


def test_pareto_study_end_to_end(tmp_path) -> None:
    result = pareto.run(tmp_path / "out", Where(tmp_path / "work", progress=False), quick=True)
    saved = json.loads((tmp_path / "out" / "pareto.json").read_text())
    assert saved == json.loads(json.dumps(result))
    assert result["front_points"] >= 2 and result["samples"] == 60
    paper = next(r for r in result["gain_sets"] if r["gains"].startswith("paper"))
    assert paper["k"] == 1.28 and np.isfinite(paper["psi"])
    for name in ("pareto.png", "pareto_points.csv", "gain_sets.csv", "k_along_weights.csv"):
        assert (tmp_path / "out" / name).stat().st_size > 0
