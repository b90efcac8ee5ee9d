"""Record the swarm's topics to a standard ROS 2 MCAP bag.

The bag follows the ``ros2`` MCAP profile that rosbag2's MCAP storage writes:
one ``ros2msg`` schema per message type (the ``.msg`` text of the type and of
every type it uses, in rosbag2's concatenated layout) and the messages as the
CDR bytes that came over the wire (raw subscriptions: nothing is decoded or
re-encoded). The container is written by the ``mcap`` package; any MCAP tool,
``ros2 bag play`` or ``mcap_ros2.reader.read_ros2_messages`` reads it back::

    from aes_ros.ros.recorder import read_bag
    for topic, log_time_ns, msg in read_bag("run.mcap", topics=["/swarm/alignment"]):
        print(log_time_ns, msg.data)

(:func:`read_bag` is ``mcap.reader`` with the ``mcap_ros2`` decoder; the older
``mcap_ros2.reader.read_ros2_messages`` works too.)

Recorded: every ``/swarm/*`` topic, ``/clock`` and every ``/mona_<i>/cmd_vel``.
The known topics are subscribed at once with the QoS of SPEC §7 (transient-local
for the supervisor's latched topics, so their last value is in the bag); further
matching topics are picked up by discovery once a second. Log times are wall
time [ns], like ``ros2 bag record`` without ``--use-sim-time``; the messages keep
their own (sim-time) stamps.

The open chunk is flushed to disk every ``FLUSH_PERIOD`` (1 s): a recorder killed
with SIGKILL leaves a bag without summary that :func:`read_bag` still reads up to
its last complete chunk (:func:`bag_is_closed` tells the two apart).

Run on its own (it stops and closes the bag on Ctrl-C / SIGTERM)::

    python -m aes_ros.ros.recorder run.mcap --robots 16
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import threading
import time
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import rclpy
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosidl_adapter.parser import parse_message_string

from aes_ros.ros.qos import COMMAND, COMMAND_KEPT, LATCHED, STREAM_WRITER
from aes_ros.ros.spin import spin

#: Topics recorded from the start: name -> (type, QoS of its publisher, SPEC §7).
KNOWN_TOPICS: dict[str, tuple[str, QoSProfile]] = {
    "/clock": ("rosgraph_msgs/msg/Clock", STREAM_WRITER),
    "/swarm/poses": ("geometry_msgs/msg/PoseArray", STREAM_WRITER),
    "/swarm/cmd": ("geometry_msgs/msg/Twist", COMMAND),
    "/swarm/desired_velocity": ("geometry_msgs/msg/TwistStamped", LATCHED),
    "/swarm/rotation_center": ("geometry_msgs/msg/PointStamped", LATCHED),
    "/swarm/enabled": ("std_msgs/msg/Bool", LATCHED),
    "/swarm/alignment": ("std_msgs/msg/Float64", LATCHED),
    "/swarm/heading_order": ("std_msgs/msg/Float64", LATCHED),
    "/swarm/total_force": ("std_msgs/msg/Float64", LATCHED),
}
CMD_VEL_TYPE = "geometry_msgs/msg/Twist"
#: Topic names picked up by discovery.
RECORDED = re.compile(r"^(/clock|/swarm/.+|/mona_\d+/cmd_vel)$")
#: Separator between the definitions of a schema (rosbag2 / ROS 1 style).
SEPARATOR = "=" * 80
#: Printed once every robot's cmd_vel and every supervisor topic has a matched
#: publisher (with ``--robots N``); the launcher starts the swarm only then.
MATCHED_ALL = "found the publishers of every robot and of the supervisor"
#: Deeper queues than the publishers' so that a busy recorder loses nothing.
QUEUE_DEPTH = 100
#: Wall seconds between chunk flushes: what a recorder killed with SIGKILL can lose.
FLUSH_PERIOD = 1.0


def share_dirs() -> list[Path]:
    """Where the interface packages' ``share/<pkg>/msg/*.msg`` files live."""
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    prefixes.append(sys.prefix)
    return [Path(p) / "share" for p in prefixes]


def _msg_text(type_name: str) -> str:
    pkg, _, name = type_name.partition("/msg/")
    for share in share_dirs():
        path = share / pkg / "msg" / f"{name}.msg"
        if path.is_file():
            return path.read_text()
    raise FileNotFoundError(f"no .msg file for {type_name} under {share_dirs()}")


def message_definition(type_name: str) -> str:
    """The ``ros2msg`` schema text of ``pkg/msg/Type``: its ``.msg`` text, then every
    type it uses (depth first, each once) after a separator and ``MSG: pkg/Type``."""
    parts: list[str] = []
    seen: set[str] = set()

    def visit(full: str, top: bool) -> None:
        if full in seen:
            return
        seen.add(full)
        pkg, _, name = full.partition("/msg/")
        text = _msg_text(full)
        parts.append(text if top else f"{SEPARATOR}\nMSG: {pkg}/{name}\n{text}")
        for field in parse_message_string(pkg, name, text).fields:
            if not field.type.is_primitive_type():
                visit(f"{field.type.pkg_name}/msg/{field.type.type}", False)

    visit(type_name, True)
    return "\n".join(p.rstrip("\n") for p in parts) + "\n"


class BagWriter:
    """An MCAP file in the ``ros2`` profile taking raw CDR messages (thread-safe)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "wb")  # closed in close()
        self._writer = McapWriter(self._file, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library="aes-swarm recorder (mcap)")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence: dict[int, int] = {}
        self._lock = threading.Lock()
        self.counts: dict[str, int] = {}
        self.closed = False

    def add_topic(self, topic: str, type_name: str) -> None:
        with self._lock:
            if topic in self._channels or self.closed:
                return
            schema = self._schemas.get(type_name)
            if schema is None:
                schema = self._writer.register_schema(
                    type_name, "ros2msg", message_definition(type_name).encode()
                )
                self._schemas[type_name] = schema
            channel = self._writer.register_channel(topic, "cdr", schema)
            self._channels[topic] = channel
            self._sequence[channel] = 0
            self.counts[topic] = 0

    def write(self, topic: str, data: bytes, log_time_ns: int | None = None) -> None:
        """Append one serialized message of a topic added with :meth:`add_topic`."""
        stamp = time.time_ns() if log_time_ns is None else log_time_ns
        with self._lock:
            if self.closed:
                return
            channel = self._channels[topic]
            self._sequence[channel] += 1
            self._writer.add_message(channel, stamp, bytes(data), stamp, self._sequence[channel])
            self.counts[topic] += 1

    def flush(self) -> None:
        """Finish the chunk in progress and write it out: a recorder killed with
        SIGKILL leaves a bag readable (:func:`read_bag`) up to the last flush."""
        with self._lock:
            if self.closed:
                return
            self._writer.flush()
            self._file.flush()

    def close(self) -> None:
        """Write the summary and close the file (idempotent)."""
        with self._lock:
            if self.closed:
                return
            self.closed = True
            self._writer.finish()
            self._file.close()


def bag_is_closed(path: str | Path) -> bool:
    """True if the bag ends with its summary and footer (its recorder closed it)."""
    from mcap.reader import make_reader

    with open(path, "rb") as fh:
        try:
            return make_reader(fh).get_summary() is not None
        except Exception:  # no footer: the recorder did not get to close it
            return False


def read_bag(
    path: str | Path, topics: Iterable[str] | None = None
) -> Iterator[tuple[str, int, Any]]:
    """(topic, log time [ns], decoded message) of every message of a bag.

    A closed bag is read through its index, in log-time order. A bag whose
    recorder was killed (no summary) is read front to back, in write order, up to
    its last complete chunk; the truncated rest is skipped.
    """
    from mcap.reader import NonSeekingReader, make_reader
    from mcap_ros2.decoder import DecoderFactory

    wanted = None if topics is None else list(topics)
    closed = bag_is_closed(path)
    with open(path, "rb") as fh:
        if closed:
            reader = make_reader(fh, decoder_factories=[DecoderFactory()])
            for _, channel, message, msg in reader.iter_decoded_messages(topics=wanted):
                yield channel.topic, message.log_time, msg
            return
        reader = NonSeekingReader(fh, decoder_factories=[DecoderFactory()])
        messages = reader.iter_decoded_messages(topics=wanted, log_time_order=False)
        while True:
            try:
                _, channel, message, msg = next(messages)
            except StopIteration:
                return
            except Exception:  # the record cut off by the kill: the end of what is there
                return
            yield channel.topic, message.log_time, msg


def _subscriber_qos(infos: Iterable) -> QoSProfile:
    """A QoS matching every publisher of a topic (as rosbag2 adapts its subscriptions)."""
    infos = list(infos)
    reliable = bool(infos) and all(
        i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos
    )
    latched = bool(infos) and all(
        i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos
    )
    return QoSProfile(
        depth=QUEUE_DEPTH,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


class RecorderNode(Node):
    """Subscribes (raw) to the recorded topics and writes them to a :class:`BagWriter`.

    Parameters (constructor): ``bag`` the writer, ``num_robots`` N (subscribes
    ``/mona_<i>/cmd_vel`` for i < N at once; others are found by discovery),
    ``discover`` look for further matching topics once a second.
    """

    def __init__(
        self, bag: BagWriter, num_robots: int = 0, discover: bool = True, **kwargs: Any
    ) -> None:
        super().__init__("aes_recorder", **kwargs)
        self.bag = bag
        self._subs: dict[str, object] = {}
        self._heard: set[str] = set()
        for topic, (type_name, qos) in KNOWN_TOPICS.items():
            self._subscribe(topic, type_name, _with_depth(qos))
        for i in range(num_robots):
            self._subscribe(f"/mona_{i}/cmd_vel", CMD_VEL_TYPE, _with_depth(COMMAND_KEPT))
        if discover:
            self.create_timer(1.0, self.on_discover)
        self.create_timer(FLUSH_PERIOD, self.bag.flush)
        # The robots' and the supervisor's topics (the latched ones are the supervisor's).
        self._awaited = [f"/mona_{i}/cmd_vel" for i in range(num_robots)] + [
            topic for topic, (_, qos) in KNOWN_TOPICS.items() if qos is LATCHED
        ]
        self._match_timer = self.create_timer(0.1, self.on_check_matched) if num_robots else None

    def _subscribe(self, topic: str, type_name: str, qos: QoSProfile) -> None:
        pkg, _, name = type_name.partition("/msg/")
        msg_type = getattr(__import__(f"{pkg}.msg", fromlist=[name]), name)
        self.bag.add_topic(topic, type_name)
        self._subs[topic] = self.create_subscription(
            msg_type, topic, lambda data, t=topic: self.on_message(t, data), qos, raw=True
        )

    def on_message(self, topic: str, data: bytes) -> None:
        self.bag.write(topic, data)
        if topic not in self._heard:
            self._heard.add(topic)
            # The launcher waits for this line before it starts the robots.
            print(f"receiving {topic}", flush=True)

    def on_check_matched(self) -> None:
        """Say :data:`MATCHED_ALL` once the robots and the supervisor are all found."""
        self._awaited = [t for t in self._awaited if self._subs[t].get_publisher_count() == 0]
        if not self._awaited:
            print(MATCHED_ALL, flush=True)
            self._match_timer.cancel()

    def take_remaining(self) -> int:
        """Write every message the subscriptions still hold; returns how many.

        Called after spinning stopped: those messages were acknowledged to their
        writers (nobody would send them again), so leaving them in the queues
        would lose them. Taken directly, until each queue is empty, rather than
        by spinning until it looks quiet, which a starved process cannot tell.
        """
        taken = 0
        for topic, sub in self._subs.items():
            if sub is None:
                continue
            while True:
                with sub.handle:
                    msg_info = sub.handle.take_message(sub.msg_type, sub.raw)
                if msg_info is None:
                    break
                self.on_message(topic, msg_info[0])
                taken += 1
        return taken

    def on_discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self._subs or not RECORDED.match(topic) or len(types) != 1:
                continue
            infos = self.get_publishers_info_by_topic(topic)
            if not infos:
                continue
            try:
                self._subscribe(topic, types[0], _subscriber_qos(infos))
            except (ImportError, AttributeError, FileNotFoundError) as exc:
                self.get_logger().warning(f"not recording {topic}: {exc}")
                self._subs[topic] = None


def _with_depth(qos: QoSProfile) -> QoSProfile:
    """``qos`` with a queue of QUEUE_DEPTH, also for the latched topics: their
    publishers keep only the last sample for late joiners, but a recorder that keeps
    only one would lose every sample it has not taken before the next arrives (the
    supervisor publishes the rotation centre for every poses message)."""
    return QoSProfile(
        depth=max(qos.depth, QUEUE_DEPTH),
        reliability=qos.reliability,
        durability=qos.durability,
        history=qos.history,
    )


def main(argv: list[str] | None = None) -> int:
    """``python -m aes_ros.ros.recorder OUT.mcap [--robots N] [--ros-args ...]``."""
    argv = sys.argv[1:] if argv is None else argv
    cut = argv.index("--ros-args") if "--ros-args" in argv else len(argv)
    parser = argparse.ArgumentParser(
        prog="python -m aes_ros.ros.recorder", description=__doc__.splitlines()[0]
    )
    parser.add_argument("output", type=Path, help="the MCAP file to write")
    parser.add_argument("--robots", type=int, default=0, help="subscribe cmd_vel of N robots")
    args = parser.parse_args(argv[:cut])
    # SIGINT/SIGTERM end spin(); what the readers still hold is written, then the
    # bag is closed.
    rclpy.init(args=["recorder", *argv[cut:]], signal_handler_options=SignalHandlerOptions.NO)
    bag = BagWriter(args.output)
    node = None
    try:
        node = RecorderNode(bag, args.robots)
        print(f"recording to {args.output}", flush=True)
        spin([node])
        drained = node.take_remaining()
        print(f"stopped; {drained} messages taken from the queues after the stop", flush=True)
    except ExternalShutdownException:
        pass
    finally:
        bag.close()
        total = sum(bag.counts.values())
        print(f"bag {args.output}: {total} messages on {len(bag.counts)} topics", flush=True)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
