"""The packaged ``cluttered`` scenario under ``aes-swarm launch``: the bridge's simulated IR
sensors feed the robot nodes' avoidance term over DDS, and the swarm gets past the posts
across its path without a body touching one."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from aes_ros import scenario
from aes_ros.obstacles import arrays
from aes_ros.simulator import BODY
from aes_ros.trajectory import load_trajectory


def test_cluttered_swarm_passes_the_posts_without_touching_them(spawn, tmp_path) -> None:
    """Lockstep, kinematic mode, 16 robots, 40 s of sim time (about 10 s of wall time):
    no body ever comes within 1 mm of a post, and every robot ends beyond them. Without
    the term (``--set w_o=0``) the same run drives bodies onto the posts
    (docs/model.md, "The cluttered scenario")."""
    out = tmp_path / "out"
    proc = spawn.start(
        "aes-swarm", "launch", "--setup", "cluttered", "--lockstep", "--real-time-factor", "0",
        "--mode", "kinematic", "--duration", "40", "--seed", "1", "--out", str(out),
        name="launch",
    )  # fmt: skip
    try:
        rc = proc.wait(180.0)
    except subprocess.TimeoutExpired:
        pytest.fail(f"aes-swarm launch did not finish:\n{spawn.log(proc).read_text()[-3000:]}")
    assert rc == 0, spawn.log(proc).read_text()[-3000:]

    circles = arrays(scenario.load("cluttered").obstacles)[0]
    traj = load_trajectory(out / "trajectory.h5")
    pos, head = traj.positions[0], traj.headings[0]  # (T, N, 2), (T, N)
    assert traj.times[-1] > 30.0
    centres = pos + BODY.axle_offset * np.stack([np.cos(head), np.sin(head)], axis=-1)
    gap = np.linalg.norm(centres[..., None, :] - circles[:, :2], axis=-1) - circles[:, 2]
    assert (gap - BODY.body_radius).min() > 1e-3  # no body within 1 mm of a post
    post_x = (circles[:, 0] - circles[:, 2]).min()
    assert (pos[-1, :, 0] < post_x - 0.1).all(), pos[-1, :, 0]  # every robot past them
