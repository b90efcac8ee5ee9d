"""The Mona firmware for system tests: whether it can be built here, and its build.

``scripts/setup.sh`` installs the toolchain (Debian's gcc-avr avr-libc simavr
libsimavr-dev libelf-dev), so in CI these tests run; elsewhere they skip with the reason.
"""

from __future__ import annotations

import fcntl
import shutil
import subprocess
import tempfile
from pathlib import Path

from aes_ros.ros.launch.firmware import BUILD

FIRMWARE = BUILD.parent
ELF = BUILD / "mona.elf"
SIL = BUILD / "mona-sil"


def toolchain_missing() -> str | None:
    """Why the firmware cannot be built and simulated here (None: it can)."""
    if shutil.which("avr-gcc") is None or shutil.which("make") is None:
        return "needs avr-gcc and make (scripts/setup.sh installs gcc-avr avr-libc)"
    if not Path("/usr/include/simavr/sim_avr.h").exists():
        return "needs libsimavr (scripts/setup.sh installs simavr libsimavr-dev libelf-dev)"
    return None


def build() -> None:
    """``make -C firmware`` (serialised: parallel tests share firmware/build)."""
    lock = Path(tempfile.gettempdir()) / "aes-swarm-firmware-build.lock"
    with lock.open("w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        result = subprocess.run(
            ["make", "-s", "-C", str(FIRMWARE)], capture_output=True, text=True, timeout=120
        )
    assert result.returncode == 0, result.stdout + result.stderr
