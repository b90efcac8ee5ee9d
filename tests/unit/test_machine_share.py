"""helpers.machine_share: under ``pytest -n`` a test marked ``alone`` runs with no other
beside it, the others run together, and a waiting ``alone`` test goes before new ones."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from pathlib import Path

import pytest
from helpers.machine_share import RUN_VARIABLE, lock_dir, machine_share


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


@pytest.mark.parametrize("planted", ["link", "open dir"])
def test_a_lock_directory_planted_in_the_temporary_directory_is_refused(
    planted: str, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """Someone who guesses the lock directory's name and puts a link (to a directory of
    the victim's) or a directory anyone may write there first: the locks are not taken
    through it, and nothing is created where the link points."""
    run = uuid.uuid4().hex
    monkeypatch.setenv(RUN_VARIABLE, run)
    target = tmp_path / "victim"
    target.mkdir()
    where = Path(tempfile.gettempdir()) / f"aes_swarm_tests_{run}"
    if planted == "link":
        where.symlink_to(target)
    else:
        where.mkdir()
        where.chmod(0o777)
    try:
        with pytest.raises(RuntimeError, match="mode 0700"), machine_share(False):
            pass
        assert list(target.iterdir()) == [] and sorted(os.listdir(where)) == []
    finally:
        where.unlink() if where.is_symlink() else where.rmdir()


def test_the_lock_directory_is_this_users_alone(parallel_run: None) -> None:
    with machine_share(False):
        pass
    info = os.lstat(lock_dir())
    assert stat.S_ISDIR(info.st_mode) and info.st_uid == os.getuid()
    assert stat.S_IMODE(info.st_mode) == 0o700


def test_the_alone_tests_run_on_one_worker_in_one_row(tmp_path: Path) -> None:
    """Under ``pytest -n N --dist loadgroup`` (the README's N = 3; 2 here) the tests marked
    ``alone`` are one worker's, one after the other: a pytest that stops grouping them (9.2
    with xdist 3.8) spreads them over the workers, each waiting for the others'."""
    ours = Path(__file__).parents[1]  # this project's tests/: its conftest and helpers
    tests = tmp_path / "tests"
    tests.mkdir()
    (tests / "conftest.py").write_text((ours / "conftest.py").read_text())
    (tmp_path / "pyproject.toml").write_text(
        '[tool.pytest.ini_options]\nmarkers = ["alone: runs with no other test beside it"]\n'
    )
    log = tmp_path / "log"
    for module in "abc":
        (tests / f"test_{module}.py").write_text(
            "import os, time, pytest\n"
            "def ran(name, alone=''):\n"
            f"    with open({str(log)!r}, 'a') as f:\n"
            "        f.write(f\"{os.environ['PYTEST_XDIST_WORKER']} {name} {alone}\\n\")\n"
            "    time.sleep(0.2)\n"
            f"def test_{module}1(): ran('{module}1')\n"
            "@pytest.mark.alone\n"
            f"def test_{module}2(): ran('{module}2', 'alone')\n"
            f"def test_{module}3(): ran('{module}3')\n"
            "@pytest.mark.alone\n"
            f"def test_{module}4(): ran('{module}4', 'alone')\n"
        )
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")}
    env["PYTHONPATH"] = str(ours)
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-n", "2", "--dist", "loadgroup",
         "-p", "no:cacheprovider", str(tests)],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert run.returncode == 0, run.stdout + run.stderr
    lines = [line.split() for line in log.read_text().splitlines()]
    alone = [worker for worker, *rest in lines if rest[1:] == ["alone"]]
    assert len(alone) == 6 and len(set(alone)) == 1, lines  # one worker's
    own = [rest[1:] == ["alone"] for worker, *rest in lines if worker == alone[0]]
    first = own.index(True)
    assert own[first : first + 6] == [True] * 6, lines  # in one row
