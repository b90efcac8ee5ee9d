"""``aes-swarm launch --firmware sil``: the whole chain robot node → ``cmd_vel`` →
``aes-mona-driver`` → bytes → the real firmware in ``mona-sil`` → PWM → the bridge's
wheels → poses moves and aligns the swarm like the same launch without firmware.

A chain broken anywhere leaves the wheels at rest (no ``wheel_cmd``: the bridge's
robots never move and the launch fails to start) or drives them wrongly (a sign or
scale error in the PWM read back: the sheet does not go the commanded way, or it
loses its alignment), so the tolerances are generous for a loaded machine yet out of
reach of a broken chain. One MCU is killed early in the run: the launcher restarts it,
the driver reaches the new one, and the summary counts it recovered.
"""

from __future__ import annotations

import csv
import signal
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import psutil
import pytest
from helpers.firmware import build, toolchain_missing

N = 8
DURATION_S = 14.0
KILLED = 3  # the MCU killed mid-run


pytestmark = pytest.mark.skipif(toolchain_missing() is not None, reason=str(toolchain_missing()))


def _launch(
    spawn, out: Path, *extra: str, moving: Callable[[int], None] | None = None
) -> dict[str, np.ndarray]:
    """One ``aes-swarm launch --setup linear`` of N robots, seed 0, on pybullet's wheels
    (saturated per wheel as the firmware's are); its metrics.csv. ``moving(pid)`` is
    called with the launcher's pid once every robot moves."""
    launcher = spawn.start(
        "aes-swarm", "launch", "--setup", "linear", "--robots", str(N), "--seed", "0",
        "--mode", "dynamic",
        "--duration", str(DURATION_S), "--out", str(out), *extra, name=out.name,
    )  # fmt: skip
    log = spawn.log(launcher)
    deadline = time.monotonic() + 60.0
    while moving is not None and launcher.poll() is None and time.monotonic() < deadline:
        if "robots moving at sim time" in log.read_text():
            moving(launcher.pid)
            break
        time.sleep(0.1)
    try:
        assert launcher.wait(90) == 0, spawn.log(launcher).read_text()[-3000:]
    except subprocess.TimeoutExpired:
        pytest.fail(f"launch did not end:\n{spawn.log(launcher).read_text()[-3000:]}")
    with open(out / "metrics.csv") as fh:
        rows = list(csv.DictReader(fh))
    return {key: np.array([float(r[key]) for r in rows]) for key in rows[0]}


def _kill_mcu(launcher_pid: int) -> None:
    """SIGKILL robot KILLED's ``mona-sil``, as a crash would end it."""
    for p in psutil.Process(launcher_pid).children(recursive=True):
        argv = p.cmdline()
        if argv and argv[0].endswith("mona-sil") and argv[1:3] == ["--robot-id", str(KILLED)]:
            p.send_signal(signal.SIGKILL)
            return
    pytest.fail(f"no mona-sil --robot-id {KILLED} under the launcher")


def test_the_firmware_in_the_loop_moves_and_aligns_like_the_bridge(spawn, tmp_path) -> None:
    build()
    plain = _launch(spawn, tmp_path / "plain")
    sil = _launch(spawn, tmp_path / "sil", "--firmware", "sil", moving=_kill_mcu)

    logs = tmp_path / "sil" / "logs"
    assert len(list(logs.glob("mona_sil_*.log"))) == N
    for i in range(N):  # every MCU's motors were driven
        text = (logs / f"mona_sil_{i}.log").read_text()
        assert "left=" in text and text.count("\nmotors") > 20, text[-500:]
    # the killed MCU was restarted, counted recovered, and driven again through the
    # link firmware_loop moved to its new device
    restarted = (logs / f"mona_sil_{KILLED}.log").read_text().split("pty: ")[1:]
    assert len(restarted) == 2 and restarted[1].count("\nmotors") > 10, restarted[-1][-500:]
    said = (tmp_path / "logs" / "sil.log").read_text()  # the launcher's output
    assert f"1 fault (mona_sil_{KILLED} 1×), 1 recovered" in said, said[-2000:]

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
