"""A recording's files: its segments ``run.mcap``, ``run_1.mcap``… (:func:`segment_path`)
and its sequences journal ``run.sequences.json`` (:func:`read_journal`)."""

from __future__ import annotations

import glob
import json
import os
import re
from pathlib import Path
from typing import NamedTuple


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
