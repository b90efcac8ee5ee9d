"""A run's outputs written while it goes, so that a crash loses at most a second or two.

``aes-swarm launch`` streams every pose sample into a :class:`RunWriter`:

- ``metrics.csv`` gets its rows (:data:`aes_ros.report.CSV_COLUMNS`, the same
  numbers :func:`aes_ros.report.metrics_table` gives for the whole run) appended
  as whole lines, one ``os.write`` per flush;
- the trajectory goes into ``trajectory.parts/part-NNNNNN.npz``, one file per
  flush, each written to a temporary name and renamed, so a part is either
  complete or absent;
- both are flushed at least every ``flush_every`` wall seconds (1 s).

:meth:`RunWriter.finish` then writes ``trajectory.npz`` and the plots
(:func:`aes_ros.report.write_run_outputs`) and removes the parts. After a crash
(even ``kill -9`` of the launcher) ``metrics.csv`` and the parts load with the
usual readers (:func:`aes_ros.report.load_trajectory` reads the parts), and
``aes-swarm report DIR`` (:func:`aes_ros.report.rebuild_run_outputs`) writes the
rest. A write that fails (disk full) stops the writer with :attr:`RunWriter.error`
set; what was written before stays readable.
"""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from aes_ros.report import (
    CSV_COLUMNS,
    PARTS_DIR,
    load_trajectory,
    metrics_table,
    write_run_outputs,
)
from aes_ros.scenario import Scenario

#: Wall seconds between flushes (at most what a crash can lose, plus one sample).
FLUSH_EVERY = 1.0
#: The run's description next to its outputs (the label of its plots and summary).
RUN_FILE = "run.json"


class RunWriter:
    """Streams the samples of one run into ``out_dir``.

    Parameters
    ----------
    out_dir : the run's output directory (created; old parts in it are removed).
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
        self._pending: list[tuple[float, np.ndarray, np.ndarray]] = []
        self._previous: tuple[float, np.ndarray, np.ndarray] | None = None
        self._part = 0
        self._last_flush = clock()
        self._metrics_fd: int | None = None
        try:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            shutil.rmtree(self.out_dir / PARTS_DIR, ignore_errors=True)
            (self.out_dir / PARTS_DIR).mkdir()
            (self.out_dir / RUN_FILE).write_text(json.dumps({"label": label}) + "\n")
            flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_APPEND
            self._metrics_fd = os.open(self.out_dir / "metrics.csv", flags, 0o644)
            os.write(self._metrics_fd, _csv_lines([CSV_COLUMNS]))
        except OSError as exc:
            self._fail(exc)

    def add(self, t: float, positions: np.ndarray, headings: np.ndarray) -> None:
        """One sample: sim time [s], positions (N, 2) [m], headings (N,) [rad]."""
        self._pending.append((t, positions, headings))
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

    def flush(self) -> None:
        """Write the pending samples (and their metrics rows) to disk."""
        self._last_flush = self._clock()
        if self.error is not None or not self._pending:
            return
        window = ([self._previous] if self._previous is not None else []) + self._pending
        if len(window) < 2:
            return  # the first row's angular velocity needs the second sample
        times = np.array([s[0] for s in window])
        positions = np.stack([s[1] for s in window])[None]
        headings = np.stack([s[2] for s in window])[None]
        table = metrics_table(times, positions, headings, self.scenario)
        first = 1 if self._previous is not None else 0
        rows = zip(*(table[c][first:] for c in CSV_COLUMNS), strict=True)
        try:
            part = self.out_dir / PARTS_DIR / f"part-{self._part:06d}.npz"
            temporary = part.with_name("." + part.name + ".tmp")
            with open(temporary, "wb") as fh:
                np.savez(
                    fh,
                    times=times[first:],
                    positions=positions[:, first:],
                    headings=headings[:, first:],
                )
            os.replace(temporary, part)
            os.write(self._metrics_fd, _csv_lines([f"{v:.6g}" for v in row] for row in rows))
        except OSError as exc:
            self._fail(exc)
            return
        self._part += 1
        self.written += len(self._pending)
        self.t_written = self._pending[-1][0]
        self._previous = self._pending[-1]
        self._pending = []

    def finish(self) -> str:
        """Flush, then write ``trajectory.npz``, the full ``metrics.csv`` and the plots
        and remove the parts. Returns the run's summary line ("" if nothing could
        be written, or the writer failed: then the parts stay for ``aes-swarm report``)."""
        self.flush()
        self._close()
        if self.error is not None or self.written < 2:
            return ""
        trajectory = load_trajectory(self.out_dir)
        try:
            summary = write_run_outputs(
                self.out_dir, trajectory.times, trajectory.positions, trajectory.headings,
                self.scenario, label=self.label,
            )  # fmt: skip
        except OSError as exc:
            self._fail(exc)
            return ""
        shutil.rmtree(self.out_dir / PARTS_DIR, ignore_errors=True)
        return summary

    def _fail(self, exc: OSError) -> None:
        self.error = f"cannot write the outputs to {self.out_dir}: {exc.strerror or exc}"
        self._close()

    def _close(self) -> None:
        if self._metrics_fd is not None:
            os.close(self._metrics_fd)
            self._metrics_fd = None


def _csv_lines(rows) -> bytes:
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerows(rows)
    return buffer.getvalue().encode()
