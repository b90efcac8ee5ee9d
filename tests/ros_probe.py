"""A stranger on the network, for tests/test_isolation.py (run as a script).

Listens to ``/swarm/poses`` and ``/isolation/control`` and, with ``--steer``,
tries to steer the swarm (``/swarm/cmd`` north, ``/mona_0/cmd_vel`` spinning);
with ``--talk`` it publishes ``/isolation/control`` instead. Prints one JSON line:
messages received per topic and the most subscribers its publishers matched.
Its ROS domain and discovery settings come from the environment.
"""

from __future__ import annotations

import argparse
import json
import time

import rclpy
from geometry_msgs.msg import PoseArray, Twist
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--steer", action="store_true")
    parser.add_argument("--talk", action="store_true")
    args = parser.parse_args()
    rclpy.init()
    node = rclpy.create_node("stranger")
    got = {"poses": 0, "control": 0}
    best_effort = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    node.create_subscription(
        PoseArray, "/swarm/poses", lambda _: got.__setitem__("poses", got["poses"] + 1), best_effort
    )
    node.create_subscription(
        Float64, "/isolation/control", lambda _: got.__setitem__("control", got["control"] + 1), 10
    )
    pubs = {}
    if args.steer:
        pubs["/swarm/cmd"] = node.create_publisher(Twist, "/swarm/cmd", 10)
        pubs["/mona_0/cmd_vel"] = node.create_publisher(Twist, "/mona_0/cmd_vel", 10)
    if args.talk:
        pubs["/isolation/control"] = node.create_publisher(Float64, "/isolation/control", 10)
    matched = dict.fromkeys(pubs, 0)
    north, spin = Twist(), Twist()
    north.linear.y = 1.0
    spin.angular.z = 3.0
    end = time.monotonic() + args.seconds
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.1)
        for topic, pub in pubs.items():
            matched[topic] = max(matched[topic], pub.get_subscription_count())
            if topic == "/isolation/control":
                pub.publish(Float64(data=1.0))
            else:
                pub.publish(north if topic == "/swarm/cmd" else spin)
    print(json.dumps({**got, "matched": matched}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


if __name__ == "__main__":
    main()
