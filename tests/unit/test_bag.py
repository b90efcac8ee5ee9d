"""The MCAP bag: message schemas, segments, losses counted from sequence numbers
(no DDS: the recorder itself runs in tests/system/test_recording.py)."""

from __future__ import annotations

from pathlib import Path

from rclpy.serialization import serialize_message
from std_msgs.msg import Float64

from aes_ros.ros.bag import (
    RECORDING_METADATA,
    BagWriter,
    SequenceGaps,
    bag_segments,
    last_sequences,
    message_definition,
    read_bags,
    recording_summary,
    segment_path,
)


def test_bag_schemas_are_complete_ros2msg_definitions() -> None:
    """A schema holds the type's .msg text and every type it uses (rosbag2 layout)."""
    text = message_definition("geometry_msgs/msg/PoseArray")
    assert text.startswith("# An array of poses")
    for dep in ("std_msgs/Header", "builtin_interfaces/Time", "geometry_msgs/Pose",
                "geometry_msgs/Point", "geometry_msgs/Quaternion"):  # fmt: skip
        assert f"MSG: {dep}\n" in text
        assert text.count(f"MSG: {dep}\n") == 1


def float64(value: float) -> bytes:
    return serialize_message(Float64(data=value))


def write_segment(path: Path, values: list[int], start_ns: int, closed: bool = True) -> None:
    """Messages ``values`` of one publisher: sequence number = value, sent 1 ms apart."""
    bag = BagWriter(path)
    bag.add_topic("/swarm/alignment", "std_msgs/msg/Float64")
    for v in values:
        sent = start_ns + v * 1_000_000
        bag.write("/swarm/alignment", float64(float(v)), sent, publish_time_ns=sent, sequence=v)
    if closed:
        bag.add_metadata(RECORDING_METADATA, {"lost_total": "0"})
        bag.close()
    else:
        bag.flush()  # a recorder killed after its last flush


def test_segments_read_back_in_order_each_message_once(tmp_path: Path) -> None:
    """A restarted recorder is resent what its writers still keep (here 4..6): the
    segments read back as one recording, nothing twice."""
    first = segment_path(tmp_path / "run.mcap", 0)
    write_segment(first, [1, 2, 3, 4, 5, 6], 0, closed=False)
    write_segment(segment_path(first, 1), [4, 5, 6, 7, 8], 0)
    assert bag_segments(first) == [tmp_path / "run.mcap", tmp_path / "run_1.mcap"]
    values = [msg.data for _, _, msg in read_bags(bag_segments(first))]
    assert values == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]
    assert last_sequences([first]) == {"/swarm/alignment": (6, 6_000_000)}
    assert recording_summary(segment_path(first, 1)) == {"lost_total": "0"}
    assert recording_summary(first) == {}  # killed: no summary


def test_gaps_in_sequence_numbers_are_counted_as_lost() -> None:
    gaps = SequenceGaps()
    for seq in (1, 2, 5, 6):  # 3 and 4 lost
        gaps.seen("/mona_0/cmd_vel", seq, seq)
    assert gaps.lost == {"/mona_0/cmd_vel": 2}
    # A restarted publisher starts at 1 again, sent later: counting starts over.
    assert gaps.seen("/mona_0/cmd_vel", 1, 100) == 0
    assert gaps.seen("/mona_0/cmd_vel", 3, 101) == 1
    # History resent to a late joiner (sent before the last one): not new, not lost.
    assert gaps.seen("/mona_0/cmd_vel", 2, 50) == 0
    assert gaps.total() == 3


def test_gaps_continue_across_segments_and_skip_shared_topics() -> None:
    """What was lost while no recorder ran counts in the next segment; a topic with
    several publishers is not countable."""
    gaps = SequenceGaps(start={"/swarm/poses": (40, 40)})
    assert gaps.seen("/swarm/poses", 38, 38) == 0  # resent history
    assert gaps.seen("/swarm/poses", 61, 61) == 20
    gaps.seen("/swarm/cmd", 1, 1)
    gaps.seen("/swarm/cmd", 5, 5)
    gaps.publishers("/swarm/cmd", 2)
    assert gaps.lost == {"/swarm/poses": 20} and "/swarm/cmd" in gaps.uncountable
    assert gaps.seen("/swarm/cmd", 9, 9) == 0
