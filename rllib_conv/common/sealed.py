"""Folders that are either whole or refused: sealed with a manifest, verified before use.

`seal(folder)` writes `manifest.json` last: the size and SHA-256 of every other file. A
folder interrupted while being written or copied (no manifest, a file missing or short)
and one damaged later (a file changed) fail `verify` with a `ValueError` naming the file,
so nothing ever loads a half-written or corrupt checkpoint or partner as if it were fine.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from rllib_conv.common.atomic_files import write_text_atomically

MANIFEST = "manifest.json"


def _digest(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.is_file() and p.name != MANIFEST)


def seal(folder: str | Path) -> Path:
    """Write `folder`'s manifest (size and SHA-256 of every file) atomically; return its path."""
    folder = Path(folder)
    entries = {str(p.relative_to(folder)): {"size": p.stat().st_size, "sha256": _digest(p)} for p in _files(folder)}
    return write_text_atomically(folder / MANIFEST, json.dumps(entries, indent=1, sort_keys=True))


def verify(folder: str | Path) -> None:
    """Raise ValueError unless `folder` is a complete, unchanged sealed folder."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"checkpoint {str(folder)!r} does not exist")
    manifest = folder / MANIFEST
    if not manifest.is_file():
        raise ValueError(f"checkpoint {str(folder)!r} is incomplete: no {MANIFEST} (it was interrupted while being written)")
    try:
        entries = json.loads(manifest.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"checkpoint {str(folder)!r} is corrupt: unreadable {MANIFEST} ({exc})") from None
    for name, want in entries.items():
        path = folder / name
        if not path.is_file():
            raise ValueError(f"checkpoint {str(folder)!r} is incomplete: {name} is missing")
        if path.stat().st_size != want["size"] or _digest(path) != want["sha256"]:
            raise ValueError(f"checkpoint {str(folder)!r} is corrupt: {name} differs from what was saved")


def is_sealed(folder: str | Path) -> bool:
    """Whether `folder` carries a manifest (folders written before sealing existed do not)."""
    return (Path(folder) / MANIFEST).is_file()
