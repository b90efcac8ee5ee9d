"""``aes-swarm launch --firmware sil``: the whole chain robot node → ``cmd_vel`` →
``aes-mona-driver`` → bytes → the real firmware in ``mona-sil`` → PWM → the bridge's
wheels → poses moves and aligns the swarm like the same launch without firmware.

A chain broken anywhere leaves the wheels at rest (no ``wheel_cmd``: the bridge's
robots never move and the launch fails to start) or drives them wrongly (a sign or
scale error in the PWM read back: the sheet does not go the commanded way, or it
loses its alignment), so the tolerances are generous for a loaded machine yet out of
reach of a broken chain.
"""

from __future__ import annotations

import csv
import subprocess
from pathlib import Path

import numpy as np
import pytest
from helpers.firmware import build, toolchain_missing

N = 8
DURATION_S = 14.0


pytestmark = pytest.mark.skipif(toolchain_missing() is not None, reason=str(toolchain_missing()))


def _launch(spawn, out: Path, *extra: str) -> dict[str, np.ndarray]:
    """One ``aes-swarm launch --setup linear`` of N robots, seed 0, on pybullet's wheels
    (saturated per wheel as the firmware's are); its metrics.csv."""
    launcher = spawn.start(
        "aes-swarm", "launch", "--setup", "linear", "--robots", str(N), "--seed", "0",
        "--mode", "dynamic",
        "--duration", str(DURATION_S), "--out", str(out), *extra, name=out.name,
    )  # fmt: skip
    try:
        assert launcher.wait(90) == 0, spawn.log(launcher).read_text()[-3000:]
    except subprocess.TimeoutExpired:
        pytest.fail(f"launch did not end:\n{spawn.log(launcher).read_text()[-3000:]}")
    with open(out / "metrics.csv") as fh:
        rows = list(csv.DictReader(fh))
    return {key: np.array([float(r[key]) for r in rows]) for key in rows[0]}


def test_the_firmware_in_the_loop_moves_and_aligns_like_the_bridge(spawn, tmp_path) -> None:
    build()
    plain = _launch(spawn, tmp_path / "plain")
    sil = _launch(spawn, tmp_path / "sil", "--firmware", "sil")

    logs = tmp_path / "sil" / "logs"
    assert len(list(logs.glob("mona_sil_*.log"))) == N
    for i in range(N):  # every MCU's motors were driven
        text = (logs / f"mona_sil_{i}.log").read_text()
        assert "left=" in text and text.count("\nmotors") > 20, text[-500:]

    def moved(m: dict[str, np.ndarray]) -> np.ndarray:
        return np.array(
            [m["centroid_x"][-1] - m["centroid_x"][0], m["centroid_y"][-1] - m["centroid_y"][0]]
        )

    d_plain, d_sil = moved(plain), moved(sil)
    along = float(d_sil @ d_plain) / float(np.linalg.norm(d_plain))
    late = {k: m["t"] >= m["t"][-1] - 5.0 for k, m in (("plain", plain), ("sil", sil))}
    psi = {k: float(m["alignment"][late[k]].mean()) for k, m in (("plain", plain), ("sil", sil))}
    print(f"moved {d_plain} m without, {d_sil} m with firmware; psi {psi}")
    assert np.linalg.norm(d_plain) > 0.3, "the run without firmware did not move"
    assert along >= 0.5 * np.linalg.norm(d_plain), (d_plain, d_sil)
    assert abs(psi["sil"] - psi["plain"]) <= 0.1, psi
