"""Make ``contacts_off_reference.npz``: simulator outputs from before contacts existed.

Made from commit 7acad83 (the simulator and kernel before contacts) with
``git archive 7acad83 aes_ros | tar -x -C /tmp/base`` and
``PYTHONPATH=/tmp/base .venv/bin/python tests/data/make_contacts_off_reference.py``.
tests/unit/test_contacts_sim.py recomputes every case with :func:`compute` and the
current code and asserts equality bit for bit: with ``contacts`` false and no walls or
obstacles the simulator must give exactly what it gave before.

Cases: the combined setup on a 3 x 4 sheet for 2 s (40 steps, two noise chunks), seeds
0 and 1 in one batch, noise on, both backends; and the same with perception error on
(noise, delay, a 10 Hz camera, misses), which takes the kernel's perception path.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from aes_ros import scenario, simulator
from aes_ros.params import PARAMS

PATH = Path(__file__).with_name("contacts_off_reference.npz")
SEEDS = (0, 1)
#: contacts off whatever its default (the code before contacts has no such parameter)
SMALL = {
    "rows": 3,
    "cols": 4,
    "duration": 2.0,
    **({"contacts": False} if "contacts" in PARAMS else {}),
}
PERCEIVED = {
    "perception_sigma": 0.01,
    "perception_delay": 0.1,
    "perception_rate": 10.0,
    "perception_miss": 0.1,
}
#: name: (overrides, backend)
CASES = {
    "combined": ({}, "numba"),
    "combined_numpy": ({}, "numpy"),
    "perceived": (PERCEIVED, "numba"),
    "perceived_numpy": (PERCEIVED, "numpy"),
}


def compute(name: str) -> dict[str, np.ndarray]:
    """Metrics (B, T+1, 5), positions (B, T+1, N, 2) and headings (B, T+1, N) of a case."""
    overrides, backend = CASES[name]
    sc = scenario.load("combined", {**SMALL, **overrides})
    result = simulator.simulate(sc, list(SEEDS), record=True, backend=backend)
    return {
        "metrics": result.metrics[..., :5],
        "positions": result.positions,
        "headings": result.headings,
    }


def main() -> None:
    arrays = {f"{name}/{field}": value for name in CASES for field, value in compute(name).items()}
    np.savez_compressed(PATH, **arrays)
    print(f"wrote {PATH} ({PATH.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
