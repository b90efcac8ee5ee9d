"""Isolation: a node in another ROS_DOMAIN_ID, or on another host while the swarm's
discovery range is LOCALHOST, can neither see nor steer the swarm.

The swarm is aes-sim-bridge + aes-supervisor (4 robots, linear setup: west); the
stranger (tests/helpers/stranger.py) listens to /swarm/poses and publishes /swarm/cmd
(north) and /mona_0/cmd_vel (spin) for a few seconds. Each negative check has a
positive control showing that the same stranger does see and steer when it may.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import helpers
import pytest
from helpers.probe import Probe
from helpers.ros_env import reserved_domain_id

#: The stranger, run as a script.
STRANGER = str(Path(helpers.__file__).with_name("stranger.py"))
N = 4
WORLD = ("-p", "scenario:=linear", "-p", f"num_robots:={N}")


def run_stranger(
    env: dict[str, str], *args: str, prefix: tuple[str, ...] = (), seconds: float = 4.0
) -> dict:
    """Run the stranger script with ``env`` (after ``prefix``); its JSON report."""
    out = subprocess.run(
        [*prefix, sys.executable, STRANGER, "--seconds", str(seconds), *args],
        env=env, capture_output=True, text=True, timeout=60 + seconds,
    )  # fmt: skip
    assert out.returncode == 0, out.stdout + out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def start_swarm(spawn, probe: Probe) -> float:
    """Bridge and supervisor of N robots, watched by ``probe``; robot 0's heading."""
    spawn.start("aes-sim-bridge", "--ros-args", *WORLD, "-p", "real_time_factor:=1.0")
    spawn.start("aes-supervisor", "--ros-args", *WORLD, "-p", "use_sim_time:=true")
    probe.sample_poses(N)
    probe.wait(lambda: probe.desired and len(probe.times) > 5, 60.0, "the swarm")
    return float(probe.headings[-1][0])


def untouched(probe: Probe, heading0: float) -> bool:
    """Still the one west command, robot 0 not turned."""
    return [d.twist.linear.x for d in probe.desired] == [-1.0] and abs(
        probe.headings[-1][0] - heading0
    ) < 1e-9


def test_another_domain_cannot_see_or_steer(spawn, ros_env, probe) -> None:
    heading0 = start_swarm(spawn, probe)
    with reserved_domain_id() as other:
        result = run_stranger({**ros_env, "ROS_DOMAIN_ID": str(other)}, "--steer")
    probe.wait_sim(probe.now + 1.0)
    assert result["poses"] == 0 and set(result["matched"].values()) == {0}, result
    assert untouched(probe, heading0)
    # Control: the same stranger in the swarm's domain sees it and steers it.
    result = run_stranger(ros_env, "--steer")
    assert result["poses"] > 0 and result["matched"]["/swarm/cmd"] >= 1, result
    probe.wait(lambda: probe.desired[-1].twist.linear.y == 1.0, 20.0, "steered north")
    probe.wait_sim(probe.now + 0.5)
    assert not untouched(probe, heading0)


@contextlib.contextmanager
def namespace_host():
    """A network namespace joined to this one by a veth pair: another "host".

    Yields (name, address of this side, address of the other side)."""
    ip = shutil.which("ip") or "/usr/sbin/ip"
    if os.geteuid() != 0 or not Path(ip).exists():
        pytest.skip("needs root and ip(8) for a network namespace")
    k = os.getpid() % 200 + 20
    name, here, there = f"aesiso-{os.getpid()}", f"aesi{os.getpid() % 100000}a", "eth0"
    mine, theirs = f"10.79.{k}.1", f"10.79.{k}.2"

    def run(*cmd: str, check: bool = True) -> None:
        subprocess.run([ip, *cmd], check=check, capture_output=True, timeout=30)

    try:
        run("netns", "add", name)
        run("link", "add", here, "type", "veth", "peer", "name", "aesiso-peer", "netns", name)
        run("-n", name, "link", "set", "aesiso-peer", "name", there)
        run("addr", "add", f"{mine}/30", "dev", here)
        run("link", "set", here, "up")
        run("-n", name, "addr", "add", f"{theirs}/30", "dev", there)
        run("-n", name, "link", "set", there, "up")
        run("-n", name, "link", "set", "lo", "up")
    except subprocess.CalledProcessError as exc:
        run("netns", "del", name, check=False)
        pytest.skip(f"cannot build a network namespace: {exc.stderr!r}")
    try:
        yield name, mine, theirs, ip
    finally:
        run("link", "del", here, check=False)
        run("netns", "del", name, check=False)


def test_outside_the_discovery_range_cannot_see_or_steer(spawn, ros_env, probe) -> None:
    """The swarm runs with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST; the stranger sits
    in another network namespace ("host") with range SUBNET, on UDP (namespaces share
    /dev/shm). Control: a node on the swarm's host with range SUBNET (and the
    stranger as a static peer) is reached by the stranger at the same time.

    With automatic discovery the stranger neither sees nor steers the swarm. Measured
    limit, also checked here: a stranger that names the swarm's host in
    ROS_STATIC_PEERS does get in — LOCALHOST limits what the swarm announces, not
    whom it answers (docs/reliability.md: use a firewall or SROS2)."""
    udp = {"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4", "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}
    with namespace_host() as (ns, mine, theirs, ip):
        subprocess.run([ip, "-n", ns, "route", "add", "default", "dev", "eth0"], check=True)
        heading0 = start_swarm(spawn, probe)
        # The control: a SUBNET node on the swarm's host, the stranger its static peer.
        spawn.env = {**ros_env, **udp, "ROS_STATIC_PEERS": theirs}
        talker = spawn.start(sys.executable, STRANGER, "--seconds", "20", "--talk", name="talker")
        try:
            outside = {**ros_env, **udp}
            outside.pop("ROS_STATIC_PEERS", None)
            prefix = (ip, "netns", "exec", ns)
            result = run_stranger(outside, "--steer", seconds=6.0, prefix=prefix)
            probe.wait_sim(probe.now + 1.0)
            kept = untouched(probe, heading0)
            peer = run_stranger({**outside, "ROS_STATIC_PEERS": mine}, seconds=4.0, prefix=prefix)
        finally:
            talker.kill()
            talker.wait()
    assert result["control"] > 0, f"the probe reached nothing at all: {result}"
    assert result["poses"] == 0, result
    assert set(result["matched"].values()) == {0}, result
    assert kept, "the swarm was steered from outside"
    assert peer["poses"] > 0, f"static peer: {peer}"
