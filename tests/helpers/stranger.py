"""A stranger on the network, for tests/system/test_isolation.py (run as a script:
``python tests/helpers/stranger.py [--steer] [--talk] [--seconds S]``).

Listens to ``/swarm/poses`` and ``/isolation/control`` and, with ``--steer``,
tries to steer the swarm (``/swarm/cmd`` north, ``/mona_0/cmd_vel`` spinning);
with ``--talk`` it publishes ``/isolation/control`` instead. Prints one JSON line:
messages received per topic and the most subscribers its publishers matched.
Its ROS domain and discovery settings come from the environment.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from geometry_msgs.msg import PoseArray, Twist
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run as a script: `helpers`

from aes_ros.ros import interface as names
from aes_ros.ros.interface import robot_topic
from helpers.messages import twist
from helpers.probe import Probe

#: A topic only the strangers use: the positive control of the isolation checks.
CONTROL = "/isolation/control"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--steer", action="store_true")
    parser.add_argument("--talk", action="store_true")
    args = parser.parse_args()
    probe = Probe("stranger")
    best_effort = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    got = {
        "poses": probe.record(PoseArray, names.POSES, best_effort),
        "control": probe.record(Float64, CONTROL, 10),
    }
    sends = {}
    if args.steer:
        sends[names.CMD] = (Twist, twist(vy=1.0))  # north
        sends[robot_topic(0, names.CMD_VEL)] = (Twist, twist(w=3.0))  # spin
    if args.talk:
        sends[CONTROL] = (Float64, Float64(data=1.0))
    pubs = {
        topic: probe.publisher(kind, topic, 10, wait=False) for topic, (kind, _) in sends.items()
    }
    matched = dict.fromkeys(pubs, 0)
    end = time.monotonic() + args.seconds
    while time.monotonic() < end:
        time.sleep(0.1)
        for topic, pub in pubs.items():
            matched[topic] = max(matched[topic], pub.get_subscription_count())
            pub.publish(sends[topic][1])
    print(json.dumps({**{k: len(v) for k, v in got.items()}, "matched": matched}), flush=True)
    probe.close()


if __name__ == "__main__":
    main()
