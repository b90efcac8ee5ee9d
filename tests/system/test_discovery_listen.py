"""Where the launch's discovery server listens: under ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``
on 127.0.0.1 only, as the range says (:func:`aes_ros.ros.discovery.serve`).

The server is started with the launcher's own command line; its UDP sockets are read
from ``/proc``: its port, and every other port it binds on loopback, are bound on
127.0.0.1 alone, and a datagram sent to them through this host's other interface finds
no socket (the kernel answers "port unreachable"). Its remaining sockets are Fast DDS's
send-only sockets on ephemeral ports, which nothing reads.
"""

from __future__ import annotations

import os
import socket
from pathlib import Path

import pytest
from helpers.ros_env import wait_for

from aes_ros.ros import discovery as dds


def udp_sockets(pid: int) -> list[tuple[str, int]]:
    """(address, port) of every IPv4 UDP socket process ``pid`` holds."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        target = os.readlink(fd)
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    found = []
    for line in Path("/proc/net/udp").read_text().splitlines()[1:]:
        fields = line.split()
        if fields[9] in inodes:
            hex_address, hex_port = fields[1].split(":")
            address = socket.inet_ntoa(int(hex_address, 16).to_bytes(4, "little"))
            found.append((address, int(hex_port, 16)))
    return found


def test_a_localhost_server_listens_on_loopback_only(spawn, ros_env) -> None:
    plan = dds.plan("server", 9, ros_env)
    assert plan.listen == "127.0.0.1" and plan.address == f"127.0.0.1:{plan.port}"
    server = spawn.start(*dds.server_argv(plan.port, plan.listen), name=dds.SERVER_PROCESS)
    log = spawn.log(server)
    assert wait_for(lambda: dds.SERVER_READY in log.read_text(), 30), log.read_text()

    sockets = udp_sockets(server.pid)
    loopback = {port for address, port in sockets if address == "127.0.0.1"}
    assert plan.port in loopback, sockets
    assert [(a, p) for a, p in sockets if p in loopback and a != "127.0.0.1"] == [], sockets

    other = dds.listen_address({})  # this host's address toward others, if it has one
    if other == "127.0.0.1":
        pytest.skip("no interface but loopback to send from")
    for port in sorted(loopback):
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.settimeout(5)
            probe.connect((other, port))
            probe.send(b"RTPS")
            with pytest.raises(ConnectionRefusedError):
                probe.recv(1)
