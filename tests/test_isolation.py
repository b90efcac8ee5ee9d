"""Isolation: a node in another ROS_DOMAIN_ID, or on another host while the swarm's
discovery range is LOCALHOST, can neither see nor steer the swarm.

The swarm is aes-sim-bridge + aes-supervisor (4 robots, linear setup: west); the
stranger (tests/ros_probe.py) listens to /swarm/poses and publishes /swarm/cmd
(north) and /mona_0/cmd_vel (spin) for a few seconds. Each negative check has a
positive control showing that the same probe does see and steer when it may.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip("rclpy")

from conftest import reserved_domain_id  # noqa: E402
from test_ros_system import Observer  # noqa: E402

PROBE = Path(__file__).with_name("ros_probe.py")
N = 4
WORLD = ("-p", "scenario:=linear", "-p", f"num_robots:={N}")


def probe(env: dict[str, str], *args: str, prefix: tuple[str, ...] = (), seconds: float = 4.0):
    out = subprocess.run(
        [*prefix, sys.executable, str(PROBE), "--seconds", str(seconds), *args],
        env=env, capture_output=True, text=True, timeout=60 + seconds,
    )  # fmt: skip
    assert out.returncode == 0, out.stdout + out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def start_swarm(spawn) -> Observer:
    spawn.start("aes-sim-bridge", "--ros-args", *WORLD, "-p", "real_time_factor:=1.0")
    spawn.start("aes-supervisor", "--ros-args", *WORLD, "-p", "use_sim_time:=true")
    obs = Observer(N)
    obs.spin_until(lambda: obs.desired and len(obs.times) > 5, 60.0, "the swarm")
    return obs


def untouched(obs: Observer, heading0: float) -> bool:
    """Still the one west command, robot 0 not turned."""
    return [d.twist.linear.x for d in obs.desired] == [-1.0] and abs(
        obs.headings[-1][0] - heading0
    ) < 1e-9


def test_another_domain_cannot_see_or_steer(spawn, ros_env) -> None:
    obs = start_swarm(spawn)
    try:
        heading0 = float(obs.headings[-1][0])
        with reserved_domain_id() as other:
            result = probe({**ros_env, "ROS_DOMAIN_ID": str(other)}, "--steer")
        obs.wait_sim(obs.now + 1.0)
        assert result["poses"] == 0 and set(result["matched"].values()) == {0}, result
        assert untouched(obs, heading0)
        # Control: the same probe in the swarm's domain sees it and steers it.
        result = probe(ros_env, "--steer")
        assert result["poses"] > 0 and result["matched"]["/swarm/cmd"] >= 1, result
        obs.spin_until(lambda: obs.desired[-1].twist.linear.y == 1.0, 20.0, "steered north")
        obs.wait_sim(obs.now + 0.5)
        assert not untouched(obs, heading0)
    finally:
        obs.close()


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


def test_outside_the_discovery_range_cannot_see_or_steer(spawn, ros_env) -> None:
    """The swarm runs with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST; the stranger sits
    in another network namespace ("host") with range SUBNET, on UDP (namespaces share
    /dev/shm). Control: a node on the swarm's host with range SUBNET (and the
    stranger as a static peer) is reached by the stranger at the same time.

    With automatic discovery the stranger neither sees nor steers the swarm. Measured
    limit, also checked here: a stranger that names the swarm's host in
    ROS_STATIC_PEERS does get in — LOCALHOST limits what the swarm announces, not
    whom it answers (README "Reliability": use a firewall or SROS2)."""
    udp = {"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4", "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}
    with namespace_host() as (ns, mine, theirs, ip):
        subprocess.run([ip, "-n", ns, "route", "add", "default", "dev", "eth0"], check=True)
        obs = start_swarm(spawn)
        try:
            heading0 = float(obs.headings[-1][0])
            talker = subprocess.Popen(
                [sys.executable, str(PROBE), "--seconds", "20", "--talk"],
                env={**ros_env, **udp, "ROS_STATIC_PEERS": theirs},
                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            )  # fmt: skip
            try:
                stranger = {**ros_env, **udp}
                stranger.pop("ROS_STATIC_PEERS", None)
                prefix = (ip, "netns", "exec", ns)
                result = probe(stranger, "--steer", seconds=6.0, prefix=prefix)
                obs.wait_sim(obs.now + 1.0)
                kept = untouched(obs, heading0)
                peer = probe({**stranger, "ROS_STATIC_PEERS": mine}, seconds=4.0, prefix=prefix)
            finally:
                talker.kill()
                talker.wait()
        finally:
            obs.close()
    assert result["control"] > 0, f"the probe reached nothing at all: {result}"
    assert result["poses"] == 0, result
    assert set(result["matched"].values()) == {0}, result
    assert kept, "the swarm was steered from outside"
    assert peer["poses"] > 0, f"static peer: {peer}"
