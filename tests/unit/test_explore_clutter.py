"""``aes-swarm explore clutter``: a tiny run through the command line, and the posts."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from aes_ros.cli import main
from aes_ros.studies import clutter


@pytest.fixture(scope="module")
def quick(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("clutter")
    argv = ["explore", "clutter", "--quick", "--runs", "2", "--seed", "3", "--no-progress"]
    assert main([*argv, "--out", str(out), "--work", str(out / "work")]) == 0
    return out


def _cells(out: Path) -> dict[tuple[int, float], dict[str, float]]:
    with (out / "clutter.csv").open(newline="") as fh:
        rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(fh)]
    return {(int(r["posts"]), r["w_o"]): r for r in rows}


def test_avoidance_touches_the_posts_less_and_the_swarm_still_advances(quick: Path) -> None:
    cells = _cells(quick)
    off, on = cells[(4, 0.0)], cells[(4, 4.0)]
    assert off["post_collisions_per_robot_min_mean"] > 0  # without the term it hits posts
    assert on["post_collisions_per_robot_min_mean"] < off["post_collisions_per_robot_min_mean"]
    assert all(
        c["post_collisions_per_robot_min_mean"] == 0 for (n, _), c in cells.items() if n == 0
    )
    assert all(c["progress_m_mean"] > 0 for c in cells.values())
    assert (quick / "clutter.png").stat().st_size > 10_000


def test_runs_follow_the_seed_rule(quick: Path) -> None:
    with (quick / "clutter_runs.csv").open(newline="") as fh:
        runs = list(csv.DictReader(fh))
    assert len(runs) == 4 * 2  # (posts, w_o) cells x --runs
    assert sorted({int(r["seed"]) for r in runs}) == [3, 4]
    assert json.loads((quick / "clutter.json").read_text())["runs"] == 2


@pytest.mark.parametrize("n", [0, 2, 8])
def test_posts_stand_apart_in_the_band_and_repeat_with_the_seed(n: int) -> None:
    posts = clutter.place_posts(n, 7)
    assert posts.shape == (n, 3)
    np.testing.assert_array_equal(posts, clutter.place_posts(n, 7))
    assert np.all((posts[:, 0] >= clutter.BAND_X[0]) & (posts[:, 0] <= clutter.BAND_X[1]))
    assert np.all((posts[:, 1] >= clutter.BAND_Y[0]) & (posts[:, 1] <= clutter.BAND_Y[1]))
    gaps = np.linalg.norm(posts[:, None, :2] - posts[None, :, :2], axis=-1)
    assert np.all(gaps[np.triu_indices(n, 1)] >= clutter.POST_SPACING)
    if n:
        assert not np.array_equal(posts, clutter.place_posts(n, 8))


def test_runs_of_another_study_is_refused_naming_the_field(capsys) -> None:
    assert main(["explore", "pareto", "--runs", "3", "--no-progress"]) == 2
    assert "--runs: only for explore clutter" in capsys.readouterr().err
