"""Discovery of a launch's processes (:mod:`aes_ros.ros.discovery`, ``--discovery``): the
mode ``auto`` picks, the server's address and port, every process's environment, the lines
a user's shell needs, and where the server goes in the start order (nothing starts here,
except one short process to show the per-process environment)."""

from __future__ import annotations

import os
import socket
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from aes_ros import scenario
from aes_ros.ros import discovery as dds
from aes_ros.ros.launch.commands import start_order
from aes_ros.ros.launch.config import LaunchConfig, resolved_discovery
from aes_ros.ros.launch.events import EventLog
from aes_ros.ros.launch.processes import ProcessSet
from aes_ros.ros.launch.recovery import Backoff, RestartCommands
from aes_ros.ros.launch.supervision import Supervision, ready_signal

LOCAL = {"ROS_DOMAIN_ID": "42", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}


def config(robots: int = 9, **options) -> LaunchConfig:
    return LaunchConfig(scenario.load("linear").with_robots(robots), layout="single", **options)


@pytest.mark.parametrize(
    ("text", "expected"),
    [("127.0.0.1:11811", ("127.0.0.1", 11811)), ("lab-pc.local:7", ("lab-pc.local", 7))],
)
def test_an_address_is_host_and_port(text: str, expected: tuple[str, int]) -> None:
    assert dds.parse_address(text) == expected


@pytest.mark.parametrize("text", ["11811", "host:", ":11811", "host:0", "host:70000", "a:1;b:2"])
def test_a_bad_address_says_what_is_expected(text: str) -> None:
    with pytest.raises(ValueError, match=r"HOST:PORT|port must be"):
        dds.parse_address(text)


def test_auto_uses_a_server_for_large_swarms_or_when_one_is_given() -> None:
    large = dds.DISCOVERY_SERVER_FROM
    assert dds.resolved_mode("auto", large) == "server"
    assert dds.resolved_mode("auto", large - 1) == "simple"
    assert dds.resolved_mode("auto", 4, "10.0.0.2:11811") == "server"
    assert dds.resolved_mode("simple", 10 * large) == "simple"
    assert dds.resolved_mode("server", 1) == "server"
    assert resolved_discovery(config()) == "simple"
    assert resolved_discovery(config(discovery_port=11811)) == "server"
    assert resolved_discovery(config(discovery_server="10.0.0.2:11811")) == "server"
    assert resolved_discovery(config(discovery="server")) == "server"
    # whatever the layout: the one host of layout auto on two cores splits its robots over
    # participants behind a server (robot_node.host), which pays as two hosts do
    thousand = scenario.load("combined", {"dt": 0.05}).with_robots(1000)
    for layout in ("per-core", "auto", "single"):
        assert resolved_discovery(LaunchConfig(thousand, layout=layout, cores=2)) == "server"
    assert resolved_discovery(LaunchConfig(thousand, discovery="simple")) == "simple"


@pytest.mark.parametrize(
    ("options", "field"),
    [
        ({"discovery": "multicast"}, "discovery"),
        ({"discovery_server": "nowhere"}, "discovery_server"),
        ({"discovery": "simple", "discovery_server": "10.0.0.2:11811"}, "discovery_server"),
        ({"discovery": "simple", "discovery_port": 11811}, "discovery_port"),
        ({"discovery_port": 0}, "discovery_port"),
        ({"discovery_server": "10.0.0.2:11811", "discovery_port": 11811}, "discovery_port"),
    ],
)
def test_options_that_do_not_fit_are_refused_naming_the_field(options: dict, field: str) -> None:
    with pytest.raises(ValueError, match=f"^{field}:"):
        config(**options)


def test_a_started_server_listens_where_discovery_may_reach(monkeypatch) -> None:
    """On loopback when discovery is kept on this host, else on the one interface toward
    other hosts (robots there join), never on every interface; this host's processes
    use the address it listens on. The port is free: the server can bind it."""
    local = dds.plan("server", 9, LOCAL)
    assert local.starts_server and local.listen == "127.0.0.1"
    assert local.address == f"127.0.0.1:{local.port}"
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", local.port))
    monkeypatch.setattr(dds, "host_address", lambda: "10.0.0.5")
    wide = dds.plan("server", 9, {"ROS_DOMAIN_ID": "42"}, port=11811)
    assert (wide.listen, wide.address) == ("10.0.0.5", "10.0.0.5:11811")
    monkeypatch.setattr(dds, "host_address", lambda: "lab-pc")  # no route to other hosts
    alone = dds.plan("server", 9, {"ROS_DOMAIN_ID": "42"}, port=11811)
    assert (alone.listen, alone.address) == ("127.0.0.1", "127.0.0.1:11811")
    existing = dds.plan("auto", 9, LOCAL, server="10.0.0.2:11811")
    assert not existing.starts_server and existing.address == "10.0.0.2:11811"
    assert dds.plan("auto", 9, LOCAL) == dds.Discovery()


def test_processes_are_clients_and_only_the_asked_ones_super_clients() -> None:
    caller = {**LOCAL, "ROS_DISCOVERY_SERVER": "10.9.9.9:1", "ROS_SUPER_CLIENT": "true"}
    server = dds.Discovery("server", "127.0.0.1:5000", "127.0.0.1")
    plain = server.client_environment(caller)
    assert plain["ROS_DISCOVERY_SERVER"] == "127.0.0.1:5000"
    assert "ROS_SUPER_CLIENT" not in plain and plain["ROS_DOMAIN_ID"] == "42"
    assert server.client_environment(caller, super_client=True)["ROS_SUPER_CLIENT"] == "true"
    # simple discovery: a caller's server would make every process its client
    simple = dds.Discovery().client_environment(caller)
    assert "ROS_DISCOVERY_SERVER" not in simple and "ROS_SUPER_CLIENT" not in simple


def test_a_participant_of_simple_discovery_sets_the_server_empty() -> None:
    """Fast DDS keeps the last server it read in a process; "" resets it, removing the
    variable would not."""
    assert dds.Discovery().participant_variables() == {
        "ROS_DISCOVERY_SERVER": "",
        "ROS_SUPER_CLIENT": None,
    }
    server = dds.Discovery("server", "127.0.0.1:5000")
    assert server.participant_variables(super_client=True) == {
        "ROS_DISCOVERY_SERVER": "127.0.0.1:5000",
        "ROS_SUPER_CLIENT": "true",
    }


def test_the_shell_lines_are_what_ros2_commands_need() -> None:
    server = dds.Discovery("server", "127.0.0.1:5000", "127.0.0.1")
    assert server.shell_lines(LOCAL) == [
        "export ROS_DISCOVERY_SERVER=127.0.0.1:5000",
        "export ROS_SUPER_CLIENT=true",
        "export ROS_DOMAIN_ID=42",
        "export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST",
    ]
    assert server.shell_lines({}) == server.shell_lines(LOCAL)[:2]
    assert dds.Discovery().shell_lines({}) == ["unset ROS_DISCOVERY_SERVER ROS_SUPER_CLIENT"]
    script = server.script(LOCAL)
    assert script.endswith("\n".join(server.shell_lines(LOCAL)) + "\n")
    assert "other hosts" not in script  # a loopback server is for this host only
    wide = dds.Discovery("server", "10.0.0.5:5000", "10.0.0.5").script(LOCAL)
    assert "# robots on other hosts: ROS_DISCOVERY_SERVER=10.0.0.5:5000" in wide


def test_the_listen_command_prints_where_a_server_here_would_listen(capsys, monkeypatch) -> None:
    monkeypatch.setattr(dds, "host_address", lambda: "10.0.0.5")
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    assert dds.main(["listen"]) == 0 and capsys.readouterr().out == "127.0.0.1\n"
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET")
    assert dds.main(["listen"]) == 0 and capsys.readouterr().out == "10.0.0.5\n"


def test_the_env_command_prints_the_script(capsys: pytest.CaptureFixture[str], monkeypatch) -> None:
    for key, value in LOCAL.items():
        monkeypatch.setenv(key, value)
    assert dds.main(["env", "127.0.0.1:5000"]) == 0
    out = capsys.readouterr().out
    assert out == dds.Discovery("server", "127.0.0.1:5000").script(LOCAL)


def test_the_server_starts_before_anything_else_and_restarts_on_its_port(tmp_path: Path) -> None:
    files = (tmp_path / "s.yaml", tmp_path / "r.yaml", tmp_path / "arena.yaml")
    cfg = config(record=tmp_path / "bag", dashboard=0, discovery="server")
    own = dds.Discovery("server", "127.0.0.1:5000", "127.0.0.1")
    order = start_order(cfg, *files, own)
    assert next(iter(order.by_name)) == dds.SERVER_PROCESS
    argv = order.discovery_server.argv
    assert argv == [sys.executable, "-m", "aes_ros.ros.discovery", "serve",
                    "--port", "5000", "--listen", "127.0.0.1"]  # fmt: skip
    restart = RestartCommands(order.by_name, None, tmp_path / "w.npz", None, 9)
    assert restart(dds.SERVER_PROCESS) == argv  # the clients know that port
    assert ready_signal(dds.SERVER_PROCESS) == dds.SERVER_READY
    assert start_order(cfg, *files, dds.Discovery("server", "10.0.0.2:1")).discovery_server is None
    assert start_order(cfg, *files).discovery_server is None


def test_the_server_finds_the_wheels_libraries_and_talks_udp_only() -> None:
    program = dds.server_program()
    env = dds.server_environment(
        {"ROS_DISCOVERY_SERVER": "x:1", "ROS_SUPER_CLIENT": "true", "LD_LIBRARY_PATH": "/opt/x"},
        program,
    )
    dirs = env["LD_LIBRARY_PATH"].split(":")
    assert any(list(Path(d).glob("libfastrtps.so*")) for d in dirs), dirs
    assert any(list(Path(d).glob("libtinyxml2*")) for d in dirs), dirs
    assert dirs[-1] == "/opt/x"
    assert env["FASTDDS_BUILTIN_TRANSPORTS"] == "UDPv4"
    assert "ROS_DISCOVERY_SERVER" not in env and "ROS_SUPER_CLIENT" not in env


def test_a_process_gets_its_own_variables_at_every_start(tmp_path: Path) -> None:
    procs = ProcessSet(tmp_path, {"ROS_SUPER_CLIENT": "false"})
    procs.env_for["recorder"] = {"ROS_SUPER_CLIENT": "true"}
    show = [sys.executable, "-c", "import os; print(os.environ['ROS_SUPER_CLIENT'])"]
    for name in ("recorder", "robot_host_0", "recorder"):
        procs.start(name, show).proc.wait(30)
    assert (tmp_path / "recorder.log").read_text().split() == ["true", "true"]
    assert (tmp_path / "robot_host_0.log").read_text().split() == ["false"]


def test_the_server_forgets_quickly_and_comes_back_after_its_lease() -> None:
    """Its profile makes it a server with a short lease; the launcher restarts it only once
    every client has dropped it (a client that still holds it ignores what a new one
    with the same GUID sends: new participants were never matched)."""
    root = ET.parse(dds.SERVER_PROFILE).getroot()
    ns = {"p": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
    config = root.find(".//p:discovery_config", ns)
    assert config.find("p:discoveryProtocol", ns).text == "SERVER"
    lease = config.find("p:leaseDuration", ns)
    seconds = int(lease.find("p:sec", ns).text) + int(lease.find("p:nanosec", ns).text) * 1e-9
    assert seconds == dds.SERVER_LEASE < dds.SERVER_RESTART_DELAY


def test_serve_becomes_the_server_with_its_profile(monkeypatch: pytest.MonkeyPatch) -> None:
    became: list = []

    def execve(program: str, argv: list[str], env: dict[str, str]) -> None:
        became.append((program, argv, env, Path(argv[-1]).read_text()))

    monkeypatch.setattr(os, "execve", execve)
    monkeypatch.setenv("ROS_DISCOVERY_SERVER", "10.9.9.9:1")
    dds.serve(5000, "localhost")
    ((program, argv, env, profile),) = became
    fd = int(argv[-1].rsplit("/", 1)[1])
    assert os.get_inheritable(fd)  # the server opens it after the exec
    os.close(fd)
    assert program == dds.server_program() and argv[0] == program
    assert argv[1:-1] == ["-i", "0", "-l", "127.0.0.1", "-p", "5000", "-x"]
    assert profile == dds.server_profile("127.0.0.1")
    assert "ROS_DISCOVERY_SERVER" not in env and env["FASTDDS_BUILTIN_TRANSPORTS"] == "UDPv4"


def test_the_servers_transport_is_allowed_on_its_address_only() -> None:
    """``-l`` alone would still bind every interface: the profile allows one address."""
    ns = {"p": dds.PROFILE_NS}
    root = ET.fromstring(dds.server_profile("10.0.0.5"))
    (interface,) = root.findall(
        ".//p:transport_descriptor/p:interfaces/p:allowlist/p:interface", ns
    )
    assert interface.get("name") == "10.0.0.5"
    rtps = root.find(".//p:rtps", ns)
    assert rtps.find("p:useBuiltinTransports", ns).text == "false"
    assert rtps.find("p:userTransports/p:transport_id", ns).text == "listen"
    assert rtps.find(".//p:discoveryProtocol", ns).text == "SERVER"  # the lease profile kept
    every = ET.fromstring(dds.server_profile(dds.ANY_ADDRESS))
    assert every.find(".//p:transport_descriptor", ns) is None


def test_a_dead_server_is_restarted_after_its_lease(tmp_path: Path) -> None:
    procs = ProcessSet(tmp_path)
    events = EventLog(tmp_path / "events.csv", lambda _line: None)
    supervision = Supervision(
        procs, events, "respawn", lambda _name: [], lambda: None,
        backoff_for={dds.SERVER_PROCESS: Backoff(first=dds.SERVER_RESTART_DELAY)},
    )  # fmt: skip
    for name in (dds.SERVER_PROCESS, "robot_host_0"):
        procs.start(name, [sys.executable, "-c", "pass"]).proc.wait(30)
    supervision.check()
    actions = {e.process: e.action for e in events.events}
    assert actions == {
        dds.SERVER_PROCESS: f"restart in {dds.SERVER_RESTART_DELAY:g} s",
        "robot_host_0": "restart in 0.5 s",
    }
    events.close()
