"""Tests share the machine when pytest runs them in parallel (``pytest -n 3 --dist
loadgroup``, pytest-xdist), except the ones marked ``alone``.

A test marked ``alone`` loads both cores or judges rates and recovery times (the soak,
the benchmarks' smoke runs, the camera pipeline, packet loss, killed processes): a test
beside it would change what it measures. Every other test holds a shared lock while it
runs, an ``alone`` test the exclusive one, over the whole test (fixtures included).
A turnstile gives the exclusive one precedence: once it waits, no other test starts.

The ``alone`` tests go to one worker, one after the other (the conftest gives them one
``xdist_group``), and that worker keeps the exclusive lock from one to the next: handing
it over between them would cost a wait for the other workers' tests every time.

Without pytest-xdist's workers (a plain ``pytest``) the tests run one after the other
and nothing is locked. The locks live in a directory of the temporary directory that
only this user may use (:func:`private_dir`): a name planted there by someone else is
refused, never followed.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

#: Set by pytest-xdist in its workers: one id per ``pytest -n`` run.
RUN_VARIABLE = "PYTEST_XDIST_TESTRUNUID"

#: The exclusive lock this process kept for its next ``alone`` test (the lock's file).
_kept: IO[str] | None = None


def lock_dir() -> Path | None:
    """The directory of this parallel run's locks (None: not a parallel run)."""
    run = os.environ.get(RUN_VARIABLE)
    if not run:
        return None
    return private_dir(Path(tempfile.gettempdir()) / f"aes_swarm_tests_{run}")


def private_dir(path: Path) -> Path:
    """``path``, made a directory of mode 0700 if absent (the workers of a run race for it);
    RuntimeError if it is anything but this user's directory of mode 0700 (a planted
    symbolic link, another user's directory)."""
    with contextlib.suppress(FileExistsError):
        path.mkdir(mode=0o700)
    info = os.lstat(path)
    if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid() or info.st_mode & 0o077:
        raise RuntimeError(
            f"{path}: not a directory of this user's with mode 0700 (a link or another "
            "user's?); the test locks are not taken there: remove it"
        )
    return path


def _take(where: Path, alone: bool) -> IO[str]:
    """The machine lock, shared or exclusive, taken through the turnstile."""
    machine = open(where / "machine", "w")
    with open(where / "turnstile", "w") as turnstile:
        fcntl.flock(turnstile, fcntl.LOCK_EX)
        try:
            # an exclusive one waits at the turnstile's far side: no new test passes it
            fcntl.flock(machine, fcntl.LOCK_EX if alone else fcntl.LOCK_SH)
        except BaseException:
            machine.close()
            raise
        finally:
            fcntl.flock(turnstile, fcntl.LOCK_UN)
    return machine


def release_kept() -> None:
    """Let go of an exclusive lock kept for a next ``alone`` test (there is none)."""
    global _kept
    if _kept is not None:
        _kept.close()  # closing the file releases its lock
        _kept = None


@contextlib.contextmanager
def machine_share(alone: bool, keep: bool = False) -> Iterator[None]:
    """Hold the machine for one test: shared, or exclusively if ``alone``; ``keep``: an
    ``alone`` test whose next test is ``alone`` too keeps the exclusive lock for it."""
    global _kept
    where = lock_dir()
    if where is None:
        yield
        return
    if not alone:
        release_kept()
    machine = _kept if alone and _kept is not None else _take(where, alone)
    _kept = None
    try:
        yield
    finally:
        if alone and keep:
            _kept = machine
        else:
            machine.close()
