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
