"""What bench/bench_soak.py reads out of a run (a sibling script's module): memory growth
per process, gaps in ``metrics.csv``, messages lost in the bag inside and outside the
recovery windows, the recorder's own count of losses, and whether a segment is readable.
docs/reliability.md#how-bench_soak-judges-a-run."""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aes_ros.ros.bag import SequenceGaps, bag_is_closed, raw_messages, read_journal

#: Slack on both sides of a window [s]: the death is noticed, and a message in flight
#: logged, a little apart from the kill.
SLACK = 1.0


@dataclass
class Sample:
    t: float  # wall seconds since every robot moved
    process: str
    pid: int
    rss_mb: float
    files: int
    threads: int


@dataclass
class Growth:
    process: str
    pid: int
    warm_mb: float
    end_mb: float
    growth_pct: float
    slope_mb_h: float
    span_s: float
    files: tuple[int, int] = (0, 0)
    threads: tuple[int, int] = (0, 0)


def growth(samples: list[Sample], warmup: float, end: float) -> list[Growth]:
    """Growth of each process incarnation from ``warmup`` s past its own start (or past
    the swarm moving, for the first ones) to ``end`` [s] (the run's end: the stop and
    the final outputs come after), if that spans six samples or more: the
    longest-lived incarnation of each process name."""
    by_pid: dict[int, list[Sample]] = {}
    for s in samples:
        if s.t <= end:
            by_pid.setdefault(s.pid, []).append(s)
    best: dict[str, Growth] = {}
    for pid, rows in by_pid.items():
        born = max(rows[0].t, 0.0)
        kept = [r for r in rows if r.t >= born + warmup]
        if len(kept) < 6:
            continue
        t = np.array([r.t for r in kept])
        rss = np.array([r.rss_mb for r in kept])
        warm, end = float(np.median(rss[:3])), float(np.median(rss[-3:]))
        slope = float(np.polyfit(t / 3600.0, rss, 1)[0])
        g = Growth(
            kept[0].process, pid, warm, end, 100.0 * (end - warm) / warm, slope,
            float(t[-1] - t[0]), (kept[0].files, kept[-1].files),
            (kept[0].threads, kept[-1].threads),
        )  # fmt: skip
        if g.process not in best or g.span_s > best[g.process].span_s:
            best[g.process] = g
    return sorted(best.values(), key=lambda g: g.process)


def metric_gaps(
    metrics_csv: Path, dt: float, windows: list[tuple[float, float]]
) -> list[tuple[float, float]]:
    """Gaps of more than 2.5 ``dt`` between rows of ``metrics_csv`` [s of sim time] that
    no window (sim-time interval) covers."""
    with open(metrics_csv, newline="") as fh:
        t = np.array([float(row["t"]) for row in csv.DictReader(fh)])
    found = []
    for k in np.flatnonzero(np.diff(t) > 2.5 * dt):
        a, b = float(t[k]), float(t[k + 1])
        if not any(a >= w0 - SLACK and b <= w1 + SLACK for w0, w1 in windows):
            found.append((a, b))
    return found


def bag_losses(
    segments: list[Path], windows: list[tuple[float, float]], where: list | None = None
) -> tuple[int, int]:
    """(lost outside ``windows``, lost inside) [messages]: gaps in each topic's sequence
    numbers across the segments in order (:class:`aes_ros.ros.bag.SequenceGaps`), placed
    between the log times [s since the epoch] of the messages around them. ``where``
    gets (topic, log time before, log time after, lost) of each loss outside."""
    gaps = SequenceGaps()
    last_log: dict[str, float] = {}
    outside = inside = 0
    for channel, message in raw_messages(segments):
        topic, logged = channel.topic, message.log_time * 1e-9
        lost = gaps.seen(topic, message.sequence, message.publish_time)
        before = last_log.get(topic, logged)
        last_log[topic] = logged
        if not lost:
            continue
        if any(before <= w1 + SLACK and logged >= w0 - SLACK for w0, w1 in windows):
            inside += lost
        else:
            outside += lost
            if where is not None:
                where.append((topic, before, logged, lost))
    return outside, inside


def recorder_lost(log: Path, bag: Path) -> int:
    """Messages the recorder counted lost over its whole recording, every life of it: the
    count in the journal beside ``bag`` (each life carries it on; written at every flush
    and at the end, so a killed life's is at most a flush period behind), else the last
    ``bag …: N messages on T topics, L lost`` line of its log (a killed life prints none)."""
    journal = read_journal(bag)
    if journal is not None:
        return sum(journal.lost.values())
    if not log.exists():
        return 0
    found = re.findall(r"messages on \d+ topics, (\d+) lost", log.read_text())
    return int(found[-1]) if found else 0


def readable(segment: Path) -> bool:
    """A segment is readable: closed, or cut by a kill and read up to its last chunk."""
    return bag_is_closed(segment) or next(raw_messages([segment]), None) is not None
