"""Which Fast DDS files a clean removes: real files, locks, mappings, owners and
symlinks in a directory of /dev/shm standing in for Fast DDS's (no DDS involved)."""

from __future__ import annotations

import fcntl
import mmap
import os
import shutil
import subprocess
import sys
import threading
import time
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
        assert shared_memory.abandoned_ports(DOMAIN) == ([SHARED, GONE], [HELD])
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


def test_a_listener_that_starts_after_the_listing_keeps_its_port(
    shm_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A participant that takes up a listed port (locks and maps it) between the clean's
    listing and its look at that port: the port is live, only GONE's files go."""
    gone = make_port(shm_dir, GONE)
    taken = make_port(shm_dir, SHARED)
    started: dict[str, object] = {}
    list_ports = shared_memory.domain_port_files

    def listing_then_a_participant_starts(domain: int) -> dict[int, list[Path]]:
        ports = list_ports(domain)
        started["listener"] = os.open(taken["lock"], os.O_RDWR)
        fcntl.flock(started["listener"], fcntl.LOCK_EX | fcntl.LOCK_NB)
        with open(taken["segment"], "r+b") as f:
            started["segment"] = mmap.mmap(f.fileno(), 0)
        return ports

    monkeypatch.setattr(shared_memory, "domain_port_files", listing_then_a_participant_starts)
    try:
        shared_memory.clean_shared_memory(DOMAIN, settle=0.0)
        left = {p.name for p in shm_dir.iterdir()}
        assert left == {p.name for p in taken.values()}
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
    assert shared_memory.abandoned_ports(DOMAIN) == ([], [GONE])
    shared_memory.clean_shared_memory(DOMAIN, settle=0.0)
    assert all(path.exists() for path in files.values())
    shared_memory.clean_shared_memory(DOMAIN, settle=5.0)
    assert list(shm_dir.iterdir()) == []


def test_a_lingering_clean_removes_a_port_made_again_meanwhile(shm_dir: Path) -> None:
    """A live peer makes a killed participant's port again when it next sends to it, a
    few seconds after the clean that removed it: a clean that lingers removes it again;
    one that ends at once leaves it."""
    make_port(shm_dir, GONE)
    again = threading.Timer(0.5, make_port, (shm_dir, GONE))
    again.start()
    shared_memory.clean_shared_memory(DOMAIN, settle=0.0)  # ends at once
    again.join()
    assert len(list(shm_dir.iterdir())) == 3  # made again after the clean
    shared_memory.clean_shared_memory(DOMAIN, settle=0.0)
    again = threading.Timer(0.5, make_port, (shm_dir, GONE))
    again.start()
    start = time.monotonic()
    shared_memory.clean_shared_memory(DOMAIN, settle=10.0, linger=1.5)
    assert 1.5 <= time.monotonic() - start < 5.0
    again.join()
    assert list(shm_dir.iterdir()) == []


def make_segment(directory: Path, name: str) -> dict[str, Path]:
    """A participant's data segment and its lock file, as Fast DDS names them."""
    files = {"segment": directory / f"fastrtps_{name}", "lock": directory / f"fastrtps_{name}_el"}
    for path in files.values():
        path.write_bytes(b"\0" * mmap.PAGESIZE)
    return files


def test_segments_go_with_their_owner_also_while_a_reader_maps_them(shm_dir: Path) -> None:
    live = make_segment(shm_dir, "0123456789abcdef")
    dead = make_segment(shm_dir, "fedcba9876543210")
    read = make_segment(shm_dir, "00000000deadbeef")
    owner = os.open(live["lock"], os.O_RDONLY)
    fcntl.flock(owner, fcntl.LOCK_EX | fcntl.LOCK_NB)
    with open(read["segment"], "r+b") as f:
        reader = mmap.mmap(f.fileno(), 0)  # a reader of a writer that is gone
    try:
        shared_memory.clean_shared_memory(settle=0.0)
        assert {p.name for p in shm_dir.iterdir()} == {p.name for p in live.values()}
        assert reader[:4] == b"\0\0\0\0"  # the reader keeps its mapping
    finally:
        reader.close()
        os.close(owner)
    assert not any(path.exists() for path in dead.values())


@pytest.mark.skipif(os.geteuid() != 0, reason="chown to another user needs root")
def test_files_of_another_user_are_not_touched(shm_dir: Path) -> None:
    """Abandoned-looking port and segment files of uid 65534 (no lock, nobody maps
    them): theirs to clean, not this user's; root's clean leaves them."""
    files = [
        *make_port(shm_dir, GONE).values(),
        *make_segment(shm_dir, "0123456789abcdef").values(),
    ]
    for path in files:
        os.chown(path, 65534, 65534)
    shared_memory.clean_shared_memory(DOMAIN, settle=0.0)
    assert all(path.exists() for path in files)


def test_a_symlink_is_neither_followed_nor_removed(shm_dir: Path, tmp_path: Path) -> None:
    """Port files planted as symlinks to files of this user: the clean removes neither
    them nor what they point to, and leaves their ports alone."""
    target = tmp_path / "precious"
    target.write_bytes(b"data")
    files = make_port(shm_dir, GONE)
    files["segment"].unlink()
    files["segment"].symlink_to(target)
    lock_target = tmp_path / "precious_lock"
    lock_target.write_bytes(b"")
    (shm_dir / f"fastrtps_port{SHARED}_el").symlink_to(lock_target)
    shared_memory.clean_shared_memory(DOMAIN, settle=0.0)
    assert target.read_bytes() == b"data" and lock_target.exists()
    assert all(path.is_symlink() or path.exists() for path in files.values())
    assert (shm_dir / f"fastrtps_port{SHARED}_el").is_symlink()
