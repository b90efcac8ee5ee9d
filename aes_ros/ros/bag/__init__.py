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

One module a job: :mod:`~aes_ros.ros.bag.writer` (one MCAP file),
:mod:`~aes_ros.ros.bag.reader`, :mod:`~aes_ros.ros.bag.segments` (names and journal),
:mod:`~aes_ros.ros.bag.gaps` (losses), :mod:`~aes_ros.ros.bag.split` and
:mod:`~aes_ros.ros.bag.recording` (the recorder's rotating writer); the names below are
the package's interface.
"""

from aes_ros.ros.bag.gaps import SequenceGaps, last_sequences
from aes_ros.ros.bag.reader import (
    bag_is_closed,
    raw_messages,
    read_bag,
    read_bags,
    recording_summary,
)
from aes_ros.ros.bag.recording import Recording
from aes_ros.ros.bag.segments import (
    Journal,
    bag_segments,
    next_segment,
    read_journal,
    read_sequences,
    recording_files,
    segment_index,
    segment_path,
    sequences_path,
)
from aes_ros.ros.bag.split import (
    DURATION_UNITS,
    MIN_SPLIT_BYTES,
    MIN_SPLIT_SECONDS,
    SIZE_UNITS,
    SPLIT_FORMS,
    Split,
    parse_split,
)
from aes_ros.ros.bag.writer import (
    RECORDING_METADATA,
    SEPARATOR,
    BagWriter,
    message_definition,
    share_dirs,
)

__all__ = [
    "DURATION_UNITS",
    "MIN_SPLIT_BYTES",
    "MIN_SPLIT_SECONDS",
    "RECORDING_METADATA",
    "SEPARATOR",
    "SIZE_UNITS",
    "SPLIT_FORMS",
    "BagWriter",
    "Journal",
    "Recording",
    "SequenceGaps",
    "Split",
    "bag_is_closed",
    "bag_segments",
    "last_sequences",
    "message_definition",
    "next_segment",
    "parse_split",
    "raw_messages",
    "read_bag",
    "read_bags",
    "read_journal",
    "read_sequences",
    "recording_files",
    "recording_summary",
    "segment_index",
    "segment_path",
    "sequences_path",
    "share_dirs",
]
