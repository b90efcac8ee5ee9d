"""Messages lost on their way to the recorder, counted from the publishers' sequence
numbers (:class:`SequenceGaps`), continued from earlier segments (:func:`last_sequences`)."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from aes_ros.ros.bag.reader import raw_messages


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
