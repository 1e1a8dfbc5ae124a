"""Read a file once per version of it: a stage checks thousands of curves against the same few files.

`read_once(path, read, cache)` returns `read(path)` from `cache` while the file's size and
modification time are those it was read at, so an edited file is read again. Callers hand out
copies of what is cached (pydantic models: `model_copy(deep=True)`), never the cached object.

File systems stamp writes with a coarse clock (a few ms), so a file rewritten just after it
was read can keep its time and size: a file written in the last `SETTLED_NS` is read every
time and not cached (git's "racily clean" entries, handled the same way).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

T = TypeVar("T")
FileVersion = tuple[str, int, int]  # resolved path, mtime in ns, size
SETTLED_NS = 2_000_000_000  # a file this much older than now has its final time stamp


def settled(mtime_ns: int) -> bool:
    """Whether a file stamped `mtime_ns` is old enough that a later write would change its stamp."""
    return time.time_ns() - mtime_ns > SETTLED_NS


def read_once(path: Path, read: Callable[[Path], T], cache: dict[FileVersion, T]) -> T:
    """`read(path)`, read once per (resolved path, mtime, size) of the file; errors are raised each time, never cached."""
    try:
        stat = path.stat()
    except OSError:  # missing, unreadable: the reader says what is wrong, in its words
        return read(path)
    if not settled(stat.st_mtime_ns):
        return read(path)
    key = (str(path.resolve()), stat.st_mtime_ns, stat.st_size)
    if key not in cache:
        cache[key] = read(path)
    return cache[key]
