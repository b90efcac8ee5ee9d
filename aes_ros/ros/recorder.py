"""Record the swarm's topics to a standard ROS 2 MCAP bag (:mod:`aes_ros.ros.bag`).

Recorded: every ``/swarm/*`` topic, ``/clock`` and every ``/mona_<i>/cmd_vel``,
as the CDR bytes that came over the wire (raw subscriptions: nothing is decoded
or re-encoded). The known topics are subscribed at once with the QoS of docs/design.md#ros-interface
(transient-local for the supervisor's latched topics, so their last value is in
the bag); further matching topics are picked up by discovery once a second. Log
times are wall time [ns], like ``ros2 bag record`` without ``--use-sim-time``;
the messages keep their own (sim-time) stamps.

The open chunk is flushed to disk every ``FLUSH_PERIOD`` (1 s): a recorder killed
with SIGKILL leaves a bag without summary that :func:`aes_ros.ros.bag.read_bag`
still reads up to its last complete chunk (:func:`aes_ros.ros.bag.bag_is_closed`
tells the two apart).

For runs of hours, ``--split SIZE|DURATION`` (``1GiB``, ``500MiB``, ``10min``,
``30s``) closes the bag once it has that many bytes on disk or spans that much wall
time and goes on in the next segment (``run_1.mcap``, ``run_2.mcap``…, the numbering
a restarted recorder continues, ``--segment``); ``--keep K`` deletes all but the
newest K segments. A new recording (segment 0) where an earlier one's files are is
refused unless ``--overwrite`` (which removes those files, and only those, first).
Every closed segment is a complete bag with its own counts and losses, and starts
with the last message of each latched topic, so that it can be read alone
(:class:`aes_ros.ros.bag.Recording`).

Nothing is lost silently. Each message is stored with its publisher's send time
and sequence number, so gaps in a topic's numbers are messages that did not reach
the recorder: counted per topic (:class:`aes_ros.ros.bag.SequenceGaps`), written
into each segment's ``aes_swarm.recording`` metadata (the losses while it was open)
and printed at the end (the whole recording's). A restarted recorder (``--segment``)
continues the counts of its earlier lives from the journal beside the bag
(``run.sequences.json``, :func:`aes_ros.ros.bag.read_journal`, rewritten at every
flush and at the end), so its last line counts the whole recording's losses: also
those of lives killed before they printed theirs, and what was lost while none ran.
After each ``/swarm/poses`` it has written it publishes ``/recorder/progress`` (its
stamp): a lockstep bridge with ``wait_for_recorder`` waits for it before the next
step, so a recording in lockstep is complete at any load. A bag it cannot write
(disk full) ends the recorder with exit code 3 and a message; what was written
stays readable.

Run on its own (it stops and closes the bag on Ctrl-C / SIGTERM)::

    python -m aes_ros.ros.recorder run.mcap --robots 16
    python -m aes_ros.ros.recorder run.mcap --robots 16 --split 10min --keep 6
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import re
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock

from aes_ros.previous_run import EarlierRunError
from aes_ros.ros import interface as names
from aes_ros.ros.bag import (
    SPLIT_FORMS,
    Recording,
    Split,
    last_sequences,
    parse_split,
    read_journal,
)
from aes_ros.ros.cdr import decode_stamp
from aes_ros.ros.conversions import BadMessageError
from aes_ros.ros.qos import (
    COMMAND,
    COMMAND_KEPT,
    IMAGES,
    LATCHED,
    OUTPUT_DEPTH,
    SENSOR,
    STREAM_WRITER,
)
from aes_ros.ros.spin import spin

#: Topics recorded from the start: name -> (type, QoS of its publisher;
#: docs/design.md#ros-interface).
KNOWN_TOPICS: dict[str, tuple[str, QoSProfile]] = {
    names.CLOCK: ("rosgraph_msgs/msg/Clock", STREAM_WRITER),
    names.POSES: ("geometry_msgs/msg/PoseArray", STREAM_WRITER),
    names.CMD: ("geometry_msgs/msg/Twist", COMMAND),
    names.DESIRED_VELOCITY: ("geometry_msgs/msg/TwistStamped", LATCHED),
    names.ROTATION_CENTER: ("geometry_msgs/msg/PointStamped", LATCHED),
    names.ENABLED: ("std_msgs/msg/Bool", LATCHED),
    names.ALIGNMENT: ("std_msgs/msg/Float64", LATCHED),
    names.HEADING_ORDER: ("std_msgs/msg/Float64", LATCHED),
    names.TOTAL_FORCE: ("std_msgs/msg/Float64", LATCHED),
}
CMD_VEL_TYPE = "geometry_msgs/msg/Twist"
#: Topic names picked up by discovery.
RECORDED = re.compile(r"^(/clock|/swarm/.+|/mona_\d+/cmd_vel|/sim/ground_truth/poses)$")
#: The camera's topics, recorded only when asked (``--images RATE``): a 1280 × 960 frame
#: is 1.2 MB, 20 of them a second 1.4 GB a minute.
CAMERA_TOPICS = {
    names.CAMERA_IMAGE: ("sensor_msgs/msg/Image", IMAGES),
    names.CAMERA_INFO: ("sensor_msgs/msg/CameraInfo", SENSOR),
}
#: Wall seconds between chunk flushes: what a recorder killed with SIGKILL can lose.
FLUSH_PERIOD = 1.0


class CannotWriteError(RuntimeError):
    """The bag cannot be written (disk full, file system gone): recording stops."""


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
        depth=OUTPUT_DEPTH,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


class RecorderNode(Node):
    """Subscribes (raw) to the recorded topics and writes them to a :class:`Recording`.

    Parameters (constructor): ``bag`` the recording (its segments, and the losses it
    counts), ``num_robots`` N (subscribes ``/mona_<i>/cmd_vel`` for i < N at once;
    others are found by discovery), ``discover`` look for further matching topics
    once a second, ``images_rate`` [Hz of the frames' stamps]: also record the
    camera's frames and camera_info, at most this many a second (0: none; their
    losses are not counted, since frames are skipped on purpose).

    Spin it on a ``SingleThreadedExecutor``: its callbacks take the message info
    (send time, sequence number), which rclpy's EventsExecutor does not pass.
    """

    def __init__(
        self,
        bag: Recording,
        num_robots: int = 0,
        discover: bool = True,
        images_rate: float = 0.0,
        **kwargs: Any,
    ) -> None:
        super().__init__(names.RECORDER_NODE, **kwargs)
        self.bag = bag
        self._subs: dict[str, object] = {}
        self._heard: set[str] = set()
        self._progress = self.create_publisher(Clock, names.RECORDER_PROGRESS, LATCHED)
        self._progress_msg = Clock()
        self._image_period_ns = round(1e9 / images_rate) if images_rate > 0 else 0
        self._next_image: dict[str, int] = {}
        if images_rate > 0:
            for topic, (type_name, qos) in CAMERA_TOPICS.items():
                self._subscribe(topic, type_name, qos, sampled=True)
        for topic, (type_name, qos) in KNOWN_TOPICS.items():
            self._subscribe(topic, type_name, _with_depth(qos))
        for i in range(num_robots):
            self._subscribe(
                names.robot_topic(i, names.CMD_VEL), CMD_VEL_TYPE, _with_depth(COMMAND_KEPT)
            )
        self.create_timer(1.0, lambda: self.on_discover(discover))
        self.create_timer(FLUSH_PERIOD, self.on_flush)
        # The robots' and the supervisor's topics (the latched ones are the supervisor's).
        self._awaited = [names.robot_topic(i, names.CMD_VEL) for i in range(num_robots)] + [
            topic for topic, (_, qos) in KNOWN_TOPICS.items() if qos is LATCHED
        ]
        self._match_timer = self.create_timer(0.1, self.on_check_matched) if num_robots else None

    def _subscribe(
        self, topic: str, type_name: str, qos: QoSProfile, sampled: bool = False
    ) -> None:
        pkg, _, name = type_name.partition("/msg/")
        msg_type = getattr(__import__(f"{pkg}.msg", fromlist=[name]), name)
        # A latched topic's last message starts every segment of a split recording.
        latched = qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
        self.bag.add_topic(topic, type_name, latched=latched, sampled=sampled)
        # Two arguments: rclpy then passes the message info too.
        callback = functools.partial(self.on_message, topic)
        self._subs[topic] = self.create_subscription(msg_type, topic, callback, qos, raw=True)

    def on_message(self, topic: str, data: bytes, info: dict[str, Any] | None) -> None:
        """Write one message (the recording counts the messages before it that never
        arrived, and goes on in its next segment when the open one is full)."""
        if topic in CAMERA_TOPICS and not self._image_due(topic, data):
            return
        sequence = info.get("publication_sequence_number") if info else None
        sent = info.get("source_timestamp") if info else None
        try:
            self.bag.write(topic, data, publish_time_ns=sent, sequence=sequence)
        except OSError as exc:
            raise CannotWriteError(f"cannot write {self.bag.path}: {exc.strerror or exc}") from None
        if topic == names.POSES:
            with contextlib.suppress(BadMessageError):
                stamp = self._progress_msg.clock
                stamp.sec, stamp.nanosec = decode_stamp(data)
                self._progress.publish(self._progress_msg)
        if topic not in self._heard:
            self._heard.add(topic)
            # The launcher waits for this line before it starts the robots.
            say(names.recorder_receiving(topic))

    def _image_due(self, topic: str, data: bytes) -> bool:
        """A camera message is written when its stamp is a period past the last one."""
        try:
            sec, nanosec = decode_stamp(data)
        except BadMessageError:
            return False
        stamp = sec * 1_000_000_000 + nanosec
        due = self._next_image.get(topic, 0)
        if stamp < due and stamp > due - 10 * self._image_period_ns:
            return False
        self._next_image[topic] = stamp + self._image_period_ns
        return True

    def on_flush(self) -> None:
        try:
            self.bag.flush()
        except OSError as exc:
            raise CannotWriteError(f"cannot write {self.bag.path}: {exc.strerror or exc}") from None

    def on_check_matched(self) -> None:
        """Say RECORDER_MATCHED_ALL once the robots and the supervisor are all found."""
        self._awaited = [t for t in self._awaited if self._subs[t].get_publisher_count() == 0]
        if not self._awaited:
            say(names.RECORDER_MATCHED_ALL)
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
                self.on_message(topic, msg_info[0], msg_info[1])
                taken += 1
        return taken

    def on_discover(self, discover: bool) -> None:
        """Once a second: subscribe to new matching topics (``discover``), and mark
        topics with several publishers, whose losses cannot be counted."""
        for topic, sub in self._subs.items():
            if sub is not None:
                self.bag.gaps.publishers(topic, sub.get_publisher_count())
        if not discover:
            return
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


def say(text: str) -> None:
    """A line on standard output (the launcher reads it), unless that cannot be written:
    with the log on a full disk the recorder must not die of its own messages."""
    with contextlib.suppress(OSError):
        print(text, flush=True)


def _with_depth(qos: QoSProfile) -> QoSProfile:
    """``qos`` with a queue of OUTPUT_DEPTH, also for the latched topics: their
    publishers keep only the last sample for late joiners, but a recorder that keeps
    only one would lose every sample it has not taken before the next arrives (the
    supervisor publishes the rotation centre for every poses message)."""
    return QoSProfile(
        depth=max(qos.depth, OUTPUT_DEPTH),
        reliability=qos.reliability,
        durability=qos.durability,
        history=qos.history,
    )


def _split(text: str) -> Split:
    """``--split``: :func:`aes_ros.ros.bag.parse_split`, its error argparse's."""
    try:
        return parse_split(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _count(minimum: int) -> Callable[[str], int]:
    """An argparse ``type``: an integer >= ``minimum``."""

    def parse(text: str) -> int:
        if not text.strip().isdigit() or int(text) < minimum:
            raise argparse.ArgumentTypeError(f"{text!r}: need an integer >= {minimum}")
        return int(text)

    return parse


def main(argv: list[str] | None = None) -> int:
    """``python -m aes_ros.ros.recorder OUT.mcap [--robots N] [--split SIZE|DURATION]
    [--keep K] [--ros-args ...]``.

    Exit code 0 after SIGINT/SIGTERM (bag closed), 2 when an earlier recording's files
    are at OUTPUT (without ``--overwrite``), 3 when the bag cannot be written.
    """
    argv = sys.argv[1:] if argv is None else argv
    cut = argv.index("--ros-args") if "--ros-args" in argv else len(argv)
    parser = argparse.ArgumentParser(
        prog="python -m aes_ros.ros.recorder", description=__doc__.splitlines()[0]
    )
    parser.add_argument(
        "output", type=Path,
        help="the MCAP file to write (its first segment; further ones run_1.mcap, …)",
    )  # fmt: skip
    parser.add_argument("--robots", type=int, default=0, help="subscribe cmd_vel of N robots")
    parser.add_argument(
        "--images", type=float, default=0.0, metavar="RATE",
        help="also record the camera's frames, at most RATE a second (default: none)",
    )  # fmt: skip
    parser.add_argument(
        "--after", type=Path, nargs="*", default=[],
        help="the earlier segments of this recording: count what was lost between them",
    )  # fmt: skip
    parser.add_argument(
        "--split", type=_split, default=None, metavar="SIZE|DURATION",
        help=f"go on in the next segment once a segment reaches this: {SPLIT_FORMS} "
        "(default: one segment)",
    )  # fmt: skip
    parser.add_argument(
        "--keep", type=_count(1), default=None, metavar="K",
        help="keep only the newest K segments (K >= 1), deleting older ones (default: all)",
    )  # fmt: skip
    parser.add_argument(
        "--segment", type=_count(0), default=0, metavar="I",
        help="start with segment I of the recording OUTPUT (a restarted recorder: the "
        "next number; default 0: a new recording, refused where an earlier one's files are)",
    )  # fmt: skip
    parser.add_argument(
        "--overwrite", action="store_true",
        help="a new recording where an earlier one's files are (OUTPUT, its numbered "
        "segments, its journal): remove those first instead of refusing (exit code 2)",
    )  # fmt: skip
    args = parser.parse_args(argv[:cut])
    try:  # the bag first: a recording refused or impossible starts no ROS at all
        # the journal if the recording has one: reading the segments takes minutes
        journal = read_journal(args.output) if args.after or args.segment else None
        after: dict[str, tuple[int, int]] = {}
        if args.after:
            after = (journal.last if journal else None) or last_sequences(args.after)
        # segment 0 is a new recording: an earlier one's losses are not its own
        lost = journal.lost if journal and args.segment else None
        bag = Recording(
            args.output,
            split=args.split,
            keep=args.keep,
            segment=args.segment,
            after=after,
            lost=lost,
            say=say,
            overwrite=args.overwrite,
        )
    except EarlierRunError as exc:
        say(f"recording refused: {exc}")
        return 2
    except OSError as exc:
        say(f"recording stopped: cannot write {args.output}: {exc.strerror or exc}")
        return names.RECORDER_CANNOT_WRITE
    node = None
    code = 0
    try:
        # SIGINT/SIGTERM end spin(); what the readers still hold is written, then the
        # bag is closed.
        rclpy.init(args=["recorder", *argv[cut:]], signal_handler_options=SignalHandlerOptions.NO)
        node = RecorderNode(bag, args.robots, images_rate=args.images)
        say(f"{names.RECORDER_STARTED} {bag.path}")
        spin([node], SingleThreadedExecutor())
        drained = node.take_remaining()
        say(f"stopped; {drained} messages taken from the queues after the stop")
    except CannotWriteError as exc:
        say(f"recording stopped: {exc}; the bag holds what was written before")
        code = names.RECORDER_CANNOT_WRITE
    except ExternalShutdownException:
        pass
    finally:
        with contextlib.suppress(OSError):
            bag.close()  # with the last segment's metadata
        if node is not None:
            say(bag.summary_line())
            node.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == "__main__":
    sys.exit(main())
