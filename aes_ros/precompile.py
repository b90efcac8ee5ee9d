"""Compile the numba functions into their on-disk cache once, at install time.

``scripts/setup.sh`` runs ``python -m aes_ros.precompile``, so that the first
simulation, bridge or test after an install does not wait for the compiler
(the offline kernel with bodies, IR rays and perception takes tens of seconds on
a 2-core machine). Each call below uses the argument types the simulator, the
bridge and the dashboard use, so their calls find a cached version.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from aes_ros import scenario, simulator
from aes_ros.contact_measures import TOUCH_TOLERANCE, measure_contacts
from aes_ros.contacts import contact_geometry, resolve_contacts
from aes_ros.ir_readings import ir_ranges
from aes_ros.mona.geometry import MonaGeometry

#: Small runs that go through every path of the kernel: bodies with walls and obstacles,
#: the IR avoidance term, and the perception model.
RUNS = (
    {"rows": 2, "cols": 2, "duration": 0.2},
    {"rows": 2, "cols": 2, "duration": 0.2, "w_o": 1.0, "walls": "-5,5,-5,5",
     "obstacles": "circle:-1,0,0.05;box:-2,-1.9,-1,1"},
    {"rows": 2, "cols": 2, "duration": 0.2, "perception_sigma": 0.001, "perception_rate": 20},
)  # fmt: skip


def main() -> int:
    start = time.perf_counter()
    for values in RUNS:
        sc = scenario.load("combined", values)
        for backend in ("numba", "numpy"):
            simulator.simulate(sc, [0], backend=backend)
    g = MonaGeometry()
    positions, headings = np.array([[0.0, 0.0], [0.05, 0.0]]), np.zeros(2)
    walls, circles, boxes = contact_geometry((-1.0, 1.0, -1.0, 1.0), [(0.5, 0.5, 0.1)], None)
    resolve_contacts(positions, headings, g.body_radius, g.axle_offset, walls, circles, boxes, 8)
    measure_contacts(
        positions, headings, g.body_radius, g.axle_offset, walls, circles, boxes, TOUCH_TOLERANCE
    )
    ir_ranges(positions, headings, walls=walls, circles=circles, boxes=boxes)
    print(f"numba functions compiled in {time.perf_counter() - start:.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
