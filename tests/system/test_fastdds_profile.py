"""The Fast DDS profile every launched process gets (``aes_ros/ros/fastdds_profile.xml``).

With it a participant does not match its own endpoints: what keeps a large robot host's
start short (docs/performance.md), and why a node added *into* an aes-swarm process does
not hear that process's other nodes (docs/ros.md). A profile Fast DDS cannot read is only
logged, and the processes would silently run without it; this fails then too.
"""

from __future__ import annotations

import subprocess
import sys

from aes_ros.ros.launch.processes import PROFILE_VARIABLES, fastdds_environment

#: One process, one node: a publisher and a subscription of the same topic; prints how
#: many readers the publisher has matched after up to 3 s.
SELF_MATCH = """
import time
import rclpy
from rclpy.node import Node
from std_msgs.msg import Bool

rclpy.init()
node = Node("self_match", start_parameter_services=False)
pub = node.create_publisher(Bool, "/self_match", 1)
node.create_subscription(Bool, "/self_match", lambda _msg: None, 1)
deadline = time.monotonic() + 3.0
while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
    time.sleep(0.05)
print(pub.get_subscription_count(), flush=True)
"""


def matched_own_readers(env: dict[str, str]) -> int:
    done = subprocess.run(
        [sys.executable, "-c", SELF_MATCH], env=env, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    return int(done.stdout.split()[-1])


def test_a_launched_process_does_not_hear_itself(ros_env):
    plain = {k: v for k, v in ros_env.items() if k not in PROFILE_VARIABLES}
    assert matched_own_readers(plain) == 1  # Fast DDS's default: it does
    assert matched_own_readers(fastdds_environment(plain)) == 0
