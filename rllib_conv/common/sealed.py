"""Folders that are either whole or refused: sealed with a manifest, verified before use.

`seal(folder)` writes `manifest.json` last: the size and SHA-256 of every other file. A
folder interrupted while being written or copied (no manifest, a file missing or short)
and one damaged later (a file changed) fail `verify` with a `ValueError` naming the file,
so nothing ever loads a half-written or corrupt checkpoint or partner as if it were fine. A
folder verified in this process is hashed again only when a file of it was written since
(`file_versions.settled`: or was written in the last seconds).

A single file is sealed the same way by a digest beside it (`seal_file`: `config.yaml`
gets `config.yaml.sha256`, in `sha256sum` format, so `sha256sum -c` checks it too): a
trained ego's config is read only if it is what was saved (`verify_file`). A file without
a digest (written before files were sealed) is read as it is: refusing it would make every
older run unreadable, and such a file was never promised to be checked.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from rllib_conv.common.atomic_files import write_text_atomically
from rllib_conv.common.file_versions import settled

MANIFEST = "manifest.json"
DIGEST_SUFFIX = ".sha256"
_VERIFIED: set[tuple] = set()  # (folder, manifest mtime, every file's name, mtime, size) of folders verified whole


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
    stats = []
    for name, want in entries.items():
        path = folder / name
        if not path.is_file():
            raise ValueError(f"checkpoint {str(folder)!r} is incomplete: {name} is missing")
        stat = path.stat()
        if stat.st_size != want["size"]:
            raise ValueError(f"checkpoint {str(folder)!r} is corrupt: {name} differs from what was saved")
        stats.append((name, stat.st_mtime_ns, stat.st_size))
    # A stage verifies each ego's checkpoint once per curve: hash the files again only when one of them was written since.
    key = (str(folder.resolve()), manifest.stat().st_mtime_ns, tuple(stats))
    if key in _VERIFIED:
        return
    for name, want in entries.items():
        if _digest(folder / name) != want["sha256"]:
            raise ValueError(f"checkpoint {str(folder)!r} is corrupt: {name} differs from what was saved")
    if all(settled(mtime) for _, mtime, _ in stats) and settled(key[1]):
        _VERIFIED.add(key)


def is_sealed(folder: str | Path) -> bool:
    """Whether `folder` carries a manifest (folders written before sealing existed do not)."""
    return (Path(folder) / MANIFEST).is_file()


def digest_path(path: str | Path) -> Path:
    """Where the digest of the sealed file `path` lies: beside it, `<name>.sha256`."""
    path = Path(path)
    return path.with_name(path.name + DIGEST_SUFFIX)


def seal_file(path: str | Path) -> Path:
    """Write the SHA-256 of the file `path` beside it (`sha256sum` format), atomically; return the digest's path."""
    path = Path(path)
    return write_text_atomically(digest_path(path), f"{_digest(path)}  {path.name}\n")


def verify_file(path: str | Path, what: str = "file") -> None:
    """Raise ValueError naming `path` unless it is unchanged since `seal_file`; a file never sealed passes (see above)."""
    path, digest = Path(path), digest_path(path)
    if not digest.is_file():
        return
    want = digest.read_text(errors="replace").split(maxsplit=1)[0] if digest.stat().st_size else ""
    if not path.is_file():
        raise ValueError(f"{what} {str(path)!r} is missing (its digest {digest.name} is there)")
    if _digest(path) != want:
        raise ValueError(f"{what} {str(path)!r} is corrupt: it differs from what was saved (its SHA-256 in {digest.name})")
