"""Fast DDS's shared-memory files (/dev/shm) left behind by processes that are gone.

Fast DDS's shared-memory transport keeps a *port* per listening locator: the segment
``fastrtps_port<N>`` (N = DDS port, 7400 + 250 · domain + offset, or 7000 + participant
index, which every domain of the machine shares), its listener's lock file
``fastrtps_port<N>_el`` (a ``flock`` held while the listener lives) and a semaphore.
The listener removes its port when it shuts down, but not while another process still
maps the segment; the last peer to let go usually removes it then, but processes that
stop together (or are killed) leave port files that nobody removes, and
``fastdds shm clean`` does not recognise them.

:func:`clean_shared_memory` removes them for one ROS domain: files of ports whose
listener is gone (no lock held on its lock file) and that no live process maps. A peer
that outlives them (a ``ros2 topic echo``, a test's probe) lets go of a port about
0.3 s after its listener said goodbye, so the clean waits up to ``settle`` seconds for
such ports. Ports of live listeners are never touched, whatever domain they serve.

A participant starting beside a clean makes its port files one by one, and maps and
locks them a moment after: the clean lists the files before it looks at the locks and
mappings (a file made during its look at ``/proc`` is not taken for abandoned), and it
leaves files younger than :data:`YOUNG` seconds alone for this pass. Ports below 7400
belong to participants of every domain, so a clean of one domain runs beside the
starts of the others.
"""

from __future__ import annotations

import contextlib
import os
import re
import subprocess
import time
from pathlib import Path

from aes_ros.ros.launch.plan import LaunchError, executable

#: Where Fast DDS keeps its shared-memory files (Linux).
SHM_DIR = Path("/dev/shm")
_PORT_FILE = re.compile(r"(?:sem\.)?fastrtps_port(\d+)(?:_el|_sl|_mutex)?")
_LOCK_SUFFIXES = ("_el", "_sl")
#: Seconds a port file is left alone after it was made: its maker may not have mapped
#: or locked it yet (a loaded machine preempts a starting participant for that long).
YOUNG = 1.0


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


def mapped_files() -> set[str]:
    """Paths of the /dev/shm files some live process maps (its /proc/<pid>/maps)."""
    mapped: set[str] = set()
    for maps in Path("/proc").glob("[0-9]*/maps"):
        try:
            text = maps.read_text()
        except OSError:  # gone, or not ours to read
            continue
        mapped.update(
            line.rsplit(None, 1)[-1] for line in text.splitlines() if str(SHM_DIR) in line
        )
    return mapped


def locked_inodes() -> set[int]:
    """Inodes of the /dev/shm files a live process holds a lock on (/proc/locks)."""
    dev = SHM_DIR.stat().st_dev
    device = f"{os.major(dev):02x}:{os.minor(dev):02x}"
    inodes: set[int] = set()
    with contextlib.suppress(OSError):
        for line in Path("/proc/locks").read_text().splitlines():
            for field in line.split():
                if field.startswith(device + ":"):
                    inodes.add(int(field.rsplit(":", 1)[1]))
    return inodes


def _has_listener(files: list[Path], locked: set[int]) -> bool:
    for path in files:
        if path.name.endswith(_LOCK_SUFFIXES):
            with contextlib.suppress(OSError):
                if path.stat().st_ino in locked:
                    return True
    return False


def _made_since(path: Path, when: float) -> bool:
    try:
        return path.stat().st_ctime > when
    except OSError:  # gone already
        return False


def abandoned_ports(domain: int) -> tuple[list[Path], list[int]]:
    """Ports of ``domain`` whose listener is gone: their files that no live process maps
    (to remove), and the ports of which a live peer still maps a file, or whose files
    are younger than :data:`YOUNG` s (to wait for)."""
    ports = domain_port_files(domain)  # before the locks and mappings: see the module doc
    young_since = time.time() - YOUNG
    locked, mapped = locked_inodes(), mapped_files()
    removable: list[Path] = []
    held: list[int] = []
    for port, files in sorted(ports.items()):
        if _has_listener(files, locked):
            continue
        if any(_made_since(path, young_since) for path in files):
            held.append(port)
            continue
        free = [path for path in files if str(path) not in mapped]
        removable += free
        if len(free) < len(files):
            held.append(port)
    return removable, held


def _fastdds_tool() -> str | None:
    """``fastdds`` of this environment (next to the interpreter), else from PATH; None
    if there is none."""
    try:
        return executable("fastdds")
    except LaunchError:
        return None


def remove_abandoned_ports(domain: int) -> list[int]:
    """One pass of a clean: remove the files of ``domain``'s abandoned ports
    (:func:`abandoned_ports`); the ports still to wait for."""
    removable, held = abandoned_ports(domain)
    for path in removable:
        with contextlib.suppress(OSError):
            path.unlink()
    return held


def clean_shared_memory(domain: int | None = None, settle: float = 2.0) -> None:
    """Remove Fast DDS shared-memory files whose processes are gone: ``fastdds shm
    clean`` (segments), and with ``domain`` the files of that ROS domain's abandoned
    ports (:func:`abandoned_ports`), waiting up to ``settle`` s for live peers to let
    go of them."""
    if (tool := _fastdds_tool()) is not None:
        with contextlib.suppress(OSError, subprocess.SubprocessError):
            subprocess.run([tool, "shm", "clean"], capture_output=True, timeout=30, check=False)
    if domain is None:
        return
    deadline = time.monotonic() + settle
    while True:
        held = remove_abandoned_ports(domain)
        if not held or time.monotonic() >= deadline:
            return
        time.sleep(0.1)
