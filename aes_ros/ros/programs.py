"""The programs a launch starts, found in this environment; the error when one is not."""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path


class LaunchError(RuntimeError):
    """The system did not start, or a process died during the run."""


def executable(name: str) -> str:
    """A console script of this environment (next to the interpreter), else from PATH;
    a path is returned as it is."""
    if os.sep in name:
        return name
    local = Path(sys.executable).parent / name
    if local.exists():
        return str(local)
    found = shutil.which(name)
    if found is None:
        raise LaunchError(f"{name}: console script not found (is aes-swarm installed?)")
    return found
