"""How the processes of a swarm find each other: Fast DDS's simple discovery, or a
discovery server (``aes-swarm launch --discovery``, ``scripts/start_swarm.sh -d``).

With a **discovery server** every participant is a client that talks to the server only,
and the server relays to each client the endpoints on the topics it uses. The server is
the ``ros_fastrtps`` wheel's ``fast-discovery-server``, id 0, on one UDP port, run by
:func:`serve` (``python -m aes_ros.ros.discovery serve``: the wheel's binary does not
find its own libraries), bound to one address (:func:`host_address`, or 127.0.0.1 under
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``). A process becomes a client through
``ROS_DISCOVERY_SERVER`` (a super client with ``ROS_SUPER_CLIENT=true``), set or cleared
by :func:`set_environ`; Fast DDS keeps the last value it read, so ``""`` is
needed to go back to simple discovery. A dead server is restarted only after
:data:`SERVER_RESTART_DELAY`, once its clients have forgotten it. The whole story:
docs/ros.md#large-swarms-the-discovery-server.
"""

from __future__ import annotations

import argparse
import ipaddress
import os
import shlex
import socket
import sys
import sysconfig
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from aes_ros.ros.programs import LaunchError, executable

#: What ``--discovery`` may ask for.
DISCOVERY_MODES = ("auto", "simple", "server")
#: ``auto`` uses a discovery server from this many robots: from here a server starts the
#: swarm faster, below it it gains nothing and simple discovery keeps ``ros2`` working
#: without any setup (docs/performance.md#through-a-discovery-server).
DISCOVERY_SERVER_FROM = 400
#: The variables that make a participant a client (super client) of a discovery server.
SERVER_VARIABLE = "ROS_DISCOVERY_SERVER"
SUPER_CLIENT_VARIABLE = "ROS_SUPER_CLIENT"
#: The process name of the launch's discovery server (its log: ``discovery_server.log``).
SERVER_PROCESS = "discovery_server"
#: What ``fast-discovery-server`` prints once it listens.
SERVER_READY = "Server is running"
#: The server's id: clients address server ``k`` by the ``k``-th entry of
#: ``ROS_DISCOVERY_SERVER``; one server, so 0 and a plain ``HOST:PORT``.
SERVER_ID = 0
#: The server program of the ``ros_fastrtps`` wheel.
SERVER_PROGRAM = "fast-discovery-server"
#: The server's Fast DDS profile: its lease, SERVER_LEASE [s] (fastdds_server_profile.xml
#: says why), after which its clients forget a server that died.
SERVER_PROFILE = Path(__file__).resolve().parent / "fastdds_server_profile.xml"
SERVER_LEASE = 2.0
#: The XML namespace of Fast DDS profiles.
PROFILE_NS = "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"
#: ``--listen`` for every interface.
ANY_ADDRESS = "0.0.0.0"
#: Wall seconds before a server that died is started again: its lease and a margin, so
#: that no client takes the new server for the old one.
SERVER_RESTART_DELAY = SERVER_LEASE + 1.0


def parse_address(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (an IPv4 address or a host name, a UDP port 1 … 65535) as a pair;
    ValueError saying what is wrong otherwise."""
    host, sep, port = text.strip().rpartition(":")
    if not sep or not host or ";" in text or "[" in text:
        raise ValueError(f"{text!r}: expected HOST:PORT, e.g. 192.168.1.10:11811")
    if not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ValueError(f"{text!r}: the port must be a number 1 … 65535")
    return host, int(port)


def resolved_mode(mode: str, num_robots: int, server: str | None = None) -> str:
    """``simple`` or ``server``: what ``mode`` means for ``num_robots`` robots.

    ``auto`` is ``server`` when an existing server is given, or from
    :data:`DISCOVERY_SERVER_FROM` robots; else ``simple``."""
    if mode == "auto":
        return "server" if server or num_robots >= DISCOVERY_SERVER_FROM else "simple"
    return mode


def is_localhost(env: dict[str, str]) -> bool:
    """Discovery kept on this host (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``)."""
    return env.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip().upper() == "LOCALHOST"


def free_udp_port(host: str = "127.0.0.1") -> int:
    """A UDP port nobody listens on at ``host`` now (the kernel's choice)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind((host, 0))
        return int(sock.getsockname()[1])


def host_address() -> str:
    """This host's address as other hosts see it, best guess (the interface of the
    default route; no packet is sent), else its name."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        try:
            sock.connect(("192.0.2.1", 9))  # TEST-NET-1: only picks the route
            return str(sock.getsockname()[0])
        except OSError:
            return socket.gethostname()


@dataclass(frozen=True)
class Discovery:
    """The discovery of one swarm.

    mode : ``simple`` or ``server``.
    address : ``HOST:PORT`` of the server the processes use (None with simple discovery).
    listen : the address the server started for this swarm listens on (127.0.0.1, or
        one interface's address); None when an existing server is used.
    """

    mode: str = "simple"
    address: str | None = None
    listen: str | None = None

    @property
    def starts_server(self) -> bool:
        """This swarm starts its own server (else it uses one, or none)."""
        return self.listen is not None

    @property
    def port(self) -> int | None:
        return parse_address(self.address)[1] if self.address else None

    def client_environment(self, env: dict[str, str], super_client: bool = False) -> dict[str, str]:
        """``env`` for a process of this swarm: pointed at the server (a super client
        if asked), or with neither variable under simple discovery (a caller's
        ``ROS_DISCOVERY_SERVER`` would make the processes clients)."""
        out = {k: v for k, v in env.items() if k not in (SERVER_VARIABLE, SUPER_CLIENT_VARIABLE)}
        if self.address is not None:
            out[SERVER_VARIABLE] = self.address
            if super_client:
                out[SUPER_CLIENT_VARIABLE] = "true"
        return out

    def participant_variables(self, super_client: bool = False) -> dict[str, str | None]:
        """What to set in ``os.environ`` (None: remove) while a participant of this
        process is made (module docstring: Fast DDS keeps the last server it read, so
        simple discovery sets it to ``""`` rather than removing it)."""
        if self.address is None:
            return {SERVER_VARIABLE: "", SUPER_CLIENT_VARIABLE: None}
        return {
            SERVER_VARIABLE: self.address,
            SUPER_CLIENT_VARIABLE: "true" if super_client else None,
        }

    def shell_lines(self, env: dict[str, str]) -> list[str]:
        """The lines a shell needs for ``ros2`` commands on this swarm: the server and
        super client (or neither, for simple discovery), the ROS domain and discovery
        range of ``env`` if set; and for a server on every interface, how other hosts
        reach it."""
        if self.address is None:
            lines = [f"unset {SERVER_VARIABLE} {SUPER_CLIENT_VARIABLE}"]
        else:
            lines = [
                f"export {SERVER_VARIABLE}={shlex.quote(self.address)}",
                f"export {SUPER_CLIENT_VARIABLE}=true",
            ]
        for name in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE"):
            if env.get(name):
                lines.append(f"export {name}={shlex.quote(env[name])}")
        return lines

    def script(self, env: dict[str, str]) -> str:
        """``ros_env.sh``: :meth:`shell_lines` with comments, to be sourced."""
        head = [
            "# The environment of a shell for ros2 commands on this swarm: . ros_env.sh",
            "# (then `ros2 daemon stop`: a running daemon keeps its old discovery settings)",
        ]
        if self.starts_server and self.listen != "127.0.0.1":
            where = host_address() if self.listen == ANY_ADDRESS else self.listen
            head.append(f"# robots on other hosts: {SERVER_VARIABLE}={where}:{self.port}")
        return "\n".join([*head, *self.shell_lines(env)]) + "\n"


def plan(
    mode: str,
    num_robots: int,
    env: dict[str, str],
    server: str | None = None,
    port: int | None = None,
) -> Discovery:
    """The discovery of a swarm of ``num_robots`` robots started from ``env``: ``mode``
    resolved (:func:`resolved_mode`); with ``server`` (``HOST:PORT``) that existing
    server, else a new one on ``port`` (None: a free one), on 127.0.0.1 when ``env``
    keeps discovery on this host, else on this host's address toward other hosts
    (:func:`listen_address`); this host's processes reach it where it listens."""
    if resolved_mode(mode, num_robots, server) == "simple":
        return Discovery()
    if server is not None:
        host, number = parse_address(server)
        return Discovery("server", f"{host}:{number}")
    listen = listen_address(env)
    number = free_udp_port(listen) if port is None else int(port)
    return Discovery("server", f"{listen}:{number}", listen)


def listen_address(env: dict[str, str]) -> str:
    """Where a server started from ``env`` listens: 127.0.0.1 when ``env`` keeps discovery
    on this host, else :func:`host_address`, or 127.0.0.1 when this host has no route to
    others (then no other host could reach it anyway)."""
    if is_localhost(env):
        return "127.0.0.1"
    address = host_address()
    try:
        return address if not ipaddress.IPv4Address(address).is_loopback else "127.0.0.1"
    except ValueError:  # a host name: no interface toward other hosts
        return "127.0.0.1"


# ----------------------------------------------------------------------------- the server


def server_argv(port: int, listen: str, python: str = sys.executable) -> list[str]:
    """The command line that runs the server (:func:`serve` under ``python``)."""
    return [python, "-m", "aes_ros.ros.discovery", "serve", "--port", str(port), "--listen", listen]


def server_program() -> str:
    """``fast-discovery-server`` of this environment (next to the interpreter), else PATH."""
    try:
        return executable(SERVER_PROGRAM)
    except LaunchError:
        raise FileNotFoundError(
            f"{SERVER_PROGRAM} not found (it comes with ros_fastrtps)"
        ) from None


def server_environment(env: dict[str, str], program: str) -> dict[str, str]:
    """``env`` for the server: the ``ros_fastrtps`` wheel's libraries on the library path
    (its binary's run path points elsewhere), UDP only (nothing left in /dev/shm when it
    is killed) and no client variables."""
    dirs = []
    for key in ("platlib", "purelib"):
        libs = Path(sysconfig.get_paths()[key]) / "ros_fastrtps.libs"
        if libs.is_dir() and str(libs) not in dirs:
            dirs.append(str(libs))
    lib = Path(program).resolve().parent.parent / "lib"
    if any(lib.glob("libfastrtps.so*")):
        dirs.append(str(lib))
    if env.get("LD_LIBRARY_PATH"):
        dirs.append(env["LD_LIBRARY_PATH"])
    out = {k: v for k, v in env.items() if k not in (SERVER_VARIABLE, SUPER_CLIENT_VARIABLE)}
    out["FASTDDS_BUILTIN_TRANSPORTS"] = "UDPv4"
    if dirs:
        out["LD_LIBRARY_PATH"] = os.pathsep.join(dirs)
    return out


def server_profile(listen: str) -> str:
    """The server's profile (:data:`SERVER_PROFILE`) for a server on ``listen``: unless
    that is 0.0.0.0, with one UDPv4 transport allowed only on that address (``-l`` alone
    sets where the server is announced, but Fast DDS still binds its sockets to every
    interface)."""
    ET.register_namespace("", PROFILE_NS)
    root = ET.parse(SERVER_PROFILE).getroot()
    if listen != ANY_ADDRESS:

        def tag(name: str) -> str:
            return f"{{{PROFILE_NS}}}{name}"

        descriptors = ET.Element(tag("transport_descriptors"))
        descriptor = ET.SubElement(descriptors, tag("transport_descriptor"))
        ET.SubElement(descriptor, tag("transport_id")).text = "listen"
        ET.SubElement(descriptor, tag("type")).text = "UDPv4"
        allowlist = ET.SubElement(ET.SubElement(descriptor, tag("interfaces")), tag("allowlist"))
        ET.SubElement(allowlist, tag("interface"), name=listen, netmask_filter="OFF")
        root.insert(0, descriptors)
        rtps = root.find(f".//{tag('rtps')}")
        assert rtps is not None, SERVER_PROFILE
        users = ET.Element(tag("userTransports"))
        ET.SubElement(users, tag("transport_id")).text = "listen"
        builtin = ET.Element(tag("useBuiltinTransports"))
        builtin.text = "false"
        rtps[0:0] = [users, builtin]
    return ET.tostring(root, encoding="unicode", xml_declaration=True)


def serve(port: int, listen: str) -> None:
    """Become the discovery server on ``listen`` (an IPv4 address or a host name, 0.0.0.0
    for every interface) and UDP ``port``.

    ``exec``: the process is the server, its pid the server's, so that a signal to it
    reaches the server. Its profile (:func:`server_profile`, given with ``-x``: without
    it the server takes Fast DDS's built-in defaults, not the default profile of the
    environment) is an in-memory file the server inherits. Without a backup: the server's
    ``-b`` (restore its state when restarted) crashed at the restart with these wheels
    (a malloc assertion in Fast DDS 2.14.5); its short lease does the job instead."""
    program = server_program()
    address = socket.gethostbyname(listen)  # the allowlist takes addresses, not names
    profile = os.memfd_create("aes_swarm_discovery_server.xml", 0)
    os.write(profile, server_profile(address).encode())
    os.set_inheritable(profile, True)
    path = f"/proc/self/fd/{profile}"
    argv = [program, "-i", str(SERVER_ID), "-l", address, "-p", str(port), "-x", path]
    os.execve(program, argv, server_environment(dict(os.environ), program))


def set_environ(values: dict[str, str | None]) -> None:
    """Set each variable of ``values`` in ``os.environ`` (None: remove it), as
    :meth:`Discovery.participant_variables` gives them."""
    for name, value in values.items():
        if value is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = value


def main(argv: list[str] | None = None) -> int:
    """``serve``: run a server; ``port``: print a free UDP port; ``listen``: print where a
    server would listen; ``env ADDRESS``: print the shell lines for a swarm on that server
    (``scripts/start_swarm.sh`` uses them)."""
    parser = argparse.ArgumentParser(prog="python -m aes_ros.ros.discovery")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("serve", help="run fast-discovery-server (id 0)")
    run.add_argument("--port", type=int, required=True)
    run.add_argument(
        "--listen", default=None, metavar="ADDRESS",
        help="the one address to listen on (0.0.0.0: every interface; default: "
        "127.0.0.1 under ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, else this host's address)",
    )  # fmt: skip
    free = sub.add_parser("port", help="print a free UDP port")
    free.add_argument("--listen", default="127.0.0.1")
    sub.add_parser("listen", help="print the address a server started here would listen on")
    lines = sub.add_parser("env", help="print ros_env.sh: the shell lines for ros2 commands")
    lines.add_argument("address", help="HOST:PORT of the server")
    lines.add_argument("--listen", default=None, help="what the server listens on, if started")
    args = parser.parse_args(argv)
    if args.command == "serve":
        serve(args.port, args.listen or listen_address(dict(os.environ)))
    elif args.command == "port":
        print(free_udp_port(args.listen))
    elif args.command == "listen":
        print(listen_address(dict(os.environ)))
    else:
        parse_address(args.address)
        print(Discovery("server", args.address, args.listen).script(dict(os.environ)), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
