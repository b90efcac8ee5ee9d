"""Outputs are never lost by accident (:mod:`aes_ros.previous_run`): ``aes-swarm launch``,
``simulate``, ``optimize`` and ``calibrate`` refuse to write over an earlier run before
they start anything, and ``--overwrite`` removes that run's files and nothing else.

``aes-swarm`` runs in-process; the launch itself is replaced by a stand-in (the refusal
comes before it; ``tests/system/test_previous_run.py`` runs a real one).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import pytest

import aes_ros.ros.launch
from aes_ros import scenario
from aes_ros.cli import main
from aes_ros.previous_run import (
    LAUNCH_OUTPUTS,
    EarlierRunError,
    check_out_dir,
    remove,
)
from aes_ros.ros.launch import LaunchConfig, Launcher, LaunchError, LaunchResult

SMALL = ["--setup", "linear", "--set", "rows=3", "--set", "cols=3", "--set", "duration=1"]


def earlier_launch(out: Path) -> dict[Path, bytes]:
    """A directory as a launch leaves it (some of its files), and what each holds."""
    out.mkdir(parents=True)
    (out / "logs").mkdir()
    files = {
        out / "run.json": b'{"label": "the first run"}\n',
        out / "metrics.csv": b"t,alignment\n0.0,1.0\n",
        out / "logs" / "sim_bridge.log": b"bridge\n",
    }
    for path, data in files.items():
        path.write_bytes(data)
    return files


def unchanged(files: dict[Path, bytes]) -> bool:
    return all(path.read_bytes() == data for path, data in files.items())


@pytest.fixture
def launches(monkeypatch: pytest.MonkeyPatch) -> list[LaunchConfig]:
    """The configurations ``aes-swarm launch`` would run (none is started)."""
    calls: list[LaunchConfig] = []

    def stand_in(config: LaunchConfig, say: Callable[[str], None]) -> LaunchResult:
        calls.append(config)
        return LaunchResult(samples=0, t_last=0.0, t_go=0.0, wall_time=0.0, summary="ran")

    monkeypatch.setattr(aes_ros.ros.launch, "launch", stand_in)
    return calls


def test_a_launch_into_an_earlier_runs_directory_is_refused_before_anything_starts(
    tmp_path: Path, launches: list[LaunchConfig], capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    files = earlier_launch(out)
    assert main(["launch", "--robots", "4", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"--out {out} holds an earlier run (run.json, metrics.csv, logs)" in err
    assert "--overwrite" in err and "Traceback" not in err
    assert launches == [] and unchanged(files)
    assert sorted(p.name for p in out.iterdir()) == ["logs", "metrics.csv", "run.json"]


def test_a_launch_into_a_new_or_empty_directory_or_one_of_other_files_goes_ahead(
    tmp_path: Path, launches: list[LaunchConfig]
) -> None:
    (tmp_path / "empty").mkdir()
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "README.txt").write_text("mine")
    for out in ("new", "empty", "notes"):
        assert main(["launch", "--robots", "4", "--out", str(tmp_path / out)]) == 0
    assert [config.overwrite for config in launches] == [False] * 3


def test_with_overwrite_the_launch_goes_ahead(tmp_path: Path, launches: list[LaunchConfig]) -> None:
    out = tmp_path / "out"
    earlier_launch(out)
    assert main(["launch", "--robots", "4", "--out", str(out), "--overwrite"]) == 0
    assert len(launches) == 1 and launches[0].overwrite and launches[0].out_dir == out


def test_a_recording_over_an_earlier_ones_segment_is_refused(
    tmp_path: Path, launches: list[LaunchConfig], capsys: pytest.CaptureFixture[str]
) -> None:
    """The earlier recording's numbered segment, not only the file named, stops the launch."""
    segment = tmp_path / "run_1.mcap"
    segment.write_bytes(b"someone else's segment")
    bag = tmp_path / "run.mcap"
    assert main(["launch", "--robots", "4", "--record", str(bag)]) == 2
    err = capsys.readouterr().err
    assert f"--record {bag} holds an earlier recording (run_1.mcap)" in err
    assert launches == [] and segment.read_bytes() == b"someone else's segment"


def test_the_launcher_with_overwrite_removes_the_earlier_runs_files_and_no_others(
    tmp_path: Path,
) -> None:
    out, bag = tmp_path / "out", tmp_path / "bags" / "run.mcap"
    earlier_launch(out)
    (out / "notes.txt").write_text("mine")
    bag.parent.mkdir()
    earlier_bag = [bag, bag.with_name("run_1.mcap"), bag.with_name("run.sequences.json")]
    others = [bag.with_name(n) for n in ("run_x.mcap", "run.mcap.bak", "other_1.mcap")]
    for path in (*earlier_bag, *others):
        path.write_bytes(b"x")
    sc = scenario.load("linear").with_robots(4)
    said: list[str] = []
    with pytest.raises(LaunchError, match="holds an earlier run"):
        Launcher(LaunchConfig(sc, out_dir=out, record=bag), said.append)
    launcher = Launcher(LaunchConfig(sc, out_dir=out, record=bag, overwrite=True), said.append)
    assert launcher.procs.children == []  # nothing started yet
    assert not (out / "run.json").exists() and not (out / "metrics.csv").exists()
    assert list((out / "logs").iterdir()) == []  # made anew for this run
    assert (out / "notes.txt").read_text() == "mine"
    assert not any(path.exists() for path in earlier_bag)
    assert all(path.read_bytes() == b"x" for path in others)
    assert len(said) == 1 and "--overwrite: removed the earlier run's" in said[0]
    assert str(bag.with_name("run_1.mcap")) in said[0]


def test_a_planted_link_counts_and_only_the_link_is_removed(tmp_path: Path) -> None:
    """A link where an output goes (even one to nothing) is refused like a file; removing
    it with --overwrite removes the link, never what it points to."""
    out, target = tmp_path / "out", tmp_path / "precious.txt"
    out.mkdir()
    target.write_text("precious")
    (out / "run.json").symlink_to(target)
    (out / "metrics.csv").symlink_to(tmp_path / "nowhere")
    with pytest.raises(EarlierRunError, match=r"run\.json, metrics\.csv"):
        check_out_dir(out, LAUNCH_OUTPUTS, overwrite=False)
    found = check_out_dir(out, LAUNCH_OUTPUTS, overwrite=True)
    assert remove(found) == [out / "run.json", out / "metrics.csv"]
    assert list(out.iterdir()) == [] and target.read_text() == "precious"


def test_simulate_refuses_an_earlier_run_and_replaces_it_with_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "sim"
    assert main(["simulate", *SMALL, "--out", str(out)]) == 0
    first = (out / "metrics.csv").read_bytes()
    assert main(["simulate", *SMALL, "--seed", "7", "--out", str(out)]) == 2
    assert f"--out {out} holds an earlier run" in capsys.readouterr().err
    assert (out / "metrics.csv").read_bytes() == first
    assert main(["simulate", *SMALL, "--seed", "7", "--out", str(out), "--overwrite"]) == 0
    assert (out / "metrics.csv").read_bytes() != first


def test_optimize_refuses_an_earlier_tuning_before_it_tunes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "result.json").write_text("{}")
    assert main(["optimize", *SMALL, "--no-progress", "--out", str(tmp_path)]) == 2
    assert "holds an earlier run (result.json)" in capsys.readouterr().err
    assert (tmp_path / "result.json").read_text() == "{}"


def test_calibrate_refuses_an_existing_calibration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "calibration.yaml"
    out.write_text("the lab's calibration")
    none = str(tmp_path / "none")
    args = ["calibrate", "--image", none, "--arena-layout", none, "--camera-info", none]
    assert main([*args, "--out", str(out)]) == 2
    assert f"--out {out} holds an earlier calibration" in capsys.readouterr().err
    assert out.read_text() == "the lab's calibration"


def test_a_directory_of_another_user_is_refused_whatever_it_holds(
    tmp_path: Path, launches: list[LaunchConfig], capsys: pytest.CaptureFixture[str]
) -> None:
    """Someone else's empty directory (``/tmp/out`` made by another user first): its owner
    could put a link where a run's file is about to be created, so nothing goes there."""
    if os.geteuid() != 0:
        pytest.skip("giving a directory to another user needs root")
    out = tmp_path / "out"
    out.mkdir()
    os.chown(out, 12345, 12345)
    assert main(["launch", "--robots", "4", "--out", str(out), "--overwrite"]) == 2
    assert "belongs to another user (uid 12345)" in capsys.readouterr().err
    assert launches == [] and list(out.iterdir()) == []
    assert main(["launch", "--robots", "4", "--record", str(out / "run.mcap")]) == 2
    assert "--record" in capsys.readouterr().err and launches == []
