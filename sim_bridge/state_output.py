"""What the bridge publishes for each state of its world (docs/interface.md).

``/clock``, ``/swarm/poses`` (the perceived frame when the scenario models perception
error, the exact poses then on ``/sim/ground_truth/poses``) and each robot's
``/mona_<i>/odom``, written straight into their wire format
(:class:`aes_ros.ros.cdr.PoseArrayEncoder`, :class:`~aes_ros.ros.cdr.OdometryEncoder`):
only the numbers of the messages change from step to step.
"""

from __future__ import annotations

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseArray
from nav_msgs.msg import Odometry
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg

from aes_ros.perception import PerceptionSettings
from aes_ros.ros import interface as names
from aes_ros.ros.cdr import OdometryEncoder, PoseArrayEncoder
from aes_ros.ros.qos import SENSOR, STREAM_WRITER
from sim_bridge.perceived_poses import PerceivedPoses
from sim_bridge.world import World


class StateOutput:
    """The publishers of a bridge's state and the messages they reuse.

    ``perception`` is the scenario's perception error (off: the robots see the exact
    poses); ``rate`` [Hz] the control rate and ``seed`` the run whose perception draws
    are used (:class:`sim_bridge.perceived_poses.PerceivedPoses`).
    """

    def __init__(
        self, node: Node, world: World, perception: PerceptionSettings, rate: float, seed: int
    ) -> None:
        self.world = world
        n = world.n
        dt = 1.0 / rate
        self.dt_ns = round(1e9 / rate)
        self.stamp = Time()  #: the stamp of the state published last
        self.clock_msg = ClockMsg(clock=self.stamp)
        self.clock_pub = node.create_publisher(ClockMsg, names.CLOCK, STREAM_WRITER)
        self.poses_pub = node.create_publisher(PoseArray, names.POSES, STREAM_WRITER)
        self.poses_encoder = PoseArrayEncoder(n, names.WORLD_FRAME)
        self.perceived: PerceivedPoses | None = None
        if perception.enabled(dt):
            self.perceived = PerceivedPoses(perception, n, dt, seed)
            self.truth_pub = node.create_publisher(
                PoseArray, names.GROUND_TRUTH_POSES, STREAM_WRITER
            )
            self.seen_encoder = PoseArrayEncoder(n, names.WORLD_FRAME)
        # Every QoS event handler is one more entity in each wait of the executor;
        # robot 0's report incompatible QoS (all robots are alike), the others none.
        quiet = PublisherEventCallbacks(use_default_callbacks=False)
        self.odom_pubs = [
            node.create_publisher(
                Odometry,
                names.robot_topic(i, names.ODOM),
                SENSOR,
                event_callbacks=quiet if i else None,
            )
            for i in range(n)
        ]
        self.odom_encoders = [
            OdometryEncoder(names.WORLD_FRAME, names.base_link(i)) for i in range(n)
        ]
        self.odom_listened: list[int] = []
        self.update_listeners()

    def update_listeners(self) -> None:
        """Note the robots whose odometry has a subscriber (the bridge checks 4x per wall
        second, not per step)."""
        self.odom_listened = [
            i for i, pub in enumerate(self.odom_pubs) if pub.get_subscription_count()
        ]

    def publish(self) -> Time:
        """Publish /clock, /swarm/poses and the odometry for the world's current step;
        returns its stamp.

        Odometry goes only to robots whose ``odom`` topic has a subscriber (the
        ``odom`` neighbour source, a driver, ``ros2 topic echo``; a new subscriber
        is noticed within 0.25 s): for nobody, building and publishing N messages
        would cost more than the physics.
        """
        step = self.world.step_count
        stamp = self.stamp
        stamp.sec, stamp.nanosec = divmod(step * self.dt_ns, 1_000_000_000)
        self.clock_pub.publish(self.clock_msg)
        positions, headings = self.world.poses()
        exact = self.poses_encoder.encode(stamp.sec, stamp.nanosec, positions, headings)
        if self.perceived is None:
            self.poses_pub.publish(exact)
        else:
            self.truth_pub.publish(exact)
            seen = self.perceived.frame(step, positions, headings)
            self.poses_pub.publish(self.seen_encoder.encode(stamp.sec, stamp.nanosec, *seen))
        if self.odom_listened:
            self._publish_odometry(stamp.sec, stamp.nanosec)
        return stamp

    def _publish_odometry(self, sec: int, nanosec: int) -> None:
        listened = self.odom_listened
        forward, sideways, turn = self.world.velocities()
        encoded = self.poses_encoder.poses  # x, y, z, qx, qy, qz, qw as just published
        rows = zip(
            listened,
            encoded[listened, 0:2].tolist(),
            encoded[listened, 5:7].tolist(),
            forward[listened].tolist(),
            sideways[listened].tolist(),
            turn[listened].tolist(),
            strict=True,
        )
        for i, (x, y), (qz, qw), fwd, side, w in rows:
            data = self.odom_encoders[i].encode(sec, nanosec, x, y, qz, qw, fwd, side, w)
            self.odom_pubs[i].publish(data)
