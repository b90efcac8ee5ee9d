"""Tests share the machine when pytest runs them in parallel (``pytest -n 2``,
pytest-xdist), except the ones marked ``alone``.

A test marked ``alone`` loads both cores or judges rates and recovery times (the soak,
the benchmarks' smoke runs, the camera pipeline, packet loss, killed processes): a test
beside it would change what it measures. Every other test holds a shared lock while it
runs, an ``alone`` test the exclusive one, over the whole test (fixtures included).
A turnstile gives the exclusive one precedence: once it waits, no other test starts.

Without pytest-xdist's workers (a plain ``pytest``) the tests run one after the other
and nothing is locked.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

#: Set by pytest-xdist in its workers: one id per ``pytest -n`` run.
RUN_VARIABLE = "PYTEST_XDIST_TESTRUNUID"


def lock_dir() -> Path | None:
    """The directory of this parallel run's locks (None: not a parallel run)."""
    run = os.environ.get(RUN_VARIABLE)
    if not run:
        return None
    path = Path(tempfile.gettempdir()) / f"aes_swarm_tests_{run}"
    path.mkdir(exist_ok=True)
    return path


@contextlib.contextmanager
def machine_share(alone: bool) -> Iterator[None]:
    """Hold the machine for one test: shared, or exclusively if ``alone``."""
    where = lock_dir()
    if where is None:
        yield
        return
    with open(where / "turnstile", "w") as turnstile, open(where / "machine", "w") as machine:
        fcntl.flock(turnstile, fcntl.LOCK_EX)
        try:
            # an exclusive one waits at the turnstile's far side: no new test passes it
            fcntl.flock(machine, fcntl.LOCK_EX if alone else fcntl.LOCK_SH)
        finally:
            fcntl.flock(turnstile, fcntl.LOCK_UN)
        try:
            yield
        finally:
            fcntl.flock(machine, fcntl.LOCK_UN)
