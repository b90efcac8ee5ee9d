"""ROS 2 bags in MCAP: writing raw CDR messages, reading them back.

The bag follows the ``ros2`` MCAP profile that rosbag2's MCAP storage writes:
one ``ros2msg`` schema per message type (the ``.msg`` text of the type and of
every type it uses, in rosbag2's concatenated layout) and the messages as the
CDR bytes that came over the wire. The container is written by the ``mcap``
package; any MCAP tool, ``ros2 bag play`` or Foxglove reads it::

    from aes_ros.ros.bag import read_bag
    for topic, log_time_ns, msg in read_bag("run.mcap", topics=["/swarm/alignment"]):
        print(log_time_ns, msg.data)

(:func:`read_bag` is ``mcap.reader`` with the ``mcap_ros2`` decoder; the older
``mcap_ros2.reader.read_ros2_messages`` works too.) The node that records the
swarm into a :class:`BagWriter` is :mod:`aes_ros.ros.recorder`.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from rosidl_adapter.parser import parse_message_string

#: Separator between the definitions of a schema (rosbag2 / ROS 1 style).
SEPARATOR = "=" * 80
#: Name of the metadata record with the recorder's counts (recorded, lost per topic).
RECORDING_METADATA = "aes_swarm.recording"


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

    def write(
        self,
        topic: str,
        data: bytes,
        log_time_ns: int | None = None,
        publish_time_ns: int | None = None,
        sequence: int | None = None,
    ) -> None:
        """Append one serialized message of a topic added with :meth:`add_topic`.

        ``log_time_ns``: when it was received (default now); ``publish_time_ns``:
        when it was sent (default the log time); ``sequence``: the publisher's
        sequence number (default: counted per topic). With the publisher's own
        time and number, a message is recognised again in another bag segment.
        """
        stamp = time.time_ns() if log_time_ns is None else log_time_ns
        with self._lock:
            if self.closed:
                return
            channel = self._channels[topic]
            self._sequence[channel] += 1
            number = self._sequence[channel] if sequence is None else sequence
            sent = stamp if publish_time_ns is None else publish_time_ns
            self._writer.add_message(channel, stamp, bytes(data), sent, number & 0xFFFFFFFF)
            self.counts[topic] += 1

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """A metadata record (MCAP ``Metadata``: a name and string pairs)."""
        with self._lock:
            if not self.closed:
                self._writer.add_metadata(name, data)

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
    return read_bags([path], topics)


def segment_path(path: str | Path, index: int) -> Path:
    """Segment ``index`` of a recording: ``run.mcap``, then ``run_1.mcap``, ``run_2.mcap``…"""
    path = Path(path)
    return path if index == 0 else path.with_name(f"{path.stem}_{index}{path.suffix}")


def bag_segments(path: str | Path) -> list[Path]:
    """The segments of the recording ``path`` that exist, in order."""
    out = []
    while (segment := segment_path(path, len(out))).exists():
        out.append(segment)
    return out


def read_bags(
    paths: Iterable[str | Path], topics: Iterable[str] | None = None
) -> Iterator[tuple[str, int, Any]]:
    """:func:`read_bag` of several segments in order, each message once: a recorder
    restarted into a new segment is resent what its writers still kept (the
    transient-local history), which the segment before may already hold. A message is
    the same if its topic, publish time and publisher's sequence number are."""
    from mcap.reader import NonSeekingReader, make_reader
    from mcap_ros2.decoder import DecoderFactory

    wanted = None if topics is None else list(topics)
    seen: set[tuple[str, int, int]] = set()
    for path in paths:
        closed = bag_is_closed(path)
        with open(path, "rb") as fh:
            factory = [DecoderFactory()]
            if closed:
                reader = make_reader(fh, decoder_factories=factory)
                messages = reader.iter_decoded_messages(topics=wanted)
            else:
                reader = NonSeekingReader(fh, decoder_factories=factory)
                messages = reader.iter_decoded_messages(topics=wanted, log_time_order=False)
            while True:
                try:
                    _, channel, message, msg = next(messages)
                except StopIteration:
                    break
                except Exception:  # a segment cut off by a kill: the end of what is there
                    break
                key = (channel.topic, message.publish_time, message.sequence)
                if key in seen:
                    continue
                seen.add(key)
                yield channel.topic, message.log_time, msg


def recording_summary(path: str | Path) -> dict[str, str]:
    """The recorder's ``aes_swarm.recording`` metadata of a closed bag (recorded and lost
    messages per topic); empty for a bag whose recorder was killed."""
    from mcap.reader import make_reader

    if not bag_is_closed(path):
        return {}
    with open(path, "rb") as fh:
        for record in make_reader(fh).iter_metadata():
            if record.name == RECORDING_METADATA:
                return dict(record.metadata)
    return {}


def last_sequences(paths: Iterable[str | Path]) -> dict[str, tuple[int, int]]:
    """(publisher's sequence number, publish time [ns]) of the last message of each
    topic in the segments ``paths`` (read up to the end of what a killed recorder left)."""
    from mcap.reader import NonSeekingReader

    last: dict[str, tuple[int, int]] = {}
    for path in paths:
        with open(path, "rb") as fh:
            messages = NonSeekingReader(fh).iter_messages(log_time_order=False)
            while True:
                try:
                    _, channel, message = next(messages)
                except StopIteration:
                    break
                except Exception:  # the record cut off by a kill: the end of what is there
                    break
                previous = last.get(channel.topic)
                if previous is None or message.publish_time >= previous[1]:
                    last[channel.topic] = (message.sequence, message.publish_time)
    return last


class SequenceGaps:
    """Messages lost on their way to the recorder, counted per topic from the
    publishers' sequence numbers and send times (pure).

    The next number after the last one is the next message; a jump of k is k - 1
    lost. A number not above the last one is either a message sent before the last
    one (a late joiner is resent a publisher's history: not new, not lost) or,
    when it was sent after it, a new publisher (a restarted process starts at 1):
    counting starts over. ``start`` continues from earlier segments
    (:func:`last_sequences`), so that what was lost while no recorder ran counts
    too. Counting needs one publisher per topic: :meth:`publishers` marks a topic
    with more as not countable.
    """

    def __init__(self, start: dict[str, tuple[int, int]] | None = None) -> None:
        self.lost: dict[str, int] = {}
        self.uncountable: set[str] = set()
        self._last: dict[str, tuple[int, int]] = dict(start or {})

    def seen(self, topic: str, sequence: int | None, sent_ns: int | None = None) -> int:
        """Message number ``sequence`` of ``topic``, sent at ``sent_ns``, arrived; returns
        how many were lost right before it (0 when not countable)."""
        if sequence is None:
            self.uncountable.add(topic)
            return 0
        sent = 0 if sent_ns is None else sent_ns
        last = self._last.get(topic)
        if last is not None and sequence <= last[0] and sent <= last[1]:
            return 0  # resent history, already counted
        self._last[topic] = (sequence, sent)
        if last is None or sequence <= last[0] or topic in self.uncountable:
            return 0
        gap = sequence - last[0] - 1
        if gap:
            self.lost[topic] = self.lost.get(topic, 0) + gap
        return gap

    def publishers(self, topic: str, count: int) -> None:
        """``topic`` has ``count`` publishers now: with more than one it is not countable."""
        if count > 1:
            self.uncountable.add(topic)
            self.lost.pop(topic, None)

    def total(self) -> int:
        return sum(self.lost.values())
