"""Several "hosts" on one machine: Linux network namespaces on a private LAN.

Used by tests/system/test_multihost.py (docs/design.md#processes,
multi-host and packet loss). :class:`Lan` builds

    namespace <prefix>b   (bridge + supervisor + observer)  br0 10.77.0.1/24
         |  veth0 ── eth0  namespace <prefix>r0  10.77.0.10/24  (robot host 0)
         |  veth1 ── eth0  namespace <prefix>r1  10.77.0.11/24  (robot host 1)

a Linux bridge ``br0`` in the first namespace with one veth pair per robot
namespace; every address exists only inside these namespaces, so no packet
can leave the machine. Optional nftables rules (:meth:`Lan.add_rules`) count
the UDP datagrams a namespace sends and receives on its LAN device, drop a
fraction of those it receives (``numgen random mod 10 0 drop``) and can block
multicast (discovery then needs ``ROS_STATIC_PEERS``). :meth:`Lan.close`
kills every process still inside the namespaces and deletes them (the veths
go with them).

Run as a script inside the bridge namespace, this module is the observer::

    ip netns exec NS python tests/helpers/netns.py observe --robots 16 --duration 20 --out obs.npz

It samples ``/swarm/poses`` (with the tests' probe, :class:`helpers.probe.Probe`) and
``/swarm/alignment`` until every robot has moved and then for ``duration`` s
of sim time, and writes them to an ``.npz`` file.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

#: Name prefix of every namespace made here; ``<PREFIX><pid>-<k>`` (stale ones are removed).
PREFIX = "aesmh-"
SUBNET = "10.77.0"
BRIDGE_ADDR = f"{SUBNET}.1"
#: nftables counters of :meth:`Lan.add_rules`.
COUNTERS = ("udp_in", "udp_out", "lost_in", "mcast_in", "mcast_out")


def tool(name: str) -> str | None:
    """Path of an admin command (also in /usr/sbin, /sbin when PATH lacks them)."""
    path = os.pathsep.join([os.environ.get("PATH", ""), "/usr/sbin", "/sbin"])
    return shutil.which(name, path=path)


IP = tool("ip") or "ip"
NFT = tool("nft") or "nft"


def robot_addr(i: int) -> str:
    return f"{SUBNET}.{10 + i}"


def _run(*cmd: str, check: bool = True, timeout: float = 30.0) -> subprocess.CompletedProcess:
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if check and out.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({out.returncode}): {out.stderr.strip()}")
    return out


def unavailable() -> str | None:
    """Why network namespaces cannot be used here (None: they can)."""
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        return "needs root (ip netns, veth, nftables)"
    if tool("ip") is None:
        return "needs the ip command (iproute2)"
    probe = f"{PREFIX}{os.getpid()}-probe"
    out = _run(IP, "netns", "add", probe, check=False)
    if out.returncode != 0:
        return f"ip netns add fails here: {out.stderr.strip()}"
    _run(IP, "netns", "del", probe, check=False)
    return None


def nft_unavailable() -> str | None:
    """Why nftables rules cannot be used here (None: they can)."""
    if tool("nft") is None:
        return "nft is not installed (apt-get install nftables; .ci/run does this as root)"
    out = _run(NFT, "list", "tables", check=False)  # read-only probe of nf_tables
    if out.returncode != 0:
        return f"nftables does not work here: {out.stderr.strip()}"
    return None


def ns_pids(ns: str) -> list[int]:
    out = _run(IP, "netns", "pids", ns, check=False)
    return [int(p) for p in out.stdout.split()] if out.returncode == 0 else []


def remove_stale() -> None:
    """Delete namespaces of earlier test processes that died without cleaning up."""
    out = _run(IP, "netns", "list", check=False)
    for line in out.stdout.splitlines():
        name = line.split()[0] if line.split() else ""
        if not name.startswith(PREFIX):
            continue
        pid = name[len(PREFIX) :].split("-")[0]
        if pid.isdigit() and not Path(f"/proc/{pid}").exists():
            _kill_all(name)
            _run(IP, "netns", "del", name, check=False)


def _kill_all(ns: str, timeout: float = 10.0) -> None:
    """SIGINT every process in ``ns``, SIGKILL whatever is left after ``timeout`` s."""
    for sig in (signal.SIGINT, signal.SIGKILL):
        pids = ns_pids(ns)
        for pid in pids:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, sig)
        deadline = time.monotonic() + timeout
        while ns_pids(ns) and time.monotonic() < deadline:
            time.sleep(0.1)
        if not ns_pids(ns):
            return


class Lan:
    """A bridge namespace and ``robots`` robot namespaces joined by veth pairs."""

    def __init__(self, robots: int = 2) -> None:
        Lan._count = getattr(Lan, "_count", 0) + 1
        base = f"{PREFIX}{os.getpid()}-{Lan._count}"
        self.bridge = f"{base}b"
        self.robots = [f"{base}r{i}" for i in range(robots)]
        self.made: list[str] = []
        try:
            self._build()
        except BaseException:
            self.close()
            raise

    @property
    def namespaces(self) -> list[str]:
        return [self.bridge, *self.robots]

    def ip(self, ns: str, *args: str) -> None:
        _run(IP, "-n", ns, *args)

    def _build(self) -> None:
        for ns in self.namespaces:
            _run(IP, "netns", "add", ns)
            self.made.append(ns)
            self.ip(ns, "link", "set", "lo", "up")
        b = self.bridge
        # No IGMP snooping: multicast (SPDP discovery) is flooded to every port.
        self.ip(b, "link", "add", "br0", "type", "bridge", "mcast_snooping", "0")
        self.ip(b, "addr", "add", f"{BRIDGE_ADDR}/24", "dev", "br0")
        self.ip(b, "link", "set", "br0", "up")
        self.ip(b, "route", "add", "224.0.0.0/4", "dev", "br0")
        for i, ns in enumerate(self.robots):
            # Made inside the bridge namespace, the peer moved straight into ns:
            # the root namespace never sees these links.
            self.ip(b, "link", "add", f"veth{i}", "type", "veth", "peer", "name", "eth0",
                    "netns", ns)  # fmt: skip
            self.ip(b, "link", "set", f"veth{i}", "master", "br0", "up")
            self.ip(ns, "addr", "add", f"{robot_addr(i)}/24", "dev", "eth0")
            self.ip(ns, "link", "set", "eth0", "up")
            self.ip(ns, "route", "add", "224.0.0.0/4", "dev", "eth0")

    def device(self, ns: str) -> str:
        """The namespace's link to the LAN: ``br0`` in the bridge namespace, else ``eth0``."""
        return "br0" if ns == self.bridge else "eth0"

    def add_rules(self, ns: str, loss_mod: int = 0, block_multicast: bool = False) -> None:
        """nftables in ``ns`` on its LAN device: count UDP datagrams both ways; drop
        one received datagram in ``loss_mod`` (at random) if ``loss_mod``; drop
        multicast both ways if ``block_multicast``.

        Loss is applied on receipt only (a drop on the output hook would make the
        sender's sendto fail instead of losing the datagram on the wire), so with
        the rule in every namespace each datagram crossing the LAN is lost with
        probability 1/loss_mod, once. Counters: udp_in, udp_out (before any drop),
        lost_in, mcast_in, mcast_out.
        """
        dev = self.device(ns)
        lines = ["table inet aes {"]
        lines += [f"  counter {c} {{ }}" for c in COUNTERS]
        for way, hook, match in (("in", "input", "iifname"), ("out", "output", "oifname")):
            lines += [
                f"  chain {hook} {{",
                f"    type filter hook {hook} priority 0; policy accept;",
                f'    {match} "{dev}" meta l4proto udp counter name udp_{way}',
            ]
            if block_multicast:
                lines.append(
                    f'    {match} "{dev}" ip daddr 224.0.0.0/4 counter name mcast_{way} drop'
                )
            if loss_mod and way == "in":
                lines.append(
                    f'    {match} "{dev}" meta l4proto udp numgen random mod {loss_mod} 0 '
                    "counter name lost_in drop"
                )
            lines.append("  }")
        lines.append("}")
        out = subprocess.run(
            [IP, "netns", "exec", ns, NFT, "-f", "-"],
            input="\n".join(lines) + "\n", capture_output=True, text=True, timeout=30,
        )  # fmt: skip
        if out.returncode != 0:
            raise RuntimeError(f"nft in {ns} failed: {out.stderr.strip()}\n" + "\n".join(lines))

    def counters(self, ns: str) -> dict[str, int]:
        """Packet counts of the nftables counters of :meth:`add_rules` in ``ns``."""
        out = _run(IP, "netns", "exec", ns, NFT, "-j", "list", "counters", "table", "inet", "aes")
        found = {}
        for item in json.loads(out.stdout)["nftables"]:
            if "counter" in item:
                found[item["counter"]["name"]] = int(item["counter"]["packets"])
        return found

    def link_packets(self, ns: str) -> dict[str, int]:
        """rx/tx packet counts of the namespace's LAN device (every protocol)."""
        dev = self.device(ns)
        stats = {}
        for way in ("rx", "tx"):
            out = _run(IP, "netns", "exec", ns, "cat",
                       f"/sys/class/net/{dev}/statistics/{way}_packets")  # fmt: skip
            stats[way] = int(out.stdout)
        return stats

    def exec_prefix(self, ns: str, **env: str) -> list[str]:
        """argv prefix running a command in ``ns`` with extra environment variables."""
        extra = [f"{k}={v}" for k, v in env.items()]
        return [IP, "netns", "exec", ns, *(["env", *extra] if extra else [])]

    def close(self) -> None:
        for ns in reversed(self.made):
            _kill_all(ns)
        for ns in reversed(self.made):
            _run(IP, "netns", "del", ns, check=False)
        self.made.clear()


# ----------------------------------------------------------------------------- observer


def observe(n: int, duration: float, out: Path, timeout: float) -> int:
    """Sample /swarm/poses and /swarm/alignment (see the module docstring).

    Returns 0 when ``duration`` s of sim time after every robot moved were
    sampled, 1 on the wall-clock ``timeout`` (what was sampled is written anyway).
    """
    import sys

    import numpy as np
    import pytest
    from std_msgs.msg import Float64

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run as a script
    from aes_ros.ros import interface as names
    from aes_ros.ros.qos import LATCHED
    from helpers.probe import Probe

    probe = Probe("observer").sample_poses(n)
    # (sim time of the last poses, ψ)
    alignment = probe.record(Float64, names.ALIGNMENT, LATCHED, lambda m: (probe.now, m.data))
    start = time.monotonic()
    t_go = None
    status = 1
    try:
        t_go = probe.wait_all_moving(timeout)
        print(f"observer: all {n} robots moving at sim time {t_go:.2f} s "
              f"(wall {time.monotonic() - start:.1f} s)", flush=True)  # fmt: skip
        probe.wait_sim(t_go + duration - 1e-6, timeout - (time.monotonic() - start))
        status = 0
    except pytest.fail.Exception as exc:
        print(f"observer: {exc}", flush=True)
    finally:
        try:
            probe.close()  # no more samples from here on
        finally:
            times = np.asarray(probe.times)
            np.savez(
                out,
                times=times,
                positions=np.asarray(probe.positions[: len(times)]).reshape(len(times), n, 2),
                headings=np.asarray(probe.headings[: len(times)]).reshape(len(times), n),
                alignment=np.asarray(alignment, dtype=float).reshape(-1, 2),
                t_go=np.nan if t_go is None else t_go,
                wall=time.monotonic() - start,
            )
    print(f"observer: {len(probe.times)} pose samples, {len(alignment)} alignment values, "
          f"status {status}", flush=True)  # fmt: skip
    return status


def main(argv: list[str] | None = None) -> int:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    obs = sub.add_parser("observe")
    obs.add_argument("--robots", type=int, required=True)
    obs.add_argument("--duration", type=float, required=True)
    obs.add_argument("--out", type=Path, required=True)
    obs.add_argument("--timeout", type=float, default=120.0)
    args = parser.parse_args(argv)
    return observe(args.robots, args.duration, args.out, args.timeout)


if __name__ == "__main__":
    raise SystemExit(main())
