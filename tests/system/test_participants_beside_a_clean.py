"""Fast DDS participants that start while a shared-memory clean runs keep their ports.

A clean of one domain (a test's teardown, a launcher's stop, the reaper) runs beside
participants of other domains that are starting: the ports from 7000 are shared by
every domain. A participant that lost a port to such a clean never heard a message
on it (seen in CI: a test's probe got no pose in 120 s).
"""

from __future__ import annotations

import json
import subprocess
import sys

from helpers.ros_env import reserved_domain_id, ros_variables

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
