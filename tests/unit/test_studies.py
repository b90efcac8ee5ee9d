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


def test_tolerance_is_where_psi_crosses_the_level_with_its_confidence_band() -> None:
    from aes_ros.studies.perception import crossing, tolerance

    x = np.array([0.0, 10.0, 20.0, 30.0])
    psi = np.array([0.9, 0.85, 0.75, 0.6])
    assert crossing(x, psi) == pytest.approx(15.0)  # halfway between 0.85 and 0.75
    assert np.isnan(crossing(x, np.array([0.9, 0.9, 0.85, 0.82])))
    assert crossing(x, np.array([0.7, 0.6, 0.5, 0.4])) == 0.0
    # a band of ±0.05 (std 0.05·√runs/1.96): the lower edge crosses first
    runs = 16
    std = np.full(4, 0.05 * np.sqrt(runs) / 1.96)
    t, low, high = tolerance(x, psi, std, runs)
    assert t == pytest.approx(15.0)
    assert low == pytest.approx(10.0) and high == pytest.approx(20.0)


def test_the_requirement_takes_the_tightest_tolerance_and_says_what_never_broke() -> None:
    from aes_ros.studies.perception import AXES, requirement

    rows = []
    for axis in AXES:
        for n, value in ((25, 4.0), (100, 2.0)):
            tol = value if axis.name != "perception_miss" else float("nan")
            rows.append({"axis": axis.name, "robots": n, "unit": axis.unit,
                         "tolerance": tol, "swept_to": 30.0})  # fmt: skip
    need = requirement(rows, AXES)
    assert need["perception_sigma"] == 2.0 and need["perception_delay"] == 2.0
    assert need["perception_rate"] == 4.0  # lower rates are worse: the larger limit binds
    assert need["perception_miss"] is None
    assert "missed detections beyond 30 %" in need["sentence"]


def test_ladder_figures_of_a_run_westward_at_known_speed() -> None:
    from aes_ros.studies.ladder import TRANSIENT, run_metrics

    t = np.arange(0.0, 30.05, 0.05)
    centroid = np.stack([-0.04 * t, 0.04 * t * np.tan(np.radians(10))], axis=-1)
    psi, order, force = np.full_like(t, 0.9), np.full_like(t, 0.8), np.full_like(t, 50.0)
    psi[t < TRANSIENT] = 0.2  # the transient is left out of the means, not out of J
    r = run_metrics(t, psi, order, force, centroid, 25, 600, (-1.0, 0.0))
    assert r["psi"] == pytest.approx(0.9) and r["psi_heading"] == pytest.approx(0.8)
    assert r["force_per_robot"] == pytest.approx(2.0)
    assert r["speed"] == pytest.approx(0.04 / np.cos(np.radians(10)))
    assert r["heading_error_deg"] == pytest.approx(10.0)
    assert r["J"] == pytest.approx(601 * np.mean(force / 25 - psi))
    # a sampled-twice-as-often run has the same J: per-sample mean × the setup's steps
    r2 = run_metrics(t[::2], psi[::2], order[::2], force[::2], centroid[::2], 25, 600, None)
    assert r2["J"] == pytest.approx(r["J"], rel=0.01) and np.isnan(r2["heading_error_deg"])


def test_ladder_verdict_names_the_largest_step_and_where_tcacs_keeps_its_lower_cost() -> None:
    from aes_ros.studies.common import GainSet
    from aes_ros.studies.ladder import verdict

    chosen = [GainSet("paper", 0.066, 0.97, 1.28), GainSet("TCACS", 0.02, 1.5, 0.5)]
    psi = {"offline": 0.9, "dynamic": 0.85, "camera": 0.6}
    summary = [
        {"rung": r, "setup": "linear", "gains": g.label, "psi_mean": p,
         "J_mean": (-500.0 if g.label == "TCACS" else -400.0) + (300.0 * (r == "camera"))
                   * (g.label == "TCACS")}
        for r, p in psi.items() for g in chosen
    ]  # fmt: skip
    v = verdict(summary, list(psi), ("linear",), chosen)
    assert v["largest_change"] == "dynamic -> camera"
    assert v["mean_abs_psi_change"]["offline -> dynamic"] == pytest.approx(0.05)
    assert v["tcacs_lower_J"]["offline"]["linear"] and not v["tcacs_lower_J"]["camera"]["linear"]
    assert not v["tcacs_keeps_advantage_on_every_rung"]
