"""A launch's outputs are on disk while it runs (aes_ros.run_writer, aes_ros.report,
aes_ros.trajectory_file): streamed rows equal the whole-run metrics, the trajectory
reads back as it was fed, a run cut short (also by SIGKILL) loads and rebuilds, a
full disk stops the writer with what was written still readable, and finishing a
long run takes memory bounded independent of its length."""

from __future__ import annotations

import csv
import errno
import os
import signal
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import h5py
import helpers.synthetic_run
import numpy as np
import pytest
from helpers.synthetic_run import samples, synthetic_scenario

from aes_ros import metrics_csv, plots, run_summary, run_writer, scenario, simulator
from aes_ros.metrics_csv import metrics_table
from aes_ros.report import rebuild_run_outputs
from aes_ros.ros.launch.param_files import write_scenario
from aes_ros.run_writer import RunWriter
from aes_ros.trajectory import load_trajectory, trajectory_samples
from aes_ros.trajectory_file import is_sealed

SYNTHETIC = str(Path(helpers.synthetic_run.__file__))


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


def test_streamed_outputs_equal_the_whole_run(tmp_path: Path, run) -> None:
    """metrics.csv streamed is the whole run's; the summary at the end has the numbers
    of the whole run's metrics (a short run: the same line as before streaming)."""
    sc, result = run
    writer = stream(tmp_path, sc, result, Clock())
    assert writer.written >= len(result.times) - 10  # flushed about once a (fake) second
    streamed = rows(tmp_path / "metrics.csv")
    summary = writer.finish()
    table = metrics_table(result.times, result.positions, result.headings, sc)
    assert summary == run_summary.summary(table, "combined (ROS)", 9)
    final = rows(tmp_path / "metrics.csv")
    assert len(final) == len(result.times) and streamed == final[: len(streamed)]
    np.testing.assert_allclose(
        [float(r["angular_velocity"]) for r in final], table["angular_velocity"], rtol=1e-5
    )
    assert is_sealed(tmp_path / "trajectory.h5")  # closed: every HDF5 reader opens it
    for name in ("snapshots.png", "metrics.png"):
        assert (tmp_path / name).stat().st_size > 0


def test_the_chunked_trajectory_reads_back_equal_to_what_was_fed(tmp_path: Path) -> None:
    """Fed one sample at a time, flushed every few: trajectory.h5 holds exactly the
    arrays fed, in the layout of ``simulate``, and reads back a slice or every k-th."""
    sc = synthetic_scenario(7)
    times, positions, headings = samples(0, 230, sc.nominal_positions())
    clock = Clock()
    writer = RunWriter(tmp_path, sc, "synthetic", clock=clock, flush_every=1.0)
    for k in range(len(times)):
        clock.now += 0.13  # a flush every 8 samples: many chunks and commits
        writer.add(times[k], positions[k], headings[k])
    assert writer.finish()
    traj = load_trajectory(tmp_path / "trajectory.h5")
    np.testing.assert_array_equal(traj.times, times)
    np.testing.assert_array_equal(traj.positions, positions[None])
    np.testing.assert_array_equal(traj.headings, headings[None])
    view = load_trajectory(tmp_path, every=7, start=3, stop=200)
    np.testing.assert_array_equal(view.positions, positions[None, 3:200:7])
    np.testing.assert_array_equal(view.times, times[3:200:7])
    chosen = trajectory_samples(tmp_path, [229, 0, 17, 17, -2])
    np.testing.assert_array_equal(chosen.headings, headings[None, [229, 0, 17, 17, 228]])
    with h5py.File(tmp_path / "trajectory.h5") as h5:  # what MATLAB and HDFView see
        assert h5["positions"].attrs["units"] == "m" and h5["times"].attrs["units"] == "s"
        assert h5["positions"].maxshape == (1, None, 7, 2) and h5["positions"].chunks[1] > 1
        assert int(h5["n_samples"][()]) == 230


def test_a_run_cut_short_loads_and_rebuilds(tmp_path: Path, run) -> None:
    """The writer is never finished: metrics.csv holds complete rows up to the last
    flush, trajectory.h5 its samples, ``aes-swarm report`` writes the rest."""
    sc, result = run
    write_scenario(sc, tmp_path / "scenario.yaml")
    clock = Clock()
    writer = stream(tmp_path, sc, result, clock, upto=35)
    on_disk = rows(tmp_path / "metrics.csv")
    assert len(on_disk) == writer.written and 20 <= writer.written < 35
    assert all(len(r) == len(metrics_csv.CSV_COLUMNS) and None not in r.values() for r in on_disk)
    partial = load_trajectory(tmp_path)  # while its writer still has it open
    assert len(partial.times) == writer.written
    np.testing.assert_array_equal(partial.positions, result.positions[:, : writer.written])
    summary = rebuild_run_outputs(tmp_path)
    assert summary.startswith("combined (ROS): N=9")
    assert len(rows(tmp_path / "metrics.csv")) == writer.written
    assert load_trajectory(tmp_path).positions.shape == (1, writer.written, 9, 2)


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
    assert writer.finish() == ""  # nothing more is written; the rest is for `report`
    assert len(rows(tmp_path / "metrics.csv")) == kept
    assert len(load_trajectory(tmp_path).times) >= kept


def test_a_full_disk_under_hdf5_stops_the_writer_and_the_process_exits_cleanly(
    tmp_path: Path,
) -> None:
    """HDF5's own write fails (a file size limit, like a full disk): the writer stops
    with the system's reason, the process exits normally (a failed HDF5 flush closed
    the usual way crashes the interpreter at exit), the file reads back to its last
    commit."""
    done = subprocess.run(
        [sys.executable, SYNTHETIC, str(tmp_path), "--file-size-limit", "150000"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    lines = done.stdout.splitlines()
    assert any(line.startswith("error ") and "File too large" in line for line in lines), lines
    written = int(lines[-1].split()[1])
    traj = load_trajectory(tmp_path)
    assert len(traj.times) >= written > 100
    expected = samples(0, len(traj.times), synthetic_scenario(9).nominal_positions())
    np.testing.assert_array_equal(traj.positions[0], expected[1])
    assert len(rows(tmp_path / "metrics.csv")) == written


def test_a_run_killed_mid_way_reads_back_to_its_last_flush_and_reports(tmp_path: Path) -> None:
    """SIGKILL to a process streaming into a RunWriter (a flush every 50 ms): its
    trajectory.h5 opens, holds at least every sample of the last flush it reported,
    each equal to what was fed; metrics.csv holds complete rows; ``aes-swarm report``
    then writes the plots and the summary and leaves an ordinary (closed) HDF5 file."""
    writer = subprocess.Popen(
        [sys.executable, SYNTHETIC, str(tmp_path)], stdout=subprocess.PIPE, text=True
    )
    try:
        reported = 0
        deadline = time.monotonic() + 60
        while reported < 400 and time.monotonic() < deadline:
            line = writer.stdout.readline()
            if line.startswith("written "):
                reported = int(line.split()[1])
        os.kill(writer.pid, signal.SIGKILL)
    finally:
        writer.kill()
        writer.wait(10)
        writer.stdout.close()
    assert writer.returncode == -signal.SIGKILL and reported >= 400
    assert not is_sealed(tmp_path)  # as its killed writer left it
    traj = load_trajectory(tmp_path)
    assert len(traj.times) >= reported
    expected = samples(0, len(traj.times), synthetic_scenario(9).nominal_positions())
    np.testing.assert_array_equal(traj.times, expected[0])
    np.testing.assert_array_equal(traj.positions[0], expected[1])
    np.testing.assert_array_equal(traj.headings[0], expected[2])
    on_disk = rows(tmp_path / "metrics.csv")
    assert reported <= len(on_disk) <= len(traj.times)
    assert all(None not in r.values() for r in on_disk)

    summary = rebuild_run_outputs(tmp_path)
    assert summary.startswith(f"synthetic: N=9 runs=1 t={(len(traj.times) - 1) * 0.02:.1f}s")
    assert is_sealed(tmp_path)  # `report` rewrote it closed: MATLAB, HDFView open it
    np.testing.assert_array_equal(load_trajectory(tmp_path).positions, traj.positions)
    assert len(rows(tmp_path / "metrics.csv")) == len(traj.times)
    for name in ("snapshots.png", "metrics.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


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
    traj = load_trajectory(tmp_path / "trajectory.h5")
    np.testing.assert_array_equal(traj.times, result.times[2:31])


def test_outputs_that_end_short_of_the_run_are_told_apart_from_complete_ones(
    tmp_path: Path, run
) -> None:
    """A launcher that missed the samples between step 7 and the run's end (held up
    longer than the bridge keeps them) is told how much its outputs lack; complete
    outputs, and ones missing a frame or two at the end, are not flagged."""
    sc, result = run
    t_end = float(result.times[-1])
    writer = stream(tmp_path / "short", sc, result, Clock(), upto=8)
    assert writer.end_gap(t_end) == pytest.approx(t_end - result.times[7])
    assert stream(tmp_path / "full", sc, result, Clock()).end_gap(t_end) == 0.0
    n = len(result.times)
    assert stream(tmp_path / "two", sc, result, Clock(), upto=n - 2).end_gap(t_end) == 0.0


def test_finishing_a_long_run_takes_memory_independent_of_its_length(tmp_path: Path) -> None:
    """200 000 samples of 20 robots (an hour at 55 Hz) streamed in chunks: finish()
    (plots and summary) peaks at a small part of what loading the trajectory would
    take, and its summary is that of the whole run's metrics."""
    n_samples, robots, chunk = 200_000, 20, 1_000
    sc = synthetic_scenario(robots)
    nominal = sc.nominal_positions()
    clock = Clock()
    writer = RunWriter(tmp_path, sc, "long", clock=clock)
    for start in range(0, n_samples, chunk):
        times, positions, headings = samples(start, start + chunk, nominal)
        for k in range(chunk):
            writer.add(times[k], positions[k], headings[k])
        clock.now += 1.0  # one flush per chunk
    whole = 8 * n_samples * (1 + 3 * robots)  # times, positions, headings as float64
    assert plots  # matplotlib imported before: its modules are not the run's memory
    tracemalloc.start()
    try:
        summary = writer.finish()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    print(
        f"\nwhole trajectory {whole / 1e6:.1f} MB, peak traced during finish() {peak / 1e6:.1f} MB"
    )
    assert writer.written == n_samples
    assert peak < whole / 4, (peak, whole)
    head, tail = samples(0, 2, nominal), samples(n_samples - 1, n_samples, nominal)
    assert summary.startswith(f"long: N=20 runs=1 t={tail[0][-1] - head[0][0]:.1f}s")
    moved = np.linalg.norm(tail[1][0].mean(axis=0) - head[1][0].mean(axis=0))
    assert f"centroid moved {moved:.2f} m" in summary
    last = metrics_table(*samples(n_samples - 2, n_samples, nominal), sc)
    assert f"psi={last['alignment'][-1]:.3f} psi_heading={last['heading_order'][-1]:.3f}" in summary
    assert summary.endswith("omega=+0.010 rad/s")  # the formation turns at 0.01 rad/s


def _rss_mb() -> float:
    status = Path("/proc/self/status").read_text()
    return (
        int(next(line for line in status.splitlines() if line.startswith("VmRSS")).split()[1])
        / 1024
    )


def test_streaming_a_long_run_keeps_the_writers_memory_flat(tmp_path: Path) -> None:
    """Four minutes of 50 robots at 50 Hz streamed to disk: after the first 40 s the
    process's memory stays within a few MB (HDF5's default chunk cache grew by ~15 MB
    over the same samples, C memory that tracemalloc does not see)."""
    sc = scenario.load("combined").with_robots(50)
    now = [0.0]
    writer = RunWriter(tmp_path, sc, "flat", clock=lambda: now[0])
    pos, head = np.random.default_rng(0).random((50, 2)), np.zeros(50)
    for k in range(12_000):
        now[0] = k * 0.02
        writer.add(k * 0.02, pos + k * 1e-4, head)
        if k == 2_000:
            warm = _rss_mb()
    assert writer.written > 11_900
    assert _rss_mb() - warm < 6.0


def test_the_plots_drawn_in_a_child_process_are_the_same(tmp_path: Path, run) -> None:
    """finish(scenario_file) draws in a child process (the launcher's way: it never
    loads matplotlib) the same outputs and summary as in this process."""
    sc, result = run
    here, child = tmp_path / "here", tmp_path / "child"
    expected = stream(here, sc, result, Clock()).finish()
    scenario_file = write_scenario(sc, tmp_path / "scenario.yaml")
    assert stream(child, sc, result, Clock()).finish(scenario_file) == expected
    for name in ("snapshots.png", "metrics.png"):
        assert (child / name).stat().st_size > 0
    broken = stream(tmp_path / "broken", sc, result, Clock())
    assert broken.finish(tmp_path / "missing.yaml") == ""
    assert "cannot draw the outputs" in broken.error


def test_drawing_started_before_a_stop_gives_the_same_outputs(tmp_path: Path, run) -> None:
    """The launcher starts the drawing child (start_drawing) before it stops its processes
    and collects it after (finish): the files are closed at the start, and the summary
    and plots are those of finish(scenario_file) at once."""
    sc, result = run
    scenario_file = write_scenario(sc, tmp_path / "scenario.yaml")
    expected = stream(tmp_path / "at_once", sc, result, Clock()).finish(scenario_file)
    early = stream(tmp_path / "early", sc, result, Clock())
    early.start_drawing(scenario_file)
    assert is_sealed(tmp_path / "early" / "trajectory.h5")  # closed: any HDF5 reader opens it
    assert early.finish(scenario_file) == expected != ""
    for name in ("snapshots.png", "metrics.png"):
        assert (tmp_path / "early" / name).stat().st_size > 0
