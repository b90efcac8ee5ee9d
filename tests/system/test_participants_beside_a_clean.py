"""Fast DDS participants beside a shared-memory clean keep their ports.

A clean of one domain (a test's teardown, a launcher's stop, the reaper) runs beside
participants of other domains that are starting: the ports from 7000 are shared by
every domain. A participant that lost a port to such a clean never heard a message
on it (seen in CI: a test's probe got no pose in 120 s). A clean in another PID
namespace (a container sharing ``/dev/shm``) sees none of the participant's
processes, mappings or locks in its ``/proc``, and must leave its ports too.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from helpers.probe import Probe
from helpers.ros_env import reserved_domain_id, ros_variables
from std_msgs.msg import String

from aes_ros.ros.launch.shared_memory import clean_shared_memory

#: Participants started one after another, each with new ports.
PARTICIPANTS = 8

#: Passes of the clean of another domain, as fast as they go, until killed.
CLEANER = """
import sys
from aes_ros.ros.launch.shared_memory import remove_abandoned_ports
print("cleaning", flush=True)
while True:
    remove_abandoned_ports(int(sys.argv[1]))
"""

#: Starts participants, then reports the shared-memory files they map, and which of
#: them were removed under them.
STARTER = """
import json, sys, time
from pathlib import Path
import rclpy
from rclpy.signals import SignalHandlerOptions
contexts, nodes = [], []  # kept: a node's participant goes with it
for k in range(int(sys.argv[1])):
    context = rclpy.Context()
    rclpy.init(args=[], context=context, signal_handler_options=SignalHandlerOptions.NO)
    nodes.append(rclpy.create_node(f"starter_{k}", context=context))
    contexts.append(context)
    time.sleep(0.2)
time.sleep(1.0)
maps = [line.split(None, 5)[-1] for line in Path("/proc/self/maps").read_text().splitlines()]
mapped = sorted({m for m in maps if m.startswith("/dev/shm/fastrtps_port")})
print(json.dumps({"mapped": mapped, "removed": [m for m in mapped if "(deleted)" in m]}))
for context in contexts:
    rclpy.try_shutdown(context=context)
"""


def test_participants_starting_beside_a_clean_of_another_domain_keep_their_ports(
    ros_env: dict[str, str],
) -> None:
    with reserved_domain_id() as other:
        cleaner = subprocess.Popen(
            [sys.executable, "-c", CLEANER, str(other)],
            env={**ros_env, **ros_variables(other)}, stdout=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            assert cleaner.stdout is not None and cleaner.stdout.readline() == "cleaning\n"
            out = subprocess.run(
                [sys.executable, "-c", STARTER, str(PARTICIPANTS)],
                env=ros_env, capture_output=True, text=True, timeout=120,
            )  # fmt: skip
        finally:
            cleaner.kill()
            cleaner.wait()
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout.strip().splitlines()[-1])
    shared = [m for m in report["mapped"] if int(m.split("port")[1].split()[0]) < 7400]
    assert len(shared) >= PARTICIPANTS, report  # each still maps its port of all domains
    assert report["removed"] == [], report


#: A listener that reports the shared-memory files it maps, and touches a file once it
#: hears a message.
LISTENER = """
import json, sys, time
from pathlib import Path
import rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("listener_beside_a_clean")
heard = Path(sys.argv[1])
node.create_subscription(String, "beside_a_clean", lambda m: heard.touch(), 10)
deadline = time.monotonic() + 1.0
while time.monotonic() < deadline:
    rclpy.spin_once(node, timeout_sec=0.1)
maps = Path("/proc/self/maps").read_text().splitlines()
print(json.dumps(sorted({m.split()[-1] for m in maps if "/dev/shm/fastrtps" in m})), flush=True)
rclpy.spin(node)
"""

#: The clean, in a PID namespace of its own: it says how many processes it sees.
CLEAN_ELSEWHERE = """
import os, sys
from aes_ros.ros.launch.shared_memory import clean_shared_memory
print(sum(name.isdigit() for name in os.listdir("/proc")), flush=True)
clean_shared_memory(int(sys.argv[1]), settle=0.0)
"""

UNSHARE = ["unshare", "--pid", "--fork", "--mount-proc"]


def _unshare_works() -> bool:
    try:
        return subprocess.run([*UNSHARE, "true"], capture_output=True, timeout=30).returncode == 0
    except (OSError, subprocess.SubprocessError):
        return False


@pytest.mark.skipif(not _unshare_works(), reason="unshare --pid needs root (CAP_SYS_ADMIN)")
def test_a_clean_in_another_pid_namespace_leaves_a_live_participant_its_ports(
    ros_env: dict[str, str], tmp_path: Path
) -> None:
    heard = tmp_path / "heard"
    listener = subprocess.Popen(
        [sys.executable, "-c", LISTENER, str(heard)],
        env=ros_env, stdout=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip
    try:
        assert listener.stdout is not None
        files = [Path(name) for name in json.loads(listener.stdout.readline())]
        assert any("port" in path.name for path in files), files  # it listens on a port
        domain = ros_env["ROS_DOMAIN_ID"]
        clean = subprocess.run(
            [*UNSHARE, sys.executable, "-c", CLEAN_ELSEWHERE, domain],
            env=ros_env, capture_output=True, text=True, timeout=60,
        )  # fmt: skip
        assert clean.returncode == 0, clean.stderr
        assert int(clean.stdout) <= 2  # itself (and unshare): the listener is out of sight
        assert [path for path in files if not path.exists()] == []
        probe = Probe("talker_after_the_clean")  # opens the listener's port by its name
        try:
            pub = probe.publisher(String, "beside_a_clean", 10)
            probe.until(lambda: pub.publish(String(data="hello")), heard.exists)
        finally:
            probe.close()
    finally:
        listener.kill()
        listener.wait()
        clean_shared_memory(int(ros_env["ROS_DOMAIN_ID"]))
