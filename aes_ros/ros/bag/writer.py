"""One MCAP file in the ``ros2`` profile, written from raw CDR messages
(:class:`BagWriter`), and the ``ros2msg`` schema text of a message type."""

from __future__ import annotations

import os
import sys
import threading
import time
from pathlib import Path

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

    def __init__(self, path: str | Path, chunk_size: int = 1024 * 1024) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # "x": a file already there (another recording's, a planted link) is never replaced
        self._file = open(self.path, "xb")  # closed in close()
        self._writer = McapWriter(
            self._file, chunk_size=chunk_size, compression=CompressionType.ZSTD
        )
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
    ) -> int:
        """Append one serialized message of a topic added with :meth:`add_topic`;
        returns the sequence number it was stored with.

        ``log_time_ns``: when it was received (default now); ``publish_time_ns``:
        when it was sent (default the log time); ``sequence``: the publisher's
        sequence number (default: counted per topic). With the publisher's own
        time and number, a message is recognised again in another bag segment.
        """
        stamp = time.time_ns() if log_time_ns is None else log_time_ns
        with self._lock:
            if self.closed:
                return 0 if sequence is None else sequence & 0xFFFFFFFF
            channel = self._channels[topic]
            self._sequence[channel] += 1
            number = (self._sequence[channel] if sequence is None else sequence) & 0xFFFFFFFF
            sent = stamp if publish_time_ns is None else publish_time_ns
            self._writer.add_message(channel, stamp, bytes(data), sent, number)
            self.counts[topic] += 1
            return number

    @property
    def size(self) -> int:
        """Bytes written to the file so far (finished chunks; the open one is not)."""
        with self._lock:
            return self.path.stat().st_size if self.closed else self._file.tell()

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
