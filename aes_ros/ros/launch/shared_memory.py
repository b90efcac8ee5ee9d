"""Fast DDS's shared-memory files (/dev/shm) left behind by processes that are gone.

Fast DDS's shared-memory transport keeps a data *segment* per participant,
``fastrtps_<16 hex digits>`` with its owner's lock file ``…_el``, and a *port* per
listening locator: the segment ``fastrtps_port<N>`` (N = DDS port, 7400 + 250 · domain
+ offset, or 7000 + participant index, which every domain of the machine shares), its
listener's lock file ``fastrtps_port<N>_el`` (``_sl`` for a port several listeners
read) and a semaphore ``sem.fastrtps_port<N>_mutex``. A live owner or listener holds
an ``flock`` on the lock file; every process that maps a segment has it open for
writing. The listener removes its port when it shuts down, but not while another
process still maps the segment; the last peer to let go usually removes it then, but
processes that stop together (or are killed) leave files that nobody removes.

:func:`clean_shared_memory` removes, of the current user's files only:

- segments whose lock nobody holds;
- with a ROS domain, that domain's ports whose lock nobody holds and whose files no
  process maps. A peer that outlives a port's listener (a ``ros2 topic echo``, a
  test's probe) lets go of it about 0.3 s after the listener said goodbye, so the
  clean waits up to ``settle`` seconds for such ports.

Both tests ask the kernel, so they see the processes of every PID namespace and user
that share ``/dev/shm`` (a container, another user's swarm), which ``/proc`` does not:
a non-blocking ``flock`` (Fast DDS's own lock type: a lock that can be taken is
nobody's; it is held while the port's files are removed, so no listener takes it
meanwhile) and a read lease (``F_SETLEASE``), which the kernel refuses while any
process has the file open for writing, a mapping included. A file is opened with
``O_NOFOLLOW`` and must be a regular file of the current user: a symlink, or a file of
another user, is never opened, locked or removed.

A participant starting beside a clean makes its port files one by one, and maps and
locks them a moment after: the clean leaves files younger than :data:`YOUNG` seconds
alone for this pass. Ports below 7400 belong to participants of every domain, so a
clean of one domain runs beside the starts of the others.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import re
import signal
import stat
import time
from collections.abc import Iterator
from pathlib import Path

#: Where Fast DDS keeps its shared-memory files (Linux).
SHM_DIR = Path("/dev/shm")
_PORT_FILE = re.compile(r"(?:sem\.)?fastrtps_port(\d+)(?:_el|_sl|_mutex)?")
_SEGMENT_FILE = re.compile(r"fastrtps_([0-9a-z]{16})(?:_el|_sl)?")
_LOCK_SUFFIXES = ("_el", "_sl")
#: Seconds a file is left alone after it was made: its maker may not have mapped or
#: locked it yet (a loaded machine preempts a starting participant for that long).
YOUNG = 1.0
#: The signal a broken lease would send (a process opening the file for writing in
#: the microseconds the clean holds one): SIGURG, ignored unless handled, instead of
#: SIGIO, which ends a process.
_LEASE_SIGNAL = signal.SIGURG


def domain_port_files(domain: int) -> dict[int, list[Path]]:
    """The port files of ``domain`` by port: ports 7400 + 250 · domain + [0, 250), and
    those below the first domain's (7400), which every participant of the machine shares."""
    low = 7400 + 250 * domain
    ports: dict[int, list[Path]] = {}
    for path in SHM_DIR.glob("*fastrtps_port*"):
        if (m := _PORT_FILE.fullmatch(path.name)) is None:
            continue
        port = int(m.group(1))
        if port < 7400 or low <= port < low + 250:
            ports.setdefault(port, []).append(path)
    return ports


def segment_files() -> dict[str, list[Path]]:
    """The participants' data segments' files (segment and lock file) by segment name."""
    segments: dict[str, list[Path]] = {}
    for path in SHM_DIR.glob("fastrtps_*"):
        if (m := _SEGMENT_FILE.fullmatch(path.name)) is not None:
            segments.setdefault(m.group(1), []).append(path)
    return segments


def _own(info: os.stat_result) -> bool:
    return stat.S_ISREG(info.st_mode) and info.st_uid == os.geteuid()


def owned(path: Path) -> bool:
    """True if ``path`` itself (not what a symlink points to) is a regular file of the
    current user."""
    try:
        return _own(os.lstat(path))
    except OSError:
        return False


@contextlib.contextmanager
def _opened(path: Path) -> Iterator[int | None]:
    """A read-only descriptor of ``path`` if it is a regular file of the current user
    (never through a symlink, never blocking on a planted FIFO), else None."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError:  # gone, a symlink, or not ours to open
        yield None
        return
    try:
        yield fd if _own(os.fstat(fd)) else None
    finally:
        os.close(fd)


def _lock(fd: int) -> bool:
    """Take an exclusive ``flock`` on ``fd`` if nobody holds one (released with ``fd``)."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    return True


def in_use(fd: int) -> bool:
    """True if some process, in any PID namespace, has the file of ``fd`` open for
    writing (maps it); False also where the kernel grants no leases (then only the
    locks decide)."""
    try:
        fcntl.fcntl(fd, fcntl.F_SETSIG, _LEASE_SIGNAL)
        fcntl.fcntl(fd, fcntl.F_SETLEASE, fcntl.F_RDLCK)
    except OSError as err:
        return err.errno in (errno.EAGAIN, errno.EBUSY)
    fcntl.fcntl(fd, fcntl.F_SETLEASE, fcntl.F_UNLCK)
    return False


def _mapped(path: Path, fd: int) -> bool:
    return not path.name.endswith(_LOCK_SUFFIXES) and in_use(fd)


def mapped(path: Path) -> bool:
    """True if ``path`` is a file of the current user that some live process maps."""
    with _opened(path) as fd:
        return fd is not None and _mapped(path, fd)


def locked(path: Path) -> bool:
    """True if ``path`` is a file of the current user that some live process holds a
    lock on."""
    with _opened(path) as fd:
        return fd is not None and not _lock(fd)


def _young(fd: int, since: float) -> bool:
    return os.fstat(fd).st_ctime > since


def _unlink_if_same(path: Path, fd: int) -> None:
    """Remove ``path`` if it is still the file of ``fd``."""
    with contextlib.suppress(OSError):
        if os.path.samestat(os.lstat(path), os.fstat(fd)):
            path.unlink()


#: What a pass makes of a group of files: not the current user's, its lock held, to
#: wait for (young, or a peer maps a port's file), removed.
FOREIGN, LIVE, WAIT, REMOVED = "foreign", "live", "wait", "removed"


def _judge(files: list[Path], young_since: float, *, mapped_waits: bool, remove: bool) -> str:
    """Decide on (and with ``remove``, remove) one segment's or port's files."""
    if not all(owned(path) for path in files):
        return FOREIGN
    with contextlib.ExitStack() as stack:
        fds = {path: stack.enter_context(_opened(path)) for path in files}
        fds = {path: fd for path, fd in fds.items() if fd is not None}  # gone meanwhile
        for path, fd in fds.items():
            if path.name.endswith(_LOCK_SUFFIXES) and not _lock(fd):
                return LIVE
        if any(_young(fd, young_since) for fd in fds.values()):
            return WAIT
        free = {path: fd for path, fd in fds.items() if not (mapped_waits and _mapped(path, fd))}
        if remove:
            for path, fd in free.items():  # lock files last, still held
                if not path.name.endswith(_LOCK_SUFFIXES):
                    _unlink_if_same(path, fd)
            for path, fd in free.items():
                if path.name.endswith(_LOCK_SUFFIXES):
                    _unlink_if_same(path, fd)
        return REMOVED if len(free) == len(fds) else WAIT


def abandoned_ports(domain: int) -> tuple[list[int], list[int]]:
    """Look without removing: the ports of ``domain`` a pass would remove, and those it
    would wait for (younger than :data:`YOUNG` s, or a peer maps a file)."""
    young_since = time.time() - YOUNG
    removable: list[int] = []
    held: list[int] = []
    for port, files in sorted(domain_port_files(domain).items()):
        verdict = _judge(files, young_since, mapped_waits=True, remove=False)
        if verdict == REMOVED:
            removable.append(port)
        elif verdict == WAIT:
            held.append(port)
    return removable, held


def remove_abandoned_ports(domain: int) -> list[int]:
    """One pass of a clean: remove the files of ``domain``'s abandoned ports (of the
    current user, lock free, nobody maps them); the ports still to wait for."""
    young_since = time.time() - YOUNG
    held: list[int] = []
    for port, files in sorted(domain_port_files(domain).items()):
        if _judge(files, young_since, mapped_waits=True, remove=True) == WAIT:
            held.append(port)
    return held


def remove_abandoned_segments() -> None:
    """Remove the data segments (of the current user) whose owner is gone: nobody holds
    their lock. Readers that still map one keep their mapping."""
    young_since = time.time() - YOUNG
    for files in segment_files().values():
        _judge(files, young_since, mapped_waits=False, remove=True)


def clean_shared_memory(
    domain: int | None = None, settle: float = 2.0, linger: float = 0.0
) -> None:
    """Remove the current user's Fast DDS shared-memory files whose processes are gone:
    segments, and with ``domain`` the files of that ROS domain's abandoned ports
    (:func:`remove_abandoned_ports`), waiting up to ``settle`` s for live peers to let
    go of them, and going on for at least ``linger`` s (at most ``settle``) for ports
    made again meanwhile.

    A live peer that has not yet noticed a participant's end (one killed says no goodbye:
    until its lease runs out) makes that participant's port again the next time it sends
    to it, a few seconds after a clean, and when it drops the participant removes some of
    the files but may leave the lock file and the mutex (seen in CI): a clean
    after a kill lingers for the lease (:data:`aes_ros.ros.launch.reaper.LINGER`)."""
    start = time.monotonic()
    remove_abandoned_segments()
    if domain is None:
        return
    while True:
        held = remove_abandoned_ports(domain)
        waited = time.monotonic() - start
        if waited >= settle or (not held and waited >= linger):
            return
        time.sleep(0.1 if held else 0.5)
