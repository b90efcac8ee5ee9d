"""The tuning cost J (E10), the tuning driver and the ``optimize``/``study`` commands.

Small swarms and short runs keep this quick; the paper-scale run is a benchmark
(``aes-swarm optimize`` with defaults), not a test.
"""

from __future__ import annotations

import csv
import inspect
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from aes_ros import metrics, scenario, simulator
from aes_ros.cli import build_parser, main
from aes_ros.optim import cost as cost_module
from aes_ros.optim import tcacs, tuning
from aes_ros.optim.cost import MonteCarloCost, NonFiniteCostWarning
from aes_ros.params import ParameterError

PAPER = [0.066, 0.97, 1.28]
EXPLODING = [10.0, 50.0, 100.0]  # Euler-unstable springs: NaN within a few steps


@pytest.fixture(scope="module")
def small() -> scenario.Scenario:
    """The combined setup on a 4x4 grid for 5 s."""
    return scenario.load("combined").with_robots(16).with_overrides({"duration": 5.0})


def test_j_is_the_monte_carlo_mean_of_the_per_run_sums(small: scenario.Scenario) -> None:
    c = MonteCarloCost(small, seeds=[3, 4, 5])
    J = c(np.array([PAPER]))
    res = simulator.simulate(small, [3, 4, 5], record=False)  # the scenario's gains = PAPER
    F, psi = res.metric("total_force"), res.metric("alignment")
    assert F.shape[1] == small.n_steps + 1  # t = 0 … t_f
    expected = np.mean(np.sum(F / 16 - psi, axis=1))
    assert J == pytest.approx([expected], rel=1e-12)
    assert c.w1 == pytest.approx(1 / 16) and c.w2 == -1.0


def test_weights_enter_linearly(small: scenario.Scenario) -> None:
    X = np.array([PAPER])
    base = MonteCarloCost(small, n_mc=2)
    only_f = MonteCarloCost(small, n_mc=2, w1=1.0, w2=0.0)(X)
    only_psi = MonteCarloCost(small, n_mc=2, w1=0.0, w2=1.0)(X)
    assert base(X) == pytest.approx(only_f / 16 - only_psi)


def test_common_random_numbers_and_batch_independence(small: scenario.Scenario) -> None:
    c = MonteCarloCost(small, n_mc=3)
    X = np.array([PAPER, [0.1, 2.0, 0.8], PAPER])
    J = c(X)
    assert J[0] == J[2]  # same seeds for every candidate
    assert c(X[1:2])[0] == pytest.approx(J[1], rel=1e-12)  # batch-mates do not matter
    assert c.nfev == 4


def test_all_candidates_and_runs_are_one_simulate_call(
    small: scenario.Scenario, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = []

    def counting(sc, seeds, **kw):
        calls.append((list(seeds), kw["gains"]))
        return simulator.simulate(sc, seeds, **kw)

    monkeypatch.setattr(cost_module, "simulate", counting)
    c = MonteCarloCost(small, seeds=[7, 8])
    c(np.array([PAPER, [0.1, 2.0, 0.8], [0.03, 0.5, 2.0]]))
    assert len(calls) == 1
    seeds, gains = calls[0]
    assert seeds == [7, 8] * 3
    assert [(g.alpha, g.beta, g.k) for g in gains[::2]] == [
        (0.066, 0.97, 1.28),
        (0.1, 2.0, 0.8),
        (0.03, 0.5, 2.0),
    ]
    assert gains[0].w_l == small.w_l  # the other gains are the scenario's


def test_paper_gains_beat_a_clearly_bad_candidate(small: scenario.Scenario) -> None:
    c = MonteCarloCost(small, n_mc=4)
    good, sluggish, wild = c(np.array([PAPER, [0.001, 0.01, 0.5], [0.5, 0.05, 5.0]]))
    assert good < sluggish and good < wild


def test_non_finite_cost_is_inf_with_one_warning(small: scenario.Scenario) -> None:
    c = MonteCarloCost(small, n_mc=2)
    with pytest.warns(NonFiniteCostWarning) as record:
        J = c(np.array([PAPER, EXPLODING, [3.0, 10.0, 50.0]]))
    assert len(record) == 1
    assert np.isfinite(J[0]) and np.all(np.isposinf(J[1:]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.isposinf(c(np.array([EXPLODING]))[0])  # counted, not warned again
    assert c.n_nonfinite == 3


def test_bad_input_names_the_argument(small: scenario.Scenario) -> None:
    with pytest.raises(ValueError, match=r"^n_mc:"):
        MonteCarloCost(small, n_mc=0)
    with pytest.raises(ValueError, match=r"^names:"):
        MonteCarloCost(small, names=("alpha", "gamma"))
    with pytest.raises(ValueError, match=r"^w1:"):
        MonteCarloCost(small, w1=float("nan"))
    with pytest.raises(ValueError, match=r"^X:"):
        MonteCarloCost(small, n_mc=1)(np.zeros((2, 2)))


def test_tune_improves_on_its_seeds_and_respects_the_box(small: scenario.Scenario) -> None:
    bounds = {"alpha": (0.001, 0.5), "beta": (0.01, 5.0)}  # k stays at the scenario's 1.28
    out = tuning.tune(small, bounds=bounds, evals=60, mc=2, seed=1)
    res = out.result
    assert res.nfev == 60 and res.x.shape == (2,)
    assert res.fun < np.min(res.history_fun[:15])  # better than the first iteration's best
    assert out.cost.seeds == [1, 2]  # run r uses seed + r
    assert set(out.best) == {"alpha", "beta"}


def test_parse_bounds() -> None:
    b = tuning.parse_bounds("alpha=0.01:0.2, k=1:3")
    assert b == {"alpha": (0.01, 0.2), "beta": tuning.DEFAULT_BOUNDS["beta"], "k": (1.0, 3.0)}
    for text, field in [
        ("alpha=0.2:0.01", "alpha"),
        ("alpha=0.1:0.1", "alpha"),
        ("k=1", "k"),
        ("k=a:b", "k"),
        ("gamma=0:1", "gamma"),
        ("k=-1:2", "k"),
    ]:
        with pytest.raises(ParameterError, match=f"--bounds: .*{field}"):
            tuning.parse_bounds(text)


def test_spring_strain(small: scenario.Scenario) -> None:
    nominal, neighbors, rest = small.sheet()
    assert metrics.spring_strain(nominal, neighbors, rest) == pytest.approx(0.0, abs=1e-12)
    stretched = np.stack([nominal * 1.1, nominal * 0.5])
    assert metrics.spring_strain(stretched, neighbors, rest) == pytest.approx([0.1, 0.5])


SMALL_ARGS = ["--set", "rows=3", "--set", "cols=3", "--set", "duration=2"]


def test_optimize_command_writes_its_outputs(tmp_path: Path, capsys) -> None:
    out = tmp_path / "tune"
    rc = main(["optimize", *SMALL_ARGS, "--evals", "30", "--runs", "2", "--no-progress",
               "--seed", "4", "--out", str(out)])  # fmt: skip
    assert rc == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith("best J = ") and "30 evaluations" in line and "\n" not in line
    result = json.loads((out / "result.json").read_text())
    assert set(result["best"]) == {"alpha", "beta", "k"}
    assert result["evaluations"] == 30 and result["wall_time_s"] > 0
    assert result["settings"]["mc_seeds"] == [4, 5]  # --seed 4: run r uses 4 + r
    assert result["settings"]["w1"] == pytest.approx(1 / 9)
    with open(out / "history.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 30
    assert float(rows[-1]["best_J"]) == pytest.approx(result["best_J"], rel=1e-5)
    assert (out / "convergence.png").stat().st_size > 1000


@pytest.mark.parametrize(
    ("args", "field"),
    [
        (["--bounds", "alpha=0.5:0.1"], "--bounds"),
        (["--bounds", "k=:"], "--bounds"),
        (["--evals", "10"], "--evals"),
        (["--evals", "0"], "--evals"),
        (["--runs", "0"], "--runs"),
        (["--ants", "1"], "--ants"),
        (["--ants", "20", "--evals", "19"], "--evals"),
        (["--weighting", "wheel"], "--weighting"),
        (["--gamma", "2"], "--gamma"),
        (["--m", "-1"], "--m"),
        (["--setup", "nowhere"], "--setup"),
    ],
)
def test_optimize_bad_input_exits_2_naming_the_field(
    tmp_path: Path, capsys, args: list[str], field: str
) -> None:
    rc = main(["optimize", *SMALL_ARGS, "--no-progress", *args, "--out", str(tmp_path)])
    assert rc == 2
    assert field in capsys.readouterr().err


@pytest.mark.parametrize(
    ("args", "field"),
    [
        (["--evals", "10"], "--evals"),  # fewer than one iteration of the paper's 15 ants
        (["--evals", "0"], "--evals"),
        (["--runs", "0"], "--runs"),
        (["--restarts", "0"], "--restarts"),
        (["--held-out", "0"], "--held-out"),
    ],
)
def test_study_bad_input_exits_2_naming_the_field(
    tmp_path: Path, capsys, args: list[str], field: str
) -> None:
    out = tmp_path / "study"
    rc = main(["study", *SMALL_ARGS, "--no-progress", *args, "--out", str(out)])
    assert rc == 2
    err = capsys.readouterr().err
    assert f"error: {field}:" in err or f"error: argument {field}:" in err, err
    assert not out.exists()


def test_paper_options_are_the_defaults_of_tune_and_the_cli() -> None:
    paper = dict(tcacs.PAPER_OPTIONS)
    params = inspect.signature(tuning.tune).parameters
    assert {k: params[k].default for k in paper} == paper
    assert params["evals"].default == tcacs.DEFAULT_MAX_EVALS
    args = build_parser().parse_args(["optimize", "--out", "x"])
    assert (args.ants, args.weighting, args.gamma, args.m) == tuple(paper.values())
    assert args.evals == tcacs.DEFAULT_MAX_EVALS
    assert build_parser().parse_args(["study", "--out", "x"]).evals == tcacs.DEFAULT_MAX_EVALS


def test_study_command_smoke(tmp_path: Path, capsys) -> None:
    rc = main(["study", *SMALL_ARGS, "--evals", "15", "--runs", "1", "--restarts", "1",
               "--held-out", "2", "--no-progress", "--out", str(tmp_path)])  # fmt: skip
    assert rc == 0
    data = json.loads((tmp_path / "study.json").read_text())
    assert [r["gains"] for r in data["table"]][:2] == [
        "untuned (α=β=k=1)",
        "paper (0.066, 0.97, 1.28)",
    ]
    assert len(data["table"]) == 6 and len(data["runs"]) == 4
    for name in ("effect_of_optimisation.png", "convergence.png", "j_slices.png", "table.csv"):
        assert (tmp_path / name).stat().st_size > 0
    assert "| gains |" in (tmp_path / "study.md").read_text()
