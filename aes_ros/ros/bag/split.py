"""When a recording goes on in its next segment: ``--split`` as a size or a duration
(:func:`parse_split`)."""

from __future__ import annotations

import re
from typing import NamedTuple

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
