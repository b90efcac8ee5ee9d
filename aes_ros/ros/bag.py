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
swarm into a :class:`Recording` is :mod:`aes_ros.ros.recorder`.

A recording is one or more segments, each a complete MCAP file on its own:
``run.mcap``, then ``run_1.mcap``, ``run_2.mcap``… (:func:`segment_path`). The next
segment gets the next number whatever starts it: the recorder splitting at a size or
a duration (:class:`Split`, like ``ros2 bag record --max-bag-size`` /
``--max-bag-duration``) or a recorder restarted after a crash
(:func:`next_segment`). :func:`bag_segments` lists them in order, also when the
oldest were deleted (``keep``); :func:`read_bags` reads them as one recording.
A new recording never replaces files it did not write: where a segment or the journal
of an earlier recording at its path exists (:func:`recording_files`), it is refused
unless asked to replace that recording (``overwrite``; ``--overwrite``).
"""

from __future__ import annotations

import glob
import json
import os
import re
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any, NamedTuple

from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from rosidl_adapter.parser import parse_message_string

from aes_ros.previous_run import refuse, remove

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


def segment_index(path: str | Path, segment: str | Path) -> int | None:
    """The number of ``segment`` in the recording ``path`` (0 for ``path`` itself), or
    None if it is not one of its segment names."""
    path, segment = Path(path), Path(segment)
    if segment.parent != path.parent:
        return None
    if segment.name == path.name:
        return 0
    pattern = rf"{re.escape(path.stem)}_([1-9][0-9]*){re.escape(path.suffix)}"
    match = re.fullmatch(pattern, segment.name)
    return int(match.group(1)) if match else None


def bag_segments(path: str | Path) -> list[Path]:
    """The segments of the recording ``path`` that exist, in the order of their numbers
    (gaps allowed: a recording with ``keep`` has deleted its oldest)."""
    path = Path(path)
    numbered = path.parent.glob(f"{glob.escape(path.stem)}_*{glob.escape(path.suffix)}")
    found = {segment_index(path, p): p for p in [path, *numbered] if p.is_file()}
    found.pop(None, None)
    return [found[i] for i in sorted(found)]


def recording_files(path: str | Path) -> list[Path]:
    """Every file of a recording at ``path`` that exists, a dangling symbolic link too:
    its segments in the order of their numbers, then its sequences journal."""
    path = Path(path)
    numbered = path.parent.glob(f"{glob.escape(path.stem)}_*{glob.escape(path.suffix)}")
    found = {segment_index(path, p): p for p in [path, *numbered] if os.path.lexists(p)}
    found.pop(None, None)
    journal = sequences_path(path)
    return [found[i] for i in sorted(found)] + ([journal] if os.path.lexists(journal) else [])


def next_segment(path: str | Path) -> int:
    """The number of the next segment of the recording ``path``: one past the highest
    that exists (0 when none does)."""
    segments = bag_segments(path)
    return segment_index(path, segments[-1]) + 1 if segments else 0


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


def sequences_path(path: str | Path) -> Path:
    """The sequences journal of the recording ``path``: ``run.mcap`` -> ``run.sequences.json``."""
    path = Path(path)
    return path.with_name(f"{path.stem}.sequences.json")


class Journal(NamedTuple):
    """A recording's sequences journal (:func:`read_journal`)."""

    #: (sequence number, publish time [ns]) of the last message of each topic on disk.
    last: dict[str, tuple[int, int]]
    #: Messages lost per topic over every life of the recording, up to that flush.
    lost: dict[str, int]


def read_journal(path: str | Path) -> Journal | None:
    """The recording ``path``'s sequences journal (:meth:`Recording.flush` writes it:
    ``{"last": {topic: [n, sent]}, "lost": {topic: k}}``; one of the first format, only
    the ``last`` mapping, has no losses); None without one (or a damaged one)."""
    try:
        data = json.loads(sequences_path(path).read_text())
        # topic names start with "/": a key "last" is the current format
        last, lost = (data["last"], data.get("lost", {})) if "last" in data else (data, {})
        return Journal(
            {topic: (int(n), int(sent)) for topic, (n, sent) in last.items()},
            {topic: int(n) for topic, n in lost.items()},
        )
    except (OSError, ValueError, TypeError, AttributeError):
        return None


def read_sequences(path: str | Path) -> dict[str, tuple[int, int]] | None:
    """(sequence number, publish time [ns]) of the last message of each topic on disk,
    from the recording ``path``'s journal (:func:`read_journal`); None without one."""
    journal = read_journal(path)
    return None if journal is None else journal.last


def raw_messages(paths: Iterable[str | Path]) -> Iterator[tuple[Any, Any]]:
    """(MCAP channel, message record) of every message of the segments ``paths`` in
    order, in write order, undecoded; a segment cut off by a kill ends at its last
    complete record."""
    from mcap.reader import NonSeekingReader

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
                yield channel, message


def last_sequences(paths: Iterable[str | Path]) -> dict[str, tuple[int, int]]:
    """(publisher's sequence number, publish time [ns]) of the last message of each
    topic in the segments ``paths`` (read up to the end of what a killed recorder left).

    Reads every message: a segment of a 100-robot swarm holds 5000 a second, so a
    restarted recorder reads the recording's journal (:func:`read_sequences`) instead;
    this is for recordings without one."""
    last: dict[str, tuple[int, int]] = {}
    for channel, message in raw_messages(paths):
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
    too; ``lost`` continues the counts of earlier lives of a recording (its journal's,
    :func:`read_journal`). Counting needs one publisher per topic: :meth:`publishers`
    marks a topic with more as not countable.
    """

    def __init__(
        self,
        start: dict[str, tuple[int, int]] | None = None,
        lost: dict[str, int] | None = None,
    ) -> None:
        self.lost: dict[str, int] = {t: n for t, n in (lost or {}).items() if n}
        self.uncountable: set[str] = set()
        #: (sequence number, send time [ns]) of the last message of each topic.
        self.last: dict[str, tuple[int, int]] = dict(start or {})

    def seen(self, topic: str, sequence: int | None, sent_ns: int | None = None) -> int:
        """Message number ``sequence`` of ``topic``, sent at ``sent_ns``, arrived; returns
        how many were lost right before it (0 when not countable)."""
        if sequence is None:
            self.uncountable.add(topic)
            return 0
        sent = 0 if sent_ns is None else sent_ns
        last = self.last.get(topic)
        if last is not None and sequence <= last[0] and sent <= last[1]:
            return 0  # resent history, already counted
        self.last[topic] = (sequence, sent)
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


# ----------------------------------------------------------------------------- splitting

#: Units of a split size (decimal and binary prefixes), lower case.
SIZE_UNITS = {
    "b": 1, "kb": 10**3, "mb": 10**6, "gb": 10**9, "tb": 10**12,
    "kib": 2**10, "mib": 2**20, "gib": 2**30, "tib": 2**40,
}  # fmt: skip
#: Units of a split duration, lower case.
DURATION_UNITS = {"s": 1.0, "min": 60.0, "h": 3600.0}
#: The smallest split: below this a segment would be mostly schemas and summary.
MIN_SPLIT_BYTES = 64 * 2**10
MIN_SPLIT_SECONDS = 1.0
#: What a split may be, for error messages.
SPLIT_FORMS = (
    "a size (e.g. 500MiB, 1GiB; units B, kB, MB, GB, TB, KiB, MiB, GiB, TiB; at least "
    "64KiB) or a duration (e.g. 30s, 10min, 2h; units s, min, h; at least 1s)"
)


class Split(NamedTuple):
    """When a recording goes on in its next segment: once the current one has ``size``
    bytes on disk, or spans ``seconds`` of log time (wall time) from its first message.
    Exactly one of the two is set (:func:`parse_split`)."""

    size: int | None = None
    seconds: float | None = None


def parse_split(text: str) -> Split:
    """A :class:`Split` from ``500MiB``, ``1GiB``, ``2.5GB``, ``30s``, ``10min``, ``2h``…
    (units :data:`SIZE_UNITS` and :data:`DURATION_UNITS`, any case); ValueError saying
    what is allowed (:data:`SPLIT_FORMS`) otherwise."""
    match = re.fullmatch(r"\s*([0-9]+(?:\.[0-9]*)?|\.[0-9]+)\s*([a-zA-Z]+)\s*", str(text))
    unit = match.group(2).lower() if match else ""
    if unit in SIZE_UNITS:
        size = round(float(match.group(1)) * SIZE_UNITS[unit])
        if size >= MIN_SPLIT_BYTES:
            return Split(size=size)
    elif unit in DURATION_UNITS:
        seconds = float(match.group(1)) * DURATION_UNITS[unit]
        if seconds >= MIN_SPLIT_SECONDS:
            return Split(seconds=seconds)
    raise ValueError(f"{text!r} is not allowed; need {SPLIT_FORMS}")


class Recording:
    """A recording into MCAP segments, each complete on its own (thread-safe).

    Like :class:`BagWriter` (``add_topic``, ``write``, ``flush``, ``close``,
    ``counts`` and ``path`` of the open segment), and besides:

    - losses: each message's publisher's sequence number and send time go to
      :attr:`gaps` (:class:`SequenceGaps`; ``after``: the last numbers of the
      segments before, :func:`last_sequences`), and every segment gets, when it
      is closed, its own ``aes_swarm.recording`` metadata (:meth:`summary`: its
      messages and the losses counted while it was open, per topic); ``lost``: the
      losses earlier lives of the recording counted (:func:`read_journal`), from which
      :attr:`gaps` counts on, so that :meth:`summary_line` and the journal hold the
      whole recording's;
    - ``split``: once the open segment reaches the :class:`Split`'s size or
      duration, the next message goes into the next segment: the open one is
      closed first (summary, metadata), so every segment but a killed
      recorder's last is complete. Numbering is continuous across the switch, so
      it counts no loss there. The next segment starts with the last message of
      each latched topic (``add_topic(latched=True)``: transient-local, the
      supervisor's) re-written with its own send time and sequence number and the
      new segment's start as log time, so that one segment opened alone has them
      (rosbag2 does not do this); :func:`read_bags` reads them once;
    - ``keep``: after opening a segment, only the newest ``keep`` segments of the
      recording stay; older ones are deleted (this recording's: a new one starts where
      no other is);
    - ``segment``: the first segment's number; ``0`` starts a new recording, a
      restarted recorder continues with :func:`next_segment`. A new recording where
      files of an earlier one are (:func:`recording_files`; they would be read as part
      of this one) raises :class:`~aes_ros.previous_run.EarlierRunError` naming them,
      unless ``overwrite``: then those files, and only those, are removed first
      (:attr:`replaced`, said). No segment file is ever opened over an existing one.

    ``say`` gets a line for every switch (None: nothing is said).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        split: Split | None = None,
        keep: int | None = None,
        segment: int = 0,
        after: dict[str, tuple[int, int]] | None = None,
        lost: dict[str, int] | None = None,
        say: Callable[[str], None] | None = None,
        overwrite: bool = False,
    ) -> None:
        if keep is not None and keep < 1:
            raise ValueError(f"keep: {keep!r} is not allowed; need an integer >= 1")
        self.base = Path(path)
        self.split = split
        self.keep = keep
        self.gaps = SequenceGaps(after, lost)
        self.written: dict[str, int] = {}
        self.deleted: list[Path] = []
        self._say = say
        self._lock = threading.RLock()
        self._topics: dict[str, tuple[str, bool]] = {}
        self._sampled: set[str] = set()
        self._latched: dict[str, tuple[bytes, int, int]] = {}
        self._chunk = min(1024 * 1024, max(split.size // 8, 4096)) if split and split.size else None
        #: The earlier recording's files removed at the start (``overwrite``).
        self.replaced: list[Path] = []
        if segment == 0:  # a new recording at this path
            where, found = f"--record {self.base}", recording_files(self.base)
            earlier = refuse(found, where, overwrite, "an earlier recording")
            self.replaced = remove(earlier)
            if self.replaced and say is not None:
                gone = ", ".join(p.name for p in self.replaced)
                say(f"replaced the earlier recording {self.base}: removed {gone}")
        self.first = segment
        self._open(segment, None)

    # -- the open segment ---------------------------------------------------------------

    @property
    def path(self) -> Path:
        """The open segment's file."""
        return self._bag.path

    @property
    def index(self) -> int:
        """The open segment's number."""
        return self._index

    @property
    def counts(self) -> dict[str, int]:
        """Messages per topic in the open segment (latched ones carried over included)."""
        return self._bag.counts

    def _open(self, index: int, start_ns: int | None) -> None:
        path = segment_path(self.base, index)
        self._bag = BagWriter(path) if self._chunk is None else BagWriter(path, self._chunk)
        self._index = index
        self._start_ns = start_ns
        self._fresh = True
        # a segment's metadata counts its own losses, not those of the segments before
        # (nor of the recorder's earlier lives)
        self._lost_before = dict(self.gaps.lost)
        self.carried = 0
        for topic, (type_name, _) in self._topics.items():
            self._bag.add_topic(topic, type_name)
        for topic, (data, sent, number) in self._latched.items():
            self._bag.write(topic, data, start_ns, publish_time_ns=sent, sequence=number)
            self.carried += 1
        if self.keep is not None:
            for old in bag_segments(self.base)[: -self.keep]:
                if old != path:
                    old.unlink(missing_ok=True)
                    self.deleted.append(old)

    def _due(self, stamp: int) -> bool:
        """The open segment is full (:attr:`split`) and has a message of its own."""
        if self.split is None or self._fresh:
            return False
        if self.split.seconds is not None:
            return stamp - self._start_ns >= self.split.seconds * 1e9
        return self._bag.size >= self.split.size

    def _finish(self) -> None:
        """Close the open segment with its metadata."""
        if not self._bag.closed:
            self._bag.add_metadata(RECORDING_METADATA, self.summary())
            self._bag.close()

    def _switch(self, stamp: int) -> None:
        closed, messages = self._bag.path, sum(self._bag.counts.values())
        lost = sum(self._segment_lost().values())
        deleted = len(self.deleted)
        self._finish()
        self._open(self._index + 1, stamp)
        if self._say is not None:
            gone = ", ".join(p.name for p in self.deleted[deleted:])
            self._say(
                f"bag segment {closed.name} closed ({messages} messages, {lost} lost); "
                f"recording into {self.path.name}" + (f"; deleted {gone}" if gone else "")
            )

    # -- BagWriter's interface ----------------------------------------------------------

    def add_topic(
        self, topic: str, type_name: str, *, latched: bool = False, sampled: bool = False
    ) -> None:
        """A topic to record; ``latched``: its last message starts every next segment;
        ``sampled``: recorded on purpose not every message (losses not counted)."""
        with self._lock:
            if topic in self._topics:
                return
            self._bag.add_topic(topic, type_name)
            self._topics[topic] = (type_name, latched)
            if sampled:
                self._sampled.add(topic)
                self.gaps.uncountable.add(topic)
            self.written.setdefault(topic, 0)

    def write(
        self,
        topic: str,
        data: bytes,
        log_time_ns: int | None = None,
        publish_time_ns: int | None = None,
        sequence: int | None = None,
    ) -> int:
        """:meth:`BagWriter.write` into the open segment, or the next one when it is full;
        counts the messages lost before this one (:attr:`gaps`) and returns how many."""
        stamp = time.time_ns() if log_time_ns is None else log_time_ns
        sent = stamp if publish_time_ns is None else publish_time_ns
        with self._lock:
            if self._bag.closed:
                return 0
            if self._due(stamp):
                self._switch(stamp)
            if self._start_ns is None:
                self._start_ns = stamp
            number = self._bag.write(topic, data, stamp, sent, sequence)
            self._fresh = False
            self.written[topic] += 1
            if self._topics[topic][1]:
                self._latched[topic] = (bytes(data), sent, number)
            return self.gaps.seen(topic, sequence, publish_time_ns)

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """A metadata record in the open segment."""
        with self._lock:
            self._bag.add_metadata(name, data)

    def flush(self) -> None:
        """:meth:`BagWriter.flush` of the open segment, then the sequences journal
        (:func:`read_journal`: the last number of each topic now on disk and the losses
        counted so far over every life of the recording, written to a temporary file
        and renamed), from which a restarted recorder counts what was lost while none
        ran without reading the segments, and continues the loss counts."""
        with self._lock:
            self._bag.flush()
            self._write_journal()

    def _write_journal(self) -> None:
        journal = sequences_path(self.base)
        temporary = journal.with_name("." + journal.name + ".tmp")
        data = json.dumps({"last": self.gaps.last, "lost": self.gaps.lost}).encode()
        # O_NOFOLLOW: a link planted at the temporary name is refused, not written through
        flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW
        fd = os.open(temporary, flags, 0o644)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view) :]
        finally:
            os.close(fd)
        os.replace(temporary, journal)

    def close(self) -> None:
        """Write the open segment's metadata and summary and close it, then the journal
        (everything is on disk now; idempotent)."""
        with self._lock:
            self._finish()
            self._write_journal()

    @property
    def closed(self) -> bool:
        return self._bag.closed

    # -- what was recorded --------------------------------------------------------------

    def _segment_lost(self) -> dict[str, int]:
        before = self._lost_before
        return {t: max(n - before.get(t, 0), 0) for t, n in self.gaps.lost.items()}

    def summary(self) -> dict[str, str]:
        """The open segment's ``aes_swarm.recording`` metadata: its number, the latched
        messages it starts with, and per topic the messages in it and the losses counted
        while it was open (``lost_total``: their sum)."""
        with self._lock:
            lost = self._segment_lost()
            out = {"lost_total": str(sum(lost.values())), "segment": str(self._index)}
            if self.carried:
                out["carried_over"] = str(self.carried)
            for topic, count in sorted(self._bag.counts.items()):
                if topic in self._sampled:
                    text = "not counted (sampled)"
                elif topic in self.gaps.uncountable:
                    text = "not counted (several publishers)"
                else:
                    text = str(lost.get(topic, 0))
                out[topic] = f"recorded {count}, lost {text}"
            return out

    def summary_line(self) -> str:
        """``bag PATH: N messages on T topics, L lost``: N over every segment this recorder
        wrote, L over the whole recording, the losses of earlier lives (``lost``, from the
        journal) included (with the topics that lost any; the segments when there are
        several)."""
        with self._lock:
            total = sum(self.written.values())
            lost = self.gaps.total()
            which = ", ".join(f"{t} {n}" for t, n in sorted(self.gaps.lost.items()) if n)
            where = str(self.path)
            if self._index != self.first:
                first = segment_path(self.base, self.first)
                kept = f", the newest {self.keep} kept" if self.keep is not None else ""
                count = self._index - self.first + 1
                where = f"{first} … {self.path.name} ({count} segments{kept})"
            return f"bag {where}: {total} messages on {len(self._topics)} topics, {lost} lost" + (
                f" ({which})" if which else ""
            )
