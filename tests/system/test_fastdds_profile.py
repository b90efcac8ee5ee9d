"""The Fast DDS profiles of launched processes: ``aes_ros/ros/fastdds_profile.xml`` for every
one, ``aes_ros/ros/fastdds_images.xml`` for the simulated camera.

With it a participant does not match its own endpoints: what keeps a large robot host's
start short (docs/performance.md), and why a node added *into* an aes-swarm process does
not hear that process's other nodes (docs/ros.md); and its reliable writers ask for
acknowledgements every 0.5 s, so a stopping node does not wait seconds for them. A
profile Fast DDS cannot read is only logged, and the processes would silently run
without it; this fails then too.
"""

from __future__ import annotations

import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

from std_msgs.msg import Bool

from aes_ros.ros import interface as names
from aes_ros.ros.launch.processes import (
    FASTDDS_PROFILE,
    IMAGES_PROFILE,
    PROFILE_VARIABLES,
    fastdds_environment,
    images_environment,
)
from aes_ros.ros.qos import LATCHED

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


def test_a_stopping_node_does_not_wait_seconds_for_its_readers(spawn, probe, ros_env):
    """A node stops once its readers have acknowledged what it published (flush_publishers
    in aes_ros/ros/spin.py), and a reader acknowledges when the writer's heartbeat asks:
    every 3 s with Fast DDS's default, when a launch's bridge and supervisor each waited
    about 2 s at every stop. With the launch's profile a supervisor whose latched state a
    reader has just taken exits within 1.5 s of SIGINT, three times out of three."""
    plain = {k: v for k, v in ros_env.items() if k not in PROFILE_VARIABLES}
    spawn.env = fastdds_environment(plain)
    enabled = probe.record(Bool, names.ENABLED, LATCHED)
    stops = []
    for attempt in range(3):
        enabled.clear()
        supervisor = spawn.start("aes-supervisor", name=f"supervisor_{attempt}")
        probe.wait(lambda: enabled, 30.0, "the supervisor's /swarm/enabled")
        start = time.monotonic()
        assert spawn.stop(supervisor) == 0, spawn.logs()
        stops.append(time.monotonic() - start)
        assert "not acknowledged" not in spawn.log(supervisor).read_text()
    print(f"\nstopped in {', '.join(f'{t:.2f}' for t in stops)} s")
    assert max(stops) < 1.5, stops


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
    """fastdds_images.xml copies fastdds_profile.xml's discovery, properties and writer
    settings (Fast DDS takes one default profile of each kind a process): the copy says
    the same."""
    ns = {"p": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}

    def settings(path: Path) -> list[bytes]:
        root = ET.parse(path).getroot()
        rtps = root.find("p:participant/p:rtps", ns)
        writer = root.find("p:data_writer", ns)
        assert rtps is not None and writer is not None, path
        tags = ("builtin", "propertiesPolicy")
        return [*(ET.tostring(rtps.find(f"p:{tag}", ns)) for tag in tags), ET.tostring(writer)]

    assert settings(IMAGES_PROFILE) == settings(FASTDDS_PROFILE)
