"""Perception error in the ROS system (``aes-swarm launch --perception``): the bridge
shows the robots the offline simulator's perceived frame (:mod:`aes_ros.perception`).

Real processes over Fast DDS, lockstep at full speed, in the test's own
``ROS_DOMAIN_ID`` (the ``spawn`` fixture).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from helpers.ros_env import wait_for

from aes_ros import scenario, simulator
from aes_ros.perception import camera_period_steps, delay_steps
from aes_ros.ros import interface as names
from aes_ros.ros.bag import read_bag
from aes_ros.trajectory import load_trajectory

BIN = Path(sys.executable).parent
SIGMA, DELAY, RATE, MISS = 0.005, 0.1, 10.0, 0.1


def _poses(msg) -> tuple[int, np.ndarray]:
    stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
    return stamp, np.array([[p.position.x, p.position.y] for p in msg.poses])


def test_a_perceived_launch_moves_like_the_offline_model_with_the_same_perception(
    spawn, tmp_path
) -> None:
    """16 robots, linear setup, lockstep, kinematic, noise and clipping off, seed 7,
    ``--perception sigma=0.005,delay=0.1,rate=10,miss=0.1``:

    - the swarm's true trajectory (the launch's outputs, from /sim/ground_truth/poses)
      reaches the run's end although the launcher is stopped for 3 s (the bridge goes on
      at full speed to the end, where it waits: its writer keeps what the launcher
      missed), and
      equals the offline simulator's run with the same perception and seed within 1 mm
      at every step: the bridge draws what the simulator draws;
    - what the robots were shown (/swarm/poses in the bag) is the true state 2 steps
      (0.1 s) earlier, refreshed every 2nd step (10 Hz), plus noise of std 5 mm per
      axis, and about 10 % of the robots kept their last pose at a refresh.
    """
    seed, out, bag = 7, tmp_path / "out", tmp_path / "run.mcap"
    proc = spawn.start(
        str(BIN / "aes-swarm"), "launch", "--setup", "linear", "--robots", "16",
        "--lockstep", "--real-time-factor", "0", "--mode", "kinematic", "--duration", "10",
        "--seed", str(seed), "--set", "d_r=0", "--set", "d_theta=0", "--set", "clip=false",
        "--perception", f"sigma={SIGMA},delay={DELAY},rate={RATE},miss={MISS}",
        "--record", str(bag), "--out", str(out), name="launch",
    )  # fmt: skip
    # The launcher held up for 3 s as the run starts (as a loaded machine can do to it):
    # the bridge runs on at full speed to the run's end (its pause_at), and the
    # launcher's outputs must still reach it (with a writer history of 50 they ended at
    # 0.35 s; with the bridge running on past the end, a loaded machine's launcher fell
    # 1000 messages behind and they ended at 0.2 s)
    log = spawn.log(proc)
    assert wait_for(lambda: "robots moving" in log.read_text(), 120), log.read_text()
    os.kill(proc.pid, signal.SIGSTOP)
    time.sleep(3.0)
    os.kill(proc.pid, signal.SIGCONT)
    try:
        rc = proc.wait(180)
    except subprocess.TimeoutExpired:
        pytest.fail(f"launch did not finish:\n{spawn.log(proc).read_text()[-3000:]}")
    assert rc == 0, spawn.log(proc).read_text()[-3000:]

    sc = scenario.load("linear", {"d_r": 0.0, "d_theta": 0.0, "clip": False, "duration": 10.0})
    sc = sc.with_robots(16).with_overrides(
        {"perception_sigma": SIGMA, "perception_delay": DELAY, "perception_rate": RATE,
         "perception_miss": MISS}
    )  # fmt: skip
    ref = simulator.simulate(sc, [seed], noise=False)
    traj = load_trajectory(out / "trajectory.h5")
    steps = np.round(traj.times / sc.dt).astype(int)
    print(f"outputs: {len(steps)} samples, steps {steps[0]}..{steps[-1]}")
    assert steps[0] == 0 and steps[-1] >= 195
    dev = np.linalg.norm(traj.positions[0] - ref.positions[0, steps], axis=-1)
    assert dev.max() < 1e-3, f"max deviation {dev.max() * 1e3:.3f} mm"
    # the draws made a difference the comparison can see: without noise and misses the
    # swarm ends elsewhere
    calm = sc.with_overrides({"perception_sigma": 0.0, "perception_miss": 0.0})
    other = simulator.simulate(calm, [seed], noise=False)
    assert np.linalg.norm(other.positions[0, -1] - ref.positions[0, -1], axis=-1).max() > 5e-3

    truth, seen = {}, {}
    for topic, _, msg in read_bag(bag, [names.GROUND_TRUTH_POSES, names.POSES]):
        stamp, xy = _poses(msg)
        (truth if topic == names.GROUND_TRUTH_POSES else seen)[round(stamp * 1e-9 / sc.dt)] = xy
    delay, period = delay_steps(DELAY, sc.dt), camera_period_steps(RATE, sc.dt)
    assert (delay, period) == (2, 2)
    residuals, kept, shown = [], 0, 0
    for s in range(period * 2, max(seen)):
        if s not in seen or s - delay not in truth:
            continue
        refresh = s - s % period
        if s != refresh:  # held between refreshes
            if s - 1 in seen:
                np.testing.assert_array_equal(seen[s], seen[s - 1])
            continue
        held = seen.get(s - period)
        if held is None:
            continue
        same = np.all(seen[s] == held, axis=1)
        kept += int(same.sum())
        shown += len(same)
        residuals.append((seen[s] - truth[s - delay])[~same])
    r = np.concatenate(residuals)
    assert shown > 1000
    assert abs(r.mean()) < 1e-3
    assert r.std() == pytest.approx(SIGMA, rel=0.1)
    assert kept / shown == pytest.approx(MISS, abs=0.03)
