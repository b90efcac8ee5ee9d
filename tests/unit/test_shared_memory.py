"""Which Fast DDS port files a clean removes: real files, locks and mappings in a
directory of /dev/shm standing in for Fast DDS's (no DDS involved)."""

from __future__ import annotations

import fcntl
import mmap
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from aes_ros.ros.launch import shared_memory

DOMAIN = 3
#: Ports of DOMAIN (7400 + 250 * 3 = 8150 + offset) and one every domain shares.
ALIVE, GONE, HELD, SHARED = 8161, 8163, 8165, 7002
OTHER_DOMAIN = 7400 + 250 * 5 + 11
#: A peer that maps a segment and lets go 0.3 s after its stdin closes (as Fast DDS
#: does after a goodbye).
PEER = """
import mmap, sys, time
with open(sys.argv[1], "r+b") as f:
    segment = mmap.mmap(f.fileno(), 0)
print("mapped", flush=True)
sys.stdin.read()
time.sleep(0.3)
"""


@pytest.fixture
def shm_dir(monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    path = Path("/dev/shm") / f"aes-test-shm-{os.getpid()}"
    path.mkdir()
    monkeypatch.setattr(shared_memory, "SHM_DIR", path)
    monkeypatch.setattr(shared_memory, "YOUNG", 0.0)  # the files made here count as old
    yield path
    shutil.rmtree(path)


def make_port(directory: Path, port: int) -> dict[str, Path]:
    """A port's three files, as Fast DDS names them."""
    files = {
        "segment": directory / f"fastrtps_port{port}",
        "lock": directory / f"fastrtps_port{port}_el",
        "mutex": directory / f"sem.fastrtps_port{port}_mutex",
    }
    for path in files.values():
        path.write_bytes(b"\0" * mmap.PAGESIZE)
    return files


def test_only_files_of_gone_listeners_nobody_maps_are_removed(shm_dir: Path) -> None:
    ports = {p: make_port(shm_dir, p) for p in (ALIVE, GONE, HELD, SHARED, OTHER_DOMAIN)}
    listener = os.open(ports[ALIVE]["lock"], os.O_RDWR)
    fcntl.flock(listener, fcntl.LOCK_EX | fcntl.LOCK_NB)  # ALIVE's listener lives
    with open(ports[HELD]["segment"], "r+b") as f:
        peer = mmap.mmap(f.fileno(), 0)  # a live peer still maps HELD's segment
    try:
        _, held = shared_memory.abandoned_ports(DOMAIN)
        assert held == [HELD]
        shared_memory.clean_shared_memory(DOMAIN, settle=0.0)
        left = {p.name for p in shm_dir.iterdir()}
        assert {p.name for p in ports[ALIVE].values()} <= left  # a live listener's
        assert {p.name for p in ports[OTHER_DOMAIN].values()} <= left  # another domain's
        assert not {p.name for p in [*ports[GONE].values(), *ports[SHARED].values()]} & left
        assert left & {p.name for p in ports[HELD].values()} == {ports[HELD]["segment"].name}
    finally:
        peer.close()
        os.close(listener)
    shared_memory.clean_shared_memory(DOMAIN, settle=0.0)  # the peer let go; ALIVE's too
    assert {p.name for p in shm_dir.iterdir()} == {p.name for p in ports[OTHER_DOMAIN].values()}


def test_a_clean_waits_for_a_peer_to_let_go(shm_dir: Path) -> None:
    files = make_port(shm_dir, HELD)
    peer = subprocess.Popen(
        [sys.executable, "-c", PEER, str(files["segment"])],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert peer.stdin is not None and peer.stdout is not None
    assert peer.stdout.readline() == "mapped\n"
    shared_memory.clean_shared_memory(DOMAIN, settle=0.0)
    assert files["segment"].exists()  # not while the peer maps it
    peer.stdin.close()  # the peer lets go 0.3 s from now
    shared_memory.clean_shared_memory(DOMAIN, settle=10.0)
    assert peer.wait(10) == 0
    assert list(shm_dir.iterdir()) == []


def test_a_port_made_while_the_clean_looks_at_proc_is_left_alone(
    shm_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A participant that starts while a clean reads the mappings: its new port is in no
    snapshot of locks or mappings, and must not be taken for abandoned (seen in CI: a
    test's probe lost its port to another test's clean and never heard a message)."""
    gone = make_port(shm_dir, GONE)
    started: dict[str, object] = {}
    read_mappings = shared_memory.mapped_files

    def mappings_then_a_participant_starts() -> set[str]:
        seen = read_mappings()
        if not started:
            files = make_port(shm_dir, SHARED)
            started["listener"] = os.open(files["lock"], os.O_RDWR)
            fcntl.flock(started["listener"], fcntl.LOCK_EX | fcntl.LOCK_NB)
            with open(files["segment"], "r+b") as f:
                started["segment"] = mmap.mmap(f.fileno(), 0)
        return seen

    monkeypatch.setattr(shared_memory, "mapped_files", mappings_then_a_participant_starts)
    try:
        shared_memory.clean_shared_memory(DOMAIN, settle=0.0)
        left = {p.name for p in shm_dir.iterdir()}
        assert left == {f"fastrtps_port{SHARED}", f"fastrtps_port{SHARED}_el",
                        f"sem.fastrtps_port{SHARED}_mutex"}  # fmt: skip
        assert not {p.name for p in gone.values()} & left
    finally:
        started["segment"].close()  # type: ignore[attr-defined]
        os.close(started["listener"])  # type: ignore[arg-type]


def test_young_files_wait_for_a_later_pass(shm_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Port files neither locked nor mapped yet, made less than YOUNG s ago (their maker
    may be about to lock and map them), stay; the clean waits for them within its
    settle time, and removes them once they are older and still abandoned."""
    monkeypatch.setattr(shared_memory, "YOUNG", 0.5)
    files = make_port(shm_dir, GONE)
    removable, held = shared_memory.abandoned_ports(DOMAIN)
    assert (removable, held) == ([], [GONE])
    shared_memory.clean_shared_memory(DOMAIN, settle=0.0)
    assert all(path.exists() for path in files.values())
    shared_memory.clean_shared_memory(DOMAIN, settle=5.0)
    assert list(shm_dir.iterdir()) == []
