"""A recording into MCAP segments, each complete on its own (:class:`Recording`): the
recorder's writer, with losses counted, splitting, keeping the newest segments and the
journal a restarted recorder continues from."""

from __future__ import annotations

import json
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path

from aes_ros.previous_run import refuse, remove
from aes_ros.ros.bag.gaps import SequenceGaps
from aes_ros.ros.bag.segments import bag_segments, recording_files, segment_path, sequences_path
from aes_ros.ros.bag.split import Split
from aes_ros.ros.bag.writer import RECORDING_METADATA, BagWriter


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
