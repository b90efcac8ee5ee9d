"""helpers.machine_share: under ``pytest -n`` a test marked ``alone`` runs with no other
beside it, the others run together, and a waiting ``alone`` test goes before new ones."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import pytest
from helpers.machine_share import RUN_VARIABLE, machine_share


@pytest.fixture
def parallel_run(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(RUN_VARIABLE, uuid.uuid4().hex)


def hold(alone: bool, seconds: float, log: list[tuple[str, str]], name: str) -> threading.Thread:
    """A thread that holds its share for ``seconds`` and logs when it started and ended."""

    def run() -> None:
        with machine_share(alone):
            log.append(("start", name))
            time.sleep(seconds)
            log.append(("end", name))

    thread = threading.Thread(target=run)
    thread.start()
    return thread


@pytest.mark.parametrize(
    ("alone", "parallel"), [(False, True), (True, False)],
    ids=["shared tests under pytest -n", "any tests without it"],
)  # fmt: skip
def test_tests_run_together_when_they_may(
    alone: bool, parallel: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    if parallel:
        monkeypatch.setenv(RUN_VARIABLE, uuid.uuid4().hex)
    else:
        monkeypatch.delenv(RUN_VARIABLE, raising=False)
    log: list[tuple[str, str]] = []
    threads = [hold(alone, 0.3, log, "a"), hold(alone, 0.3, log, "b")]
    for thread in threads:
        thread.join()
    assert [event for event, _ in log] == ["start", "start", "end", "end"]


def test_an_alone_test_waits_for_the_running_ones_and_goes_before_new_ones(
    parallel_run: None,
) -> None:
    log: list[tuple[str, str]] = []
    first = hold(False, 0.4, log, "shared")
    time.sleep(0.1)
    alone = hold(True, 0.3, log, "alone")
    time.sleep(0.1)
    later = hold(False, 0.1, log, "later")  # arrives while the alone test waits
    for thread in (first, alone, later):
        thread.join()
    assert log == [
        ("start", "shared"), ("end", "shared"), ("start", "alone"), ("end", "alone"),
        ("start", "later"), ("end", "later"),
    ]  # fmt: skip


def test_an_alone_test_keeps_the_lock_for_the_next_alone_one(
    parallel_run: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The other worker (a process) waits through two alone tests in a row, not between."""
    tests = Path(__file__).resolve().parents[1]
    other_worker = [
        sys.executable, "-c",
        "from helpers.machine_share import machine_share\n"
        "with machine_share(False):\n    print('ran', flush=True)",
    ]  # fmt: skip
    env = {**os.environ, "PYTHONPATH": str(tests)}
    with machine_share(True, keep=True):
        pass
    other = subprocess.Popen(other_worker, env=env, stdout=subprocess.PIPE, text=True)
    try:
        time.sleep(1.0)
        assert other.poll() is None  # kept for the next alone test: the other one waits
        with machine_share(True, keep=False):
            assert other.poll() is None
        assert other.communicate(timeout=10)[0] == "ran\n"
    finally:
        other.kill()
        other.wait()
