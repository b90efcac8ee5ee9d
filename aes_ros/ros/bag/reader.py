"""Reading bags back: decoded messages of one bag or of a recording's segments as one,
the recorder's counts, raw records; a segment cut off by a kill is read up to its end."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from aes_ros.ros.bag.writer import RECORDING_METADATA


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
