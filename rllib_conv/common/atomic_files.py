"""Files written whole or not at all: the new content goes to a file beside the target, which then replaces it.

`os.replace` within one folder is atomic on POSIX, so a reader, or a run resumed after a
kill, finds either the old file or the new one, never half of one. Every file the pipelines
read back to decide what is finished (curves, results, packs, specs, manifests, Tune's
result files) is written this way.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def replaced_atomically(target: str | Path) -> Iterator[Path]:
    """Yield the path to write `target`'s new content to: it replaces `target` when the block ends, and is deleted if the block raises.

    The path is a hidden file beside `target` (`.NAME.tmp`), so one left by a killed process
    is never read as a result and is overwritten by the next write.
    """
    target = Path(target)
    tmp = target.with_name(f".{target.name}.tmp")
    try:
        yield tmp
        tmp.replace(target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_text_atomically(target: str | Path, text: str) -> Path:
    """Write `text` to `target` whole or not at all (`replaced_atomically`); return the target's path."""
    with replaced_atomically(target) as tmp:
        tmp.write_text(text)
    return Path(target)


@contextmanager
def folder_replaced_atomically(target: str | Path) -> Iterator[Path]:
    """Yield an empty folder to assemble `target`'s new content in: it replaces `target` (and whatever was there) when the
    block ends, and is deleted if the block raises.

    The folder is a hidden one beside `target` (`.NAME.<random>`), so a reader never finds a half-written `target`.
    The swap is an `rmtree` then a `rename`: a kill between them leaves no `target` (its old content was being
    replaced), never a mixed one.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    try:
        yield staging
        if target.exists():
            shutil.rmtree(target)
        staging.rename(target)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
