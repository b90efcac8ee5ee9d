"""Numba's on-disk cache, made to notice the other files a cached function compiles in.

Numba stamps a cached function with its own source file only (its documented limit,
"Cache invalidation" in numba's docs): a kernel that inlines functions and constants
of other modules loads its old machine code after one of those changed, until its own
file changes too. :func:`depend_on` adds those modules' sources to the stamp, so an edit
of any of them compiles the kernel again.
"""

from __future__ import annotations

import hashlib
import importlib
from pathlib import Path
from typing import Any


def depend_on(dispatcher: Any, *modules: str) -> bool:
    """Make ``dispatcher``'s (a ``numba.njit(cache=True)`` function's) cached code stale
    whenever the source of one of ``modules`` (names) changes. Returns False, changing nothing,
    when the function is not cached or numba keeps its cache in another layout (the
    stamp is numba's private ``_cache._cache_file._source_stamp``)."""
    index = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    if index is None or not hasattr(index, "_source_stamp"):
        return False
    digest = hashlib.sha256()
    for name in modules:
        digest.update(Path(importlib.import_module(name).__file__ or "").read_bytes())
    index._source_stamp = (index._source_stamp, digest.hexdigest())
    return True
