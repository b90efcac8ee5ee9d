"""``trajectory.h5``: a run's samples in one appendable HDF5 file.

One layout whichever command wrote it (``aes-swarm simulate`` or ``launch``):

- ``times`` : (T,) float64 [s] (sim time for ``launch``);
- ``positions`` : (B, T, N, 2) float64 [m; odom];
- ``headings`` : (B, T, N) float64 [rad];
- ``n_samples`` : () int64, how many of the T samples are complete in all three;

with B the number of runs (``simulate --runs B``; 1 for ``launch``) and N the number
of robots. Each array has the attributes ``units`` and ``axes`` (``positions`` also
``frame``), is chunked along T (about :data:`CHUNK_BYTES` a chunk) and resizable
along T (``maxshape`` None).

Crash safety. The file is written with SWMR (single writer, multiple readers:
``libver='latest'``, ``swmr_mode = True`` once the datasets exist), under which HDF5
writes its metadata in an order that keeps the file on disk valid at every moment.
:meth:`TrajectoryWriter.commit` flushes the samples, then writes ``n_samples`` and
flushes again, so the first ``n_samples`` samples on disk are complete whatever
happens next (the arrays may be longer: read no further). A writer killed with
SIGKILL leaves a file that reads back up to its last commit
(``tests/unit/test_run_writer.py`` kills one to check). That file is still flagged
"open for write": HDF5 opens it only with ``swmr=True`` (what :func:`open_trajectory`
does), until :func:`seal` (``aes-swarm report DIR``) rewrites it closed for every
other reader. A write that fails (disk full) leaves the file as at its last commit.

Why HDF5 and not Zarr: one file instead of a directory of chunk files; read
natively by MATLAB (``h5read``, dimensions reversed: positions as 2 x N x T x B),
h5py, HDFView, Julia and R (pandas through h5py: ``read_hdf`` wants PyTables'
layout); SWMR keeps it valid after a crash.
"""

from __future__ import annotations

import contextlib
import os
import re
from collections.abc import Iterator
from pathlib import Path

import h5py
import numpy as np

#: The trajectory's file name in a run directory.
FILE_NAME = "trajectory.h5"
#: Bytes of one chunk of ``positions`` (``headings`` half of that): small enough for
#: a nearly full disk, large enough that an hour of 100 robots is some 10^4 chunks.
CHUNK_BYTES = 32 * 1024
#: The writer's chunk cache per dataset [bytes]: the chunks being appended to.
WRITE_CACHE_BYTES = 4 * CHUNK_BYTES
#: Bytes of positions read at once by :meth:`TrajectoryFile.blocks`.
BLOCK_BYTES = 2 * 1024 * 1024

_ATTRS = {
    "times": {"units": "s", "axes": "T"},
    "positions": {"units": "m", "axes": "B, T, N, xy", "frame": "odom"},
    "headings": {"units": "rad", "axes": "B, T, N"},
    "n_samples": {"units": "1", "axes": "", "meaning": "samples complete in every array"},
}


class TrajectoryWriter:
    """Appends samples to a new ``trajectory.h5`` (SWMR; see the module docstring).

    Parameters
    ----------
    path : the file (replaced if it exists).
    runs : B, the number of runs.
    robots : N, the number of robots.

    Notes
    -----
    After a write error (OSError or RuntimeError from h5py) call :meth:`abandon`,
    never :meth:`close`: an HDF5 file whose flush failed makes the interpreter crash
    at exit once closed the usual way (h5py issue #914).
    """

    def __init__(self, path: Path, runs: int, robots: int) -> None:
        self.path = Path(path)
        self.runs, self.robots = int(runs), int(robots)
        #: Samples appended, and samples committed (``n_samples`` on disk).
        self.appended = 0
        self.committed = 0
        # a small chunk cache: appending needs only the last chunks, and HDF5's default
        # cache grows with the file (docs/reliability.md#runs-of-hours)
        self._file: h5py.File | None = h5py.File(
            self.path, "w", libver="latest", rdcc_nbytes=WRITE_CACHE_BYTES
        )
        self._fd = self._file.id.get_vfd_handle()
        # every handle held open until the file closes: a handle dropped after a failed
        # write would close (flush) again where no exception reaches us, and crash
        self._datasets: dict[str, h5py.Dataset] = {}
        try:
            block = max(1, CHUNK_BYTES // (self.runs * self.robots * 2 * 8))  # samples a chunk
            trailing = {"times": (), "positions": (self.robots, 2), "headings": (self.robots,)}
            for name, rest in trailing.items():
                lead = () if name == "times" else (self.runs,)
                chunk_t = max(block, 1024) if name == "times" else block
                self._datasets[name] = self._file.create_dataset(
                    name,
                    shape=(*lead, 0, *rest),
                    maxshape=(*lead, None, *rest),
                    chunks=(*lead, chunk_t, *rest),
                    dtype="f8",
                )
            self._datasets["n_samples"] = self._file.create_dataset("n_samples", data=np.int64(0))
            for name, attrs in _ATTRS.items():
                self._datasets[name].attrs.update(attrs)
            self._file.swmr_mode = True
        except (OSError, RuntimeError):
            self.abandon()
            raise

    def append(self, times: np.ndarray, positions: np.ndarray, headings: np.ndarray) -> None:
        """Samples at the end: times (k,) [s], positions (B, k, N, 2) [m], headings
        (B, k, N) [rad]. On disk only once :meth:`commit` has run."""
        times = np.asarray(times, dtype=float)
        positions = np.asarray(positions, dtype=float)
        headings = np.asarray(headings, dtype=float)
        want = (self.runs, len(times), self.robots)
        if positions.shape != (*want, 2) or headings.shape != want:
            raise ValueError(
                f"positions {positions.shape}, headings {headings.shape}: need {(*want, 2)}, {want}"
            )
        a, b = self.appended, self.appended + len(times)
        self._open()
        for name, data in (("times", times), ("positions", positions), ("headings", headings)):
            dataset = self._datasets[name]
            if name == "times":
                dataset.resize(b, axis=0)
                dataset[a:b] = data
            else:
                dataset.resize(b, axis=1)
                dataset[:, a:b] = data
        self.appended = b

    def commit(self) -> None:
        """Make every appended sample readable after a crash: flush them, then write
        ``n_samples`` and flush again."""
        f = self._open()
        f.flush()
        self._datasets["n_samples"][()] = self.appended
        f.flush()
        self.committed = self.appended

    def close(self) -> None:
        """Commit and close: the file is then an ordinary HDF5 file for every reader."""
        if self._file is None:
            return
        self.commit()
        self._datasets = {}
        self._file.close()
        self._file = None

    def abandon(self) -> None:
        """Close after a write error, leaving the file as at its last commit: the
        descriptor is pointed at /dev/null first, so HDF5's closing writes go nowhere
        and cannot fail again (a failed close crashes the interpreter at exit)."""
        if self._file is None:
            return
        with contextlib.suppress(OSError):
            null = os.open(os.devnull, os.O_RDWR)
            os.dup2(null, self._fd)
            os.close(null)
        with contextlib.suppress(Exception):
            self._file.close()
        self._datasets = {}
        self._file = None

    def _open(self) -> h5py.File:
        if self._file is None:
            raise ValueError(f"{self.path}: the writer is closed")
        return self._file


def write_trajectory(
    path: Path, times: np.ndarray, positions: np.ndarray, headings: np.ndarray
) -> None:
    """A whole trajectory to ``path``: times (T,) [s], positions (B, T, N, 2) [m],
    headings (B, T, N) [rad]. Written under a temporary name and renamed, so the file
    is either complete or absent."""
    path = Path(path)
    positions = np.asarray(positions, dtype=float)
    temporary = path.with_name("." + path.name + ".tmp")
    writer = TrajectoryWriter(temporary, positions.shape[0], positions.shape[2])
    try:
        writer.append(times, positions, headings)
        writer.close()
        os.replace(temporary, path)
    except BaseException:
        writer.abandon()
        temporary.unlink(missing_ok=True)
        raise


def trajectory_path(path: Path) -> Path:
    """``path`` itself, or ``path/trajectory.h5`` if ``path`` is a directory."""
    path = Path(path)
    return path / FILE_NAME if path.is_dir() else path


class TrajectoryFile:
    """A ``trajectory.h5`` open for reading: its first :attr:`n_samples` samples.

    Parameters
    ----------
    h5 : the open file (closed, being written, or as a crashed writer left it).
    """

    def __init__(self, h5: h5py.File) -> None:
        self.h5 = h5
        self._times, self._positions, self._headings = h5["times"], h5["positions"], h5["headings"]
        extent = min(len(self._times), self._positions.shape[1], self._headings.shape[1])
        committed = int(h5["n_samples"][()]) if "n_samples" in h5 else extent
        #: T: samples complete on disk.
        self.n_samples = min(committed, extent)
        #: B and N.
        self.runs, self.robots = self._positions.shape[0], self._positions.shape[2]

    @property
    def nbytes(self) -> int:
        """Bytes of the whole trajectory in memory (float64 times, positions, headings)."""
        return 8 * self.n_samples * (1 + 3 * self.runs * self.robots)

    def read(
        self, samples: slice | np.ndarray, run: int | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Samples by a slice (step > 0) or increasing indices, all runs (positions
        (B, k, N, 2), headings (B, k, N)) or one (``run``: (k, N, 2), (k, N)), and their
        times (k,) [s]. Never beyond :attr:`n_samples`."""
        if isinstance(samples, slice):
            start, stop, step = samples.indices(self.n_samples)
            if step < 1:
                raise ValueError(f"slice step {step}: need a positive step")
            samples = slice(start, max(start, stop), step)
        else:
            samples = np.asarray(samples, dtype=np.int64).reshape(-1)
            if samples.size == 0:
                samples = slice(0, 0)
            elif samples[0] < 0 or samples[-1] >= self.n_samples or np.any(np.diff(samples) <= 0):
                raise IndexError(f"sample indices must increase within [0, {self.n_samples})")
        runs = slice(None) if run is None else run
        return (
            self._times[samples],
            self._positions[runs, samples],
            self._headings[runs, samples],
        )

    def blocks(
        self, run: int | None = None, max_bytes: int = BLOCK_BYTES
    ) -> Iterator[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
        """The samples in order, a few at a time: (index of the first, times, positions,
        headings) as :meth:`read` gives them, at least two samples and at most about
        ``max_bytes`` of positions per block (the last block may hold one)."""
        runs = self.runs if run is None else 1
        size = max(2, max_bytes // (runs * self.robots * 2 * 8))
        for start in range(0, self.n_samples, size):
            yield (start, *self.read(slice(start, start + size), run))


@contextlib.contextmanager
def open_trajectory(path: Path) -> Iterator[TrajectoryFile]:
    """Open ``trajectory.h5`` (a file, or a run directory holding one) for reading,
    whatever state its writer left it in (with ``swmr=True``, which also reads a file
    being written or left by a crash)."""
    file = trajectory_path(path)
    if not file.exists():
        raise FileNotFoundError(f"{file}: no such trajectory")
    with h5py.File(file, "r", swmr=True) as h5:
        yield TrajectoryFile(h5)


def is_sealed(path: Path) -> bool:
    """Whether any HDF5 reader opens the file (False while its writer has it open, or
    after the writer crashed)."""
    try:
        h5py.File(trajectory_path(path), "r").close()
    except OSError:
        return False
    return True


def seal(path: Path) -> bool:
    """Rewrite a trajectory its writer left open (a crash) as a closed file holding its
    complete samples, block by block (memory bounded by :data:`BLOCK_BYTES`), under a
    temporary name then renamed. Returns whether it had to."""
    file = trajectory_path(path)
    if is_sealed(file):
        return False
    temporary = file.with_name("." + file.name + ".tmp")
    with open_trajectory(file) as source:
        writer = TrajectoryWriter(temporary, source.runs, source.robots)
        try:
            for _, times, positions, headings in source.blocks():
                writer.append(times, positions, headings)
            writer.close()
        except BaseException:
            writer.abandon()
            temporary.unlink(missing_ok=True)
            raise
    os.replace(temporary, file)
    return True


def error_reason(exc: BaseException) -> str:
    """The system's words for a failed write (h5py's message holds them as
    ``error message = '…'``), else the exception's own."""
    found = re.search(r"error message = '([^']*)'", str(exc))
    if found:
        return found.group(1)
    return getattr(exc, "strerror", None) or str(exc)
