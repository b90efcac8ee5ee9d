"""Make ``perception_off_reference.npz``: simulator outputs from before perception existed.

Made at commit 490d968 (before perception existed) with
``.venv/bin/python tests/data/make_perception_off_reference.py``.
tests/unit/test_perception.py recomputes every case with :func:`compute` and the
current code and asserts equality bit for bit: with its perception parameters at
their defaults (off) the simulator must give exactly what it gave before.

Cases: the three packaged setups on a 4 x 5 sheet for 3 s (60 steps, so two noise
chunks), seeds 0-2 in one batch, noise on, numba backend; the combined setup also
through the numpy backend, and with a fixed rotation centre and clipping.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from aes_ros import scenario, simulator

PATH = Path(__file__).with_name("perception_off_reference.npz")
SEEDS = (0, 1, 2)
SMALL = {"rows": 4, "cols": 5, "duration": 3.0, "contacts": False}  # made before bodies existed
#: name: (setup, overrides, backend)
CASES = {
    "linear": ("linear", {}, "numba"),
    "rotation": ("rotation", {}, "numba"),
    "combined": ("combined", {}, "numba"),
    "combined_numpy": ("combined", {}, "numpy"),
    "combined_fixed_clip": ("combined", {"rotation_center": "0.3,-0.2", "clip": True}, "numba"),
}


def compute(name: str) -> dict[str, np.ndarray]:
    """Metrics (B, T+1, 5), positions (B, T+1, N, 2) and headings (B, T+1, N) of a case."""
    setup, overrides, backend = CASES[name]
    sc = scenario.load(setup, {**SMALL, **overrides})
    result = simulator.simulate(sc, list(SEEDS), record=True, backend=backend)
    return {"metrics": result.metrics, "positions": result.positions, "headings": result.headings}


def main() -> None:
    arrays = {f"{name}/{field}": value for name in CASES for field, value in compute(name).items()}
    np.savez_compressed(PATH, **arrays)
    print(f"wrote {PATH} ({PATH.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
