"""A run's outputs written while it goes, so that a crash loses at most a second or two.

``aes-swarm launch`` streams every pose sample into a :class:`RunWriter`:

- ``metrics.csv`` gets its rows (:data:`aes_ros.metrics_csv.CSV_COLUMNS`, the same
  numbers :func:`aes_ros.metrics_csv.metrics_table` gives for the whole run) appended
  as whole lines, one ``os.write`` per flush;
- the trajectory is appended to ``trajectory.h5`` (:mod:`aes_ros.trajectory_file`:
  one HDF5 file written with SWMR; each flush commits its samples);
- both are flushed at least every ``flush_every`` wall seconds (1 s).

Memory holds one flush's samples, never the run: :meth:`RunWriter.finish` closes the
files and draws the plots and the summary from the disk
(:func:`aes_ros.report.finish_run_outputs`, bounded whatever the run's length); given
the scenario's file it does that in a child process (``python -m aes_ros.report``),
so that a long-lived caller (the launcher) never loads matplotlib and its memory
stays what it was during the run (``bench/bench_soak.py`` checks it); the launcher
starts that child (:meth:`RunWriter.start_drawing`) before it stops its processes.
After a crash (even ``kill -9`` of the launcher) ``metrics.csv`` and
``trajectory.h5`` read back up to the last flush (:func:`aes_ros.trajectory.load_trajectory`),
and ``aes-swarm report DIR`` (:func:`aes_ros.report.rebuild_run_outputs`) writes the
rest. A write that fails (disk full) stops the writer with :attr:`RunWriter.error`
set; what was written before stays readable.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from aes_ros.metrics_csv import csv_header, csv_rows, metrics_rows
from aes_ros.report import finish_run_outputs
from aes_ros.scenario import Scenario
from aes_ros.trajectory import TRAJECTORY_FILE, Trajectory
from aes_ros.trajectory_file import TrajectoryWriter, error_reason

#: Wall seconds between flushes (at most what a crash can lose, plus one sample).
FLUSH_EVERY = 1.0
#: The run's description next to its outputs (the label of its plots and summary).
RUN_FILE = "run.json"


class RunWriter:
    """Streams the samples of one run into ``out_dir``.

    Parameters
    ----------
    out_dir : the run's output directory (created; an old trajectory in it is removed).
    scenario : for the metrics (forces E4 with its gains and command).
    label : name of the run in the plots and the summary.
    flush_every : wall seconds between flushes.
    clock : wall clock [s] (monotonic); a parameter for tests.
    """

    def __init__(
        self,
        out_dir: Path,
        scenario: Scenario,
        label: str,
        *,
        flush_every: float = FLUSH_EVERY,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.out_dir = Path(out_dir)
        self.scenario, self.label = scenario, label
        self.flush_every, self._clock = flush_every, clock
        self.error: str | None = None
        #: Samples on disk, and the sim time [s] of the last of them.
        self.written = 0
        self.t_written: float | None = None
        #: Samples added, and the sim times [s] of the first and the last of them.
        self.added = 0
        self.t_added: tuple[float, float] | None = None
        self._pending: list[tuple[float, np.ndarray, np.ndarray]] = []
        self._previous: Trajectory | None = None  # the last sample written
        self._last_flush = clock()
        self._metrics_fd: int | None = None
        self._trajectory: TrajectoryWriter | None = None  # created by the first flush
        self._drawing: subprocess.Popen[str] | None = None  # start_drawing's child
        try:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            (self.out_dir / TRAJECTORY_FILE).unlink(missing_ok=True)
            (self.out_dir / RUN_FILE).write_text(json.dumps({"label": label}) + "\n")
            flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_APPEND
            self._metrics_fd = os.open(self.out_dir / "metrics.csv", flags, 0o644)
            _write_all(self._metrics_fd, csv_header())
        except OSError as exc:
            self._fail(exc)

    def add(self, t: float, positions: np.ndarray, headings: np.ndarray) -> None:
        """One sample: sim time [s], positions (N, 2) [m], headings (N,) [rad]."""
        self._pending.append((t, positions, headings))
        self.added += 1
        self.t_added = (t, t) if self.t_added is None else (self.t_added[0], t)
        if self._clock() - self._last_flush >= self.flush_every:
            self.flush()

    def add_from(
        self,
        times: Sequence[float],
        positions: Sequence[np.ndarray],
        headings: Sequence[np.ndarray],
        start: int,
        t_end: float,
    ) -> int:
        """:meth:`add` samples ``start``, ``start + 1``, … of growing sequences up to sim
        time ``t_end`` [s]; returns the index of the first sample not added."""
        k = start
        while k < len(times) and times[k] <= t_end:
            self.add(times[k], positions[k], headings[k])
            k += 1
        return k

    def end_gap(self, t_end: float) -> float:
        """How far [s] the samples added end before sim time ``t_end`` [s], when by more
        than 10 of their mean intervals (0 otherwise: they reach it, give or take a
        frame or two a camera dropped)."""
        if self.t_added is None or self.added < 2:
            return 0.0
        first, last = self.t_added
        interval = (last - first) / (self.added - 1)
        return t_end - last if t_end - last > 10 * interval else 0.0

    def flush(self) -> None:
        """Write the pending samples to ``trajectory.h5`` and commit them, then their
        metrics rows to ``metrics.csv``."""
        self._last_flush = self._clock()
        if self.error is not None or not self._pending:
            return
        if self._previous is None and len(self._pending) < 2:
            return  # the first row's angular velocity needs the second sample
        times = np.array([s[0] for s in self._pending], dtype=float)
        positions = np.stack([s[1] for s in self._pending])[None].astype(float)
        headings = np.stack([s[2] for s in self._pending])[None].astype(float)
        table = metrics_rows(times, positions, headings, self.scenario, self._previous)
        try:
            if self._trajectory is None:
                path = self.out_dir / TRAJECTORY_FILE
                self._trajectory = TrajectoryWriter(path, 1, positions.shape[2])
            self._trajectory.append(times, positions, headings)
            self._trajectory.commit()
            _write_all(self._metrics_fd, csv_rows(table))
        except (OSError, RuntimeError, ValueError) as exc:
            self._fail(exc)
            return
        self.written += len(times)
        self.t_written = float(times[-1])
        self._previous = Trajectory(times[-1:], positions[:, -1:], headings[:, -1:])
        self._pending = []

    def finish(self, scenario_file: Path | None = None) -> str:
        """Flush, close ``trajectory.h5`` and ``metrics.csv`` (both then complete), and
        draw the plots from the disk, in a child process given ``scenario_file`` (this
        run's scenario as a file). Returns the run's summary line ("" if nothing
        could be written, or the writer failed: then what is on disk stays for
        ``aes-swarm report``). After :meth:`start_drawing`, waits for its child."""
        if scenario_file is not None:
            self.start_drawing(Path(scenario_file))  # nothing if it was started before
        if self._drawing is not None:
            return self._drawn()
        self.flush()
        self._close()
        if self.error is not None or self.written < 2:
            return ""
        try:
            return finish_run_outputs(self.out_dir, self.scenario, self.label)
        except (OSError, RuntimeError) as exc:
            self._fail(exc)
            return ""

    def _drawn(self) -> str:
        """The summary line of :meth:`start_drawing`'s child, once it has exited."""
        assert self._drawing is not None
        out, err = self._drawing.communicate()
        code, self._drawing = self._drawing.returncode, None
        if code != 0:
            why = (err.strip().splitlines() or [f"exit code {code}"])[-1]
            self.error = f"cannot draw the outputs in {self.out_dir}: {why}"
            return ""
        return out.strip().splitlines()[-1] if out.strip() else ""

    def start_drawing(self, scenario_file: Path) -> None:
        """The first half of :meth:`finish` with ``scenario_file``: flush, close the files
        and start the child that draws the plots (``python -m aes_ros.report``), so that
        the caller can stop its processes meanwhile; :meth:`finish` then waits for it.
        The child is in a session of its own: a Ctrl-C at the terminal, meant for the
        caller, does not cut the drawing short."""
        self.flush()
        self._close()
        if self.error is not None or self.written < 2 or self._drawing is not None:
            return
        command = [sys.executable, "-m", "aes_ros.report", str(self.out_dir),
                   str(scenario_file), self.label]  # fmt: skip
        self._drawing = subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            start_new_session=True,
        )  # fmt: skip

    def _fail(self, exc: Exception) -> None:
        self.error = f"cannot write the outputs to {self.out_dir}: {error_reason(exc)}"
        if self._trajectory is not None:
            self._trajectory.abandon()  # as at its last commit; HDF5 must not retry
            self._trajectory = None
        self._close()

    def _close(self) -> None:
        if self._metrics_fd is not None:
            os.close(self._metrics_fd)
            self._metrics_fd = None
        if self._trajectory is not None:
            trajectory, self._trajectory = self._trajectory, None
            try:
                trajectory.close()
            except (OSError, RuntimeError) as exc:
                self._trajectory = trajectory
                self._fail(exc)


def _write_all(fd: int | None, data: bytes) -> None:
    """``os.write`` until every byte is written (a short write on a nearly full disk
    is followed by one that raises)."""
    if fd is None:
        raise OSError(f"{fd}: not open")
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]
