"""A launch's outputs are on disk while it runs (aes_ros.run_writer, aes_ros.report):
streamed rows equal the whole-run metrics, a run cut short loads and rebuilds, a
full disk stops the writer with what was written still readable."""

from __future__ import annotations

import csv
import errno
import os
from pathlib import Path

import numpy as np
import pytest

from aes_ros import report, run_writer, scenario, simulator
from aes_ros.report import PARTS_DIR, load_trajectory, metrics_table, rebuild_run_outputs
from aes_ros.ros.launch.plan import write_scenario
from aes_ros.run_writer import RunWriter


@pytest.fixture(scope="module")
def run() -> tuple[scenario.Scenario, simulator.SimResult]:
    sc = scenario.load("combined", {"duration": 3.0}).with_robots(9)
    return sc, simulator.simulate(sc, [4])


class Clock:
    """Wall time that advances 0.1 s per sample fed to the writer."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def stream(out: Path, sc, result, clock: Clock, upto: int | None = None) -> RunWriter:
    writer = RunWriter(out, sc, "combined (ROS)", clock=clock)
    for k in range(len(result.times) if upto is None else upto):
        clock.now += 0.1
        writer.add(result.times[k], result.positions[0, k], result.headings[0, k])
    return writer


def rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_streamed_outputs_equal_the_whole_run_and_finish_cleans_up(tmp_path: Path, run) -> None:
    sc, result = run
    writer = stream(tmp_path, sc, result, Clock())
    assert writer.written >= len(result.times) - 10  # flushed about once a (fake) second
    streamed = rows(tmp_path / "metrics.csv")
    summary = writer.finish()
    assert summary.startswith("combined (ROS): N=9 runs=1")
    assert not (tmp_path / PARTS_DIR).exists()
    final = rows(tmp_path / "metrics.csv")
    assert len(final) == len(result.times) and streamed == final[: len(streamed)]
    table = metrics_table(result.times, result.positions, result.headings, sc)
    np.testing.assert_allclose(
        [float(r["angular_velocity"]) for r in final], table["angular_velocity"], rtol=1e-5
    )
    traj = load_trajectory(tmp_path / "trajectory.npz")
    np.testing.assert_array_equal(traj.positions, result.positions)
    for name in ("snapshots.png", "metrics.png"):
        assert (tmp_path / name).stat().st_size > 0


def test_a_run_cut_short_loads_and_rebuilds(tmp_path: Path, run) -> None:
    """The writer is never finished (its process killed): metrics.csv holds complete
    rows up to the last flush, the parts load, ``aes-swarm report`` writes the rest."""
    sc, result = run
    write_scenario(sc, tmp_path / "scenario.yaml")
    clock = Clock()
    writer = stream(tmp_path, sc, result, clock, upto=35)
    on_disk = rows(tmp_path / "metrics.csv")
    assert len(on_disk) == writer.written and 20 <= writer.written < 35
    assert all(len(r) == len(report.CSV_COLUMNS) and None not in r.values() for r in on_disk)
    partial = load_trajectory(tmp_path)
    assert len(partial.times) == writer.written
    np.testing.assert_array_equal(partial.positions, result.positions[:, : writer.written])
    summary = rebuild_run_outputs(tmp_path)
    assert summary.startswith("combined (ROS): N=9")
    assert len(rows(tmp_path / "metrics.csv")) == writer.written
    assert load_trajectory(tmp_path / "trajectory.npz").positions.shape == (1, writer.written, 9, 2)
    assert not (tmp_path / PARTS_DIR).exists()


def test_a_full_disk_stops_the_writer_and_keeps_what_was_written(
    tmp_path: Path, run, monkeypatch: pytest.MonkeyPatch
) -> None:
    sc, result = run
    clock = Clock()
    writer = stream(tmp_path, sc, result, clock, upto=25)
    kept = writer.written
    real_write = os.write

    def full(fd: int, data: bytes) -> int:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(run_writer.os, "write", full)
    for k in range(25, len(result.times)):
        clock.now += 0.1
        writer.add(result.times[k], result.positions[0, k], result.headings[0, k])
    monkeypatch.setattr(run_writer.os, "write", real_write)
    assert writer.error is not None and "No space left on device" in writer.error
    assert writer.finish() == ""  # nothing more is written; the parts stay for `report`
    assert len(rows(tmp_path / "metrics.csv")) == kept
    assert len(load_trajectory(tmp_path).times) >= kept


def test_add_from_takes_growing_samples_where_it_stopped_up_to_t_end(tmp_path: Path, run) -> None:
    """What the launcher streams: its monitor's lists grow between calls."""
    sc, result = run
    times = list(result.times)
    positions, headings = list(result.positions[0]), list(result.headings[0])
    writer = RunWriter(tmp_path, sc, "combined (ROS)", clock=Clock())
    t_end = times[30]
    k = writer.add_from(times[:10], positions, headings, 2, t_end)
    assert k == 10
    k = writer.add_from(times, positions, headings, k, t_end)
    assert k == 31 and writer.add_from(times, positions, headings, k, t_end) == 31
    writer.finish()
    traj = load_trajectory(tmp_path / "trajectory.npz")
    np.testing.assert_array_equal(traj.times, result.times[2:31])
