"""A recording split into segments (``--split``, ``--keep``): every segment a complete
MCAP that other readers open alone, with its own counts and losses and the latched
topics' last messages; the options through ``aes-swarm launch`` (no DDS: the real
recorder splits in tests/system/test_recording.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from helpers.bench import bench_module
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64

from aes_ros import scenario
from aes_ros.cli import main as aes_swarm
from aes_ros.previous_run import EarlierRunError
from aes_ros.ros.bag import (
    BagWriter,
    Journal,
    Recording,
    Split,
    bag_is_closed,
    bag_segments,
    last_sequences,
    next_segment,
    parse_split,
    read_bag,
    read_bags,
    read_journal,
    read_sequences,
    recording_summary,
    segment_path,
    sequences_path,
)
from aes_ros.ros.launch.commands import start_order
from aes_ros.ros.launch.config import LaunchConfig
from aes_ros.ros.launch.preflight import expected_bytes
from aes_ros.ros.launch.recovery import RestartCommands

STREAM = "/swarm/alignment"  # a stream, one message every STEP
LATCHED = "/swarm/enabled"  # a latched topic, written once at the start
STEP = 500_000_000  # [ns]
T0 = 1_700_000_000 * 10**9  # wall time [ns] of the first message


def float64(value: float) -> bytes:
    return serialize_message(Float64(data=value))


def start(path: Path, at: int = T0, **options) -> Recording:
    """A recording of STREAM and LATCHED, LATCHED's only message (-1, number 1, sent at
    T0) received at ``at``."""
    rec = Recording(path, **options)
    rec.add_topic(STREAM, "std_msgs/msg/Float64")
    rec.add_topic(LATCHED, "std_msgs/msg/Float64", latched=True)
    rec.write(LATCHED, float64(-1.0), at, T0, sequence=1)
    return rec


def write_stream(rec: Recording, numbers, flush_every: int = 0) -> None:
    """STREAM message k (value k, sequence number k + 1) at T0 + k STEP; a flush every
    ``flush_every`` messages, like the recorder's once a second."""
    for i, k in enumerate(numbers):
        t = T0 + k * STEP
        rec.write(STREAM, float64(float(k)), t, t, sequence=k + 1)
        if flush_every and i % flush_every == flush_every - 1:
            rec.flush()


def mcap_counts(path: Path) -> dict[str, int]:
    """Messages per topic by the mcap library's own reader, from the summary."""
    with open(path, "rb") as fh:
        summary = make_reader(fh).get_summary()
    counts = summary.statistics.channel_message_counts
    return {summary.channels[c].topic: n for c, n in counts.items()}


def stream_values(path: Path) -> list[float]:
    """STREAM's values in one segment, read by the mcap library with the mcap_ros2
    decoder alone (not the project's reader)."""
    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        return [msg.data for *_, msg in reader.iter_decoded_messages(topics=[STREAM])]


# ----------------------------------------------------------------------------- parsing


@pytest.mark.parametrize(
    ("text", "split"),
    [
        ("1GiB", Split(size=2**30)),
        ("500MiB", Split(size=500 * 2**20)),
        ("2.5GB", Split(size=2_500_000_000)),
        ("64KiB", Split(size=65536)),
        ("100 kb", Split(size=100_000)),
        ("30s", Split(seconds=30.0)),
        ("10min", Split(seconds=600.0)),
        ("0.5h", Split(seconds=1800.0)),
        ("1S", Split(seconds=1.0)),
    ],
)
def test_split_sizes_and_durations_parse(text: str, split: Split) -> None:
    assert parse_split(text) == split


@pytest.mark.parametrize(
    "text", ["", "10", "10x", "10m", "0s", "0.5s", "1KiB", "-1s", "nan s", "1e3s", "inf", "s"]
)
def test_bad_splits_say_what_is_allowed(text: str) -> None:
    with pytest.raises(ValueError, match=r"500MiB, 1GiB.*30s, 10min"):
        parse_split(text)


# ----------------------------------------------------------------------------- rotation


def test_split_by_time_gives_complete_segments_each_readable_alone(tmp_path: Path) -> None:
    """35 s of messages, a segment per 10 s of log time: four complete bags, each with
    its messages, its counts and the latched message; together the recording once."""
    rec = start(tmp_path / "run.mcap", split=Split(seconds=10.0))
    write_stream(rec, range(70))
    rec.close()
    segments = bag_segments(tmp_path / "run.mcap")
    assert segments == [segment_path(tmp_path / "run.mcap", i) for i in range(4)]
    for i, path in enumerate(segments):
        assert bag_is_closed(path)
        values = stream_values(path)
        assert values == [float(k) for k in range(20 * i, min(20 * i + 20, 70))]
        counts = mcap_counts(path)
        assert counts == {STREAM: len(values), LATCHED: 1}
        meta = recording_summary(path)
        assert meta["segment"] == str(i) and meta["lost_total"] == "0"
        assert meta[STREAM] == f"recorded {len(values)}, lost 0"
        assert meta.get("carried_over") == (str(1) if i else None)
        # the latched message starts every segment: its own send time and number, the
        # segment's start as log time
        with open(path, "rb") as fh:
            first = next(make_reader(fh).iter_messages(log_time_order=True))
        assert first[1].topic == LATCHED
        assert (first[2].publish_time, first[2].sequence) == (T0, 1)
        assert first[2].log_time == (T0 if i == 0 else T0 + 20 * i * STEP)
    whole = [(topic, msg.data) for topic, _, msg in read_bags(segments)]
    assert whole == [(LATCHED, -1.0)] + [(STREAM, float(k)) for k in range(70)]
    assert rec.summary_line() == (
        f"bag {tmp_path / 'run.mcap'} … run_3.mcap (4 segments): 71 messages on 2 topics, 0 lost"
    )


def test_split_by_size_keeps_segments_near_the_size(tmp_path: Path) -> None:
    """Incompressible messages, 20 kB a segment: the recording goes on in the next one
    once a segment's finished chunks reach the size; no message lost or doubled."""
    size = 20_000
    rec = Recording(tmp_path / "run.mcap", split=Split(size=size))
    rec.add_topic(STREAM, "std_msgs/msg/Float64")
    values = np.random.default_rng(0).random(3000)
    for k, value in enumerate(values):
        t = T0 + k * STEP
        rec.write(STREAM, float64(float(value)), t, t, sequence=k + 1)
    rec.close()
    segments = bag_segments(tmp_path / "run.mcap")
    assert len(segments) >= 3
    for path in segments[:-1]:  # a full segment: past the size by less than a chunk
        assert size <= path.stat().st_size < size + 8192, path.stat().st_size
    assert all(bag_is_closed(p) for p in segments)
    assert sum(mcap_counts(p)[STREAM] for p in segments) == len(values)
    read = [msg.data for _, _, msg in read_bags(segments)]
    assert np.array_equal(read, values)


def test_keep_deletes_the_oldest_segments(tmp_path: Path) -> None:
    """``keep=2``: the two newest segments stay, the first of them opens alone with the
    latched message; ``bag_segments`` lists what is left, in order."""
    rec = start(tmp_path / "run.mcap", split=Split(seconds=10.0), keep=2)
    write_stream(rec, range(70))
    rec.close()
    kept = bag_segments(tmp_path / "run.mcap")
    assert kept == [tmp_path / "run_2.mcap", tmp_path / "run_3.mcap"]
    assert rec.deleted == [tmp_path / "run.mcap", tmp_path / "run_1.mcap"]
    assert [t for t, _, _ in read_bag(kept[0])][:2] == [LATCHED, STREAM]
    assert [msg.data for _, _, msg in read_bags(kept, [STREAM])] == list(range(40, 70))
    assert "the newest 2 kept" in rec.summary_line()


def test_losses_are_counted_per_segment_and_none_at_a_switch(tmp_path: Path) -> None:
    """Numbers run on across a switch (nothing lost there); 3 messages missing in the
    second segment and 1 right after the third opened count in those segments only."""
    rec = start(tmp_path / "run.mcap", split=Split(seconds=10.0))
    numbers = [k for k in range(60) if k not in (25, 26, 27, 41)]
    write_stream(rec, numbers)
    rec.close()
    lost = [recording_summary(p)[STREAM] for p in bag_segments(tmp_path / "run.mcap")]
    assert lost == ["recorded 20, lost 0", "recorded 17, lost 3", "recorded 19, lost 1"]
    assert rec.summary_line().endswith(f", 4 lost ({STREAM} 4)")


def test_a_restarted_recorder_continues_the_numbering(tmp_path: Path) -> None:
    """A recorder killed in its third segment, restarted into the next number with the
    last sequence numbers on disk: one recording, in order, each message once, the
    resent history not counted twice; a new recording at the path, asked to, replaces them all."""
    base = tmp_path / "run.mcap"
    rec = start(base, split=Split(seconds=10.0))
    write_stream(rec, range(50))
    rec.flush()  # then killed: segment 2 has no summary
    assert next_segment(base) == 3 and not bag_is_closed(segment_path(base, 2))
    after = last_sequences(bag_segments(base))
    # resent history: the latched message, and the stream's last three (47..49)
    again = start(base, T0 + 47 * STEP, split=Split(seconds=10.0), segment=3, after=after)
    write_stream(again, range(47, 90))
    again.close()
    segments = bag_segments(base)
    assert segments == [segment_path(base, i) for i in range(6)]
    stream = [msg.data for _, _, msg in read_bags(segments, [STREAM])]
    assert stream == list(range(90))
    assert {recording_summary(p)["lost_total"] for p in segments[3:]} == {"0"}
    fresh = Recording(base, overwrite=True)
    fresh.close()
    assert bag_segments(base) == [base]


def test_the_journal_gives_a_restart_the_last_numbers_on_disk(tmp_path: Path) -> None:
    """Each flush leaves the last sequence numbers on disk in the journal, equal to what
    reading every segment gives (a restarted recorder reads it: the segments of a
    100-robot swarm take minutes); messages not flushed yet are not in it; a new
    recording that replaces the earlier one starts without one."""
    base = tmp_path / "run.mcap"
    rec = start(base, split=Split(seconds=10.0))
    write_stream(rec, range(50))
    rec.flush()
    write_stream(rec, range(50, 53))  # then killed before the next flush
    journal = read_sequences(base)
    assert journal == last_sequences(bag_segments(base))
    assert journal[STREAM] == (50, T0 + 49 * STEP) and journal[LATCHED] == (1, T0)
    fresh = Recording(base, overwrite=True)
    assert read_sequences(base) is None
    fresh.close()


def test_a_restart_continues_the_loss_counts_of_the_earlier_lives(tmp_path: Path) -> None:
    """The journal carries the losses counted so far: a recorder restarted after a kill
    starts from them, so its last line (and the journal) count the whole recording's,
    while each segment's metadata counts only the losses while it was open."""
    base = tmp_path / "run.mcap"
    rec = start(base, split=Split(seconds=10.0))
    write_stream(rec, [*range(10), *range(13, 30)])  # 10..12 lost, in segment 0
    rec.flush()  # then killed in segment 1: it prints no last line
    journal = read_journal(base)
    assert journal is not None and journal.lost == {STREAM: 3}
    again = start(
        base, T0 + 35 * STEP, split=Split(seconds=10.0), segment=next_segment(base),
        after=journal.last, lost=journal.lost,
    )  # fmt: skip
    # 30..34 lost while none ran, 50 and 51 in segment 2; segment 3 loses nothing
    write_stream(again, [*range(35, 50), *range(52, 60)])
    again.close()
    lost = {i: recording_summary(segment_path(base, i)).get("lost_total") for i in range(4)}
    assert lost == {0: "3", 1: None, 2: "7", 3: "0"}
    assert recording_summary(segment_path(base, 2))[STREAM] == "recorded 18, lost 7"
    assert again.summary_line().endswith(f"on 2 topics, 10 lost ({STREAM} 10)")
    assert read_journal(base).lost == {STREAM: 10}  # written at the end too
    with bench_module("bench_soak") as soak:
        assert soak.recorder_lost(tmp_path / "recorder.log", base) == 10


def test_a_journal_of_the_first_format_reads_without_losses(tmp_path: Path) -> None:
    """The first journals held only the last numbers ({topic: [n, sent]}): read as such,
    with no losses; a damaged one is none."""
    base = tmp_path / "run.mcap"
    sequences_path(base).write_text(f'{{"{STREAM}": [50, 1234]}}')
    assert read_sequences(base) == {STREAM: (50, 1234)}
    assert read_journal(base) == Journal({STREAM: (50, 1234)}, {})
    sequences_path(base).write_text('["damaged"')
    assert read_journal(base) is None and read_sequences(base) is None


def test_the_soak_takes_the_recorders_total_from_the_journal_else_its_last_line(
    tmp_path: Path,
) -> None:
    """bench_soak's lost_total: the counts are cumulative over the recorder's lives, so
    the journal's sum, or without one the last final line of the log (not their sum)."""
    base, log = tmp_path / "run.mcap", tmp_path / "recorder.log"
    with bench_module("bench_soak") as soak:
        assert soak.recorder_lost(log, base) == 0
        log.write_text(
            "bag run.mcap: 10 messages on 2 topics, 3 lost (/a 3)\n"
            "bag run_1.mcap: 20 messages on 2 topics, 5 lost (/a 5)\n"
        )
        assert soak.recorder_lost(log, base) == 5
        sequences_path(base).write_text('{"last": {}, "lost": {"/a": 6, "/b": 2}}')
        assert soak.recorder_lost(log, base) == 8


# ----------------------------------------------------------------------------- launch


def test_launch_passes_split_and_keep_to_the_recorder_and_its_restarts(tmp_path: Path) -> None:
    sc = scenario.load("linear").with_robots(4)
    files = (tmp_path / "s.yaml", tmp_path / "r.yaml", tmp_path / "arena.yaml")
    bag = tmp_path / "run.mcap"
    cfg = LaunchConfig(sc, record=bag, bag_split="30s", bag_keep=2, layout="single")
    order = start_order(cfg, *files)
    argv = order.recorder.argv
    assert argv[argv.index("--split") + 1] == "30s" and argv[argv.index("--keep") + 1] == "2"
    for i in (0, 1, 2):  # a recorder that split twice, then died
        segment_path(bag, i).write_bytes(b"")
    restart = RestartCommands(order.by_name, None, tmp_path / "w.npz", bag, 4)
    again = restart("recorder")
    assert again[: len(argv)] == argv
    assert again[len(argv) :] == [
        "--segment", "3", "--after", *(str(segment_path(bag, i)) for i in range(3))
    ]  # fmt: skip
    bounded = expected_bytes(LaunchConfig(sc, record=bag, bag_split="64KiB", bag_keep=2))
    assert bounded["bag"] == 3 * 65536


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"bag_split": "10x"}, "bag_split: '10x' is not allowed; need a size"),
        ({"bag_split": "10s", "record": None}, "bag_split: '10s' is not allowed; only with"),
        ({"bag_split": "10s", "bag_keep": 0}, "bag_keep: 0 is not allowed; need an integer"),
        ({"bag_keep": 2}, "bag_keep: 2 is not allowed; only with --bag-split"),
    ],
)
def test_launch_config_refuses_bad_split_options(tmp_path: Path, options, message: str) -> None:
    sc = scenario.load("linear").with_robots(4)
    with pytest.raises(ValueError, match=message):
        LaunchConfig(sc, **{"record": tmp_path / "run.mcap", **options})


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--bag-split", "10x"], "argument --bag-split: '10x': need a size (e.g. 500MiB"),
        (["--bag-split", "0.1s"], "argument --bag-split: '0.1s': need a size"),
        (["--bag-keep", "0"], "argument --bag-keep: need an integer >= 1"),
        (["--bag-split", "10s"], "bag_split: '10s' is not allowed; only with --record"),
    ],
)
def test_launch_rejects_bad_split_options_naming_them(capsys, args, expected: str) -> None:
    assert aes_swarm(["launch", *args]) == 2
    assert expected in capsys.readouterr().err


def test_recorder_rejects_bad_split_options(capsys) -> None:
    from aes_ros.ros.recorder import main

    for args, expected in [
        (["--split", "1TB/s"], "argument --split: '1TB/s' is not allowed; need a size"),
        (["--keep", "0"], "argument --keep: '0': need an integer >= 1"),
    ]:
        with pytest.raises(SystemExit) as exit_:
            main(["run.mcap", *args])
        assert exit_.value.code == 2
        assert expected in capsys.readouterr().err


def test_a_new_recording_never_removes_files_it_did_not_write(tmp_path: Path) -> None:
    """An earlier recording's segment or journal at the path: a new recording is refused,
    naming them, and nothing is touched; with ``overwrite`` exactly those go (and it
    says so), never a file of another name."""
    base = tmp_path / "run.mcap"
    earlier = [base.with_name("run_1.mcap"), base.with_name("run.sequences.json")]
    others = [tmp_path / name for name in ("run_x.mcap", "run.mcap.bak", "other_1.mcap")]
    for path in (*earlier, *others):
        path.write_bytes(b"not this recording's")
    with pytest.raises(EarlierRunError, match=r"holds an earlier recording \(run_1\.mcap, run"):
        Recording(base)
    assert not base.exists()
    assert all(p.read_bytes() == b"not this recording's" for p in (*earlier, *others))
    said: list[str] = []
    rec = Recording(base, overwrite=True, say=said.append)
    assert rec.replaced == earlier and not any(p.exists() for p in earlier)
    rec.close()  # (with this recording's own journal)
    assert said == [
        f"replaced the earlier recording {base}: removed run_1.mcap, run.sequences.json"
    ]
    assert all(p.read_bytes() == b"not this recording's" for p in others)
    assert bag_segments(base) == [base] and bag_is_closed(base)


def test_a_segment_is_never_opened_over_a_planted_link(tmp_path: Path) -> None:
    """A link at a segment's name is an earlier file like any other: refused, and never
    followed (the file it points to keeps its bytes), also by the writer alone."""
    base, target = tmp_path / "run.mcap", tmp_path / "precious"
    target.write_bytes(b"precious")
    base.symlink_to(target)
    with pytest.raises(EarlierRunError):
        Recording(base)
    with pytest.raises(FileExistsError):
        BagWriter(base)
    assert target.read_bytes() == b"precious"


def test_the_journal_is_never_written_through_a_planted_link(tmp_path: Path) -> None:
    base, target = tmp_path / "run.mcap", tmp_path / "precious"
    target.write_bytes(b"precious")
    rec = start(base)
    (tmp_path / ".run.sequences.json.tmp").symlink_to(target)
    with pytest.raises(OSError):
        rec.flush()
    assert target.read_bytes() == b"precious"


def test_the_recorder_refuses_an_earlier_recording_before_it_starts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``python -m aes_ros.ros.recorder run.mcap`` beside an earlier ``run_2.mcap``: exit
    code 2 and the file named, the file kept, nothing written."""
    from aes_ros.ros.recorder import main

    earlier = tmp_path / "run_2.mcap"
    earlier.write_bytes(b"x")
    assert main([str(tmp_path / "run.mcap")]) == 2
    assert "holds an earlier recording (run_2.mcap)" in capsys.readouterr().out
    assert earlier.read_bytes() == b"x" and sorted(tmp_path.iterdir()) == [earlier]
