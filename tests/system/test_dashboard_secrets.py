"""The dashboard's token stays with its owner: ``aes-swarm launch --dashboard`` prints the
URL with the token on its terminal, and the token is on no process's command line, in no
log file (the launch's logs under ``--out``, ROS's file logs), on ``/rosout``, and in no
parameter of ``/dashboard``; the URL printed does steer, the address alone does not.
"""

from __future__ import annotations

import re
import signal
from pathlib import Path

from helpers.dashboard import Viewers, launch_with_dashboard
from helpers.ros_env import find_process
from rcl_interfaces.msg import Log
from rcl_interfaces.srv import GetParameters, ListParameters
from rclpy.parameter import parameter_value_to_python
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from aes_ros.ros import interface as names

ROSOUT = QoSProfile(
    depth=1000, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)


def command_lines() -> dict[int, bytes]:
    """Every process's command line on this machine (as ``ps`` shows them to anyone)."""
    found = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                found[int(entry.name)] = (entry / "cmdline").read_bytes()
            except OSError:
                pass  # gone meanwhile
    return found


def test_the_token_is_only_on_the_owners_terminal(spawn, probe, tmp_path):
    rosout = probe.record(Log, "/rosout", ROSOUT)
    ros_logs = tmp_path / "ros_logs"
    spawn.env = {**spawn.env, "ROS_LOG_DIR": str(ros_logs)}
    out = tmp_path / "out"
    launcher, url = launch_with_dashboard(spawn, out, 4)
    token = re.search(r"\?token=([\w-]+)$", url).group(1)
    assert len(token) >= 16  # 192 random bits, made up by the launcher

    # the node said where it listens, without the token
    def ready() -> list[str]:
        return [m.msg for m in rosout if m.name == names.DASHBOARD_NODE and "at http" in m.msg]

    probe.wait(ready, 20.0, "the dashboard's ready line on /rosout")
    assert ready()[0].endswith(url.split("?")[0])

    # command lines: of this launch's processes (the dashboard's among them) and all others
    dashboard = find_process(spawn.env["ROS_DOMAIN_ID"], "aes-dashboard")
    lines = command_lines()
    assert dashboard in lines and launcher.pid in lines
    assert [pid for pid, line in lines.items() if token.encode() in line] == []

    # parameters: no token among them, nor as any value
    node = f"/{names.DASHBOARD_NODE}"
    listed = probe.call(
        ListParameters, f"{node}/list_parameters", ListParameters.Request()
    ).result.names
    assert "host" in listed and not any("token" in name for name in listed)
    request = GetParameters.Request(names=listed)
    values = probe.call(GetParameters, f"{node}/get_parameters", request).values
    assert all(token not in str(parameter_value_to_python(v)) for v in values)

    # the URL steers; the same page without the token only watches
    with_token, without = Viewers(url), Viewers(url.split("?")[0])
    try:
        assert with_token.send({"type": "sim", "action": "pause"})["ok"]
        refused = without.send({"type": "sim", "action": "resume"})
        assert not refused["ok"] and "no token" in refused["message"]
        assert with_token.send({"type": "sim", "action": "resume"})["ok"]
    finally:
        with_token.close()
        without.close()

    # logs, once written out at the end: the launch's (every process's output, its
    # events) and ROS's file logs; /rosout
    launcher.send_signal(signal.SIGINT)
    assert launcher.wait(60) == 0
    logs = [p for p in [*out.rglob("*"), *ros_logs.rglob("*")] if p.is_file()]
    assert any(p.name == f"{names.DASHBOARD_NODE}.log" for p in logs), sorted(logs)
    ros_log = list(ros_logs.rglob(f"*_{dashboard}_*.log"))  # the dashboard's, by its pid
    assert ros_log and "dashboard at http" in ros_log[0].read_text()
    assert [p for p in logs if token.encode() in p.read_bytes()] == []
    assert [m.msg for m in rosout if token in m.msg] == []
    # the launcher's terminal (here its log) is the one place the token is
    assert f"launch: dashboard at {url}" in spawn.log(launcher).read_text()
