"""aes_ros.numba_cache: an edit of a module whose numba function a cached kernel inlines
compiles the kernel again (numba alone loads the stale machine code)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

KERNEL = """
import sys
from numba import njit
from aes_ros.numba_cache import depend_on
import part

@njit(cache=True)
def kernel():
    return part.value()

if sys.argv[1] == "depend":
    assert depend_on(kernel, "part")
print(kernel())
"""


def run_kernel(where: Path, mode: str) -> int:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(where / "cache"), "PYTHONPATH": str(where)}
    done = subprocess.run(
        [sys.executable, str(where / "kernel.py"), mode],
        env=env, capture_output=True, text=True, timeout=120, check=True,
    )  # fmt: skip
    return int(done.stdout)


def write_part(where: Path, value: int) -> None:
    (where / "part.py").write_text(
        f"from numba import njit\n\n@njit(inline='always')\ndef value():\n    return {value}\n"
    )


def test_an_edit_of_an_inlined_module_compiles_the_kernel_again(tmp_path: Path) -> None:
    for mode in ("plain", "depend"):
        where = tmp_path / mode
        where.mkdir()
        (where / "kernel.py").write_text(KERNEL)
        write_part(where, 1)
        assert run_kernel(where, mode) == 1  # compiled and cached
        write_part(where, 2)
        if mode == "plain":  # numba's own stamp: the kernel's file only, the old code
            assert run_kernel(where, mode) == 1
        else:
            assert run_kernel(where, mode) == 2


def test_a_function_without_a_cache_is_left_as_it_is() -> None:
    from numba import njit

    from aes_ros.numba_cache import depend_on

    @njit
    def plain() -> int:
        return 1

    assert not depend_on(plain, "json")
    assert plain() == 1
