"""After ``python -m aes_ros.precompile`` (scripts/setup.sh runs it), a new process's
simulation and contact resolution load numba's cached machine code and compile nothing."""

from __future__ import annotations

import subprocess
import sys

CHECK = """
import numpy as np
from aes_ros import contacts, kernel, scenario, simulator
simulator.simulate(scenario.load("combined", {"rows": 3, "cols": 3, "duration": 0.5}), [4, 5])
walls, circles, boxes = contacts.contact_geometry((-2.0, 2.0, -2.0, 2.0), None, None)
contacts.resolve_contacts(np.zeros((3, 2)), np.zeros(3), 0.04, 0.018, walls, circles, boxes, 8)
for f in (kernel.advance, contacts.resolve_contacts):
    assert f.stats.cache_hits and not f.stats.cache_misses, (f.__name__, f.stats)
"""


def test_a_new_process_compiles_nothing_after_precompile() -> None:
    subprocess.run([sys.executable, "-m", "aes_ros.precompile"], check=True, timeout=600)
    out = subprocess.run([sys.executable, "-c", CHECK], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
