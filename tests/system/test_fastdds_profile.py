"""The Fast DDS profiles of launched processes: ``aes_ros/ros/fastdds_profile.xml`` for every
one, ``aes_ros/ros/fastdds_images.xml`` for the simulated camera.

With it a participant does not match its own endpoints: what keeps a large robot host's
start short (docs/performance.md), and why a node added *into* an aes-swarm process does
not hear that process's other nodes (docs/ros.md). A profile Fast DDS cannot read is only
logged, and the processes would silently run without it; this fails then too.
"""

from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

from aes_ros.ros.launch.processes import (
    FASTDDS_PROFILE,
    IMAGES_PROFILE,
    PROFILE_VARIABLES,
    fastdds_environment,
    images_environment,
)

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


#: Prints the sizes [bytes] of the Fast DDS data segments its process maps (its own, with
#: no peers): /dev/shm/fastrtps_<16 hex digits>.
SEGMENT = """
import os, re
import rclpy
from rclpy.node import Node

rclpy.init()
node = Node("segment_size", start_parameter_services=False)
maps = open("/proc/self/maps").read()
paths = set(re.findall(r"(/dev/shm/fastrtps_[0-9a-z]{16})$", maps, re.M))
print(*sorted(os.path.getsize(p) for p in paths), flush=True)
"""


def test_the_camera_sends_frames_through_a_segment_that_holds_them(ros_env):
    """A 1.2-3 MB frame goes as ~64 kB fragments; the camera's segment holds a few frames'
    worth (32 MB), where Fast DDS's default (512 kB) held a few fragments."""
    plain = {k: v for k, v in ros_env.items() if k not in PROFILE_VARIABLES}
    camera = {**fastdds_environment(plain), **images_environment(plain)}
    assert Path(camera["FASTRTPS_DEFAULT_PROFILES_FILE"]).name == "fastdds_images.xml"
    assert matched_own_readers(camera) == 0  # the launch's profile, otherwise
    done = subprocess.run(
        [sys.executable, "-c", SEGMENT], env=camera, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    sizes = [int(size) for size in done.stdout.split()]
    assert sizes and max(sizes) >= 32 * 2**20, sizes
    # a caller's own profile wins
    assert images_environment({**plain, "FASTRTPS_DEFAULT_PROFILES_FILE": "mine.xml"}) == {}


def test_the_camera_profile_keeps_the_launch_profiles_participant_settings():
    """fastdds_images.xml copies fastdds_profile.xml's discovery and properties (Fast DDS
    takes one default participant profile a process): the copy says the same."""
    ns = {"p": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}

    def settings(path: Path) -> list[bytes]:
        rtps = ET.parse(path).getroot().find("p:participant/p:rtps", ns)
        assert rtps is not None, path
        return [ET.tostring(rtps.find(f"p:{tag}", ns)) for tag in ("builtin", "propertiesPolicy")]

    assert settings(IMAGES_PROFILE) == settings(FASTDDS_PROFILE)
