"""Checkpoints that are either whole or refused: sealed with a manifest, verified before use.

Every trial checkpoint (`AlgorithmCheckpoints.save_checkpoint`) holds the RLlib algorithm
state, the RNG state (`rng_state`) and, written last, `manifest.json`: the size and
SHA-256 of every other file. A checkpoint interrupted while being written or copied (no
manifest, a file missing or short) and one damaged later (a file changed) fail
`verify` with a `ValueError` naming the file, so nothing ever loads a half-written or
corrupt checkpoint as if it were fine. Tune prunes old checkpoints (`num_to_keep`).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from rllib_conv.modules.multi import TASK_ID
from rllib_conv.pipelines import rng_state

MANIFEST = "manifest.json"
RL_MODULE_DIR = Path("learner_group") / "learner" / "rl_module"


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
    path, tmp = folder / MANIFEST, folder / (MANIFEST + ".tmp")
    tmp.write_text(json.dumps(entries, indent=1, sort_keys=True))
    tmp.replace(path)
    return path


def verify(folder: str | Path) -> None:
    """Raise ValueError unless `folder` is a complete, unchanged sealed checkpoint."""
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


def checkpoints(trial: str | Path) -> list[Path]:
    """The trial's checkpoint folders, oldest first."""
    return sorted(Path(trial).glob("checkpoint_*"), key=lambda p: int(p.name.rsplit("_", 1)[1]))


def last_checkpoint(trial: str | Path) -> Path:
    """The trial's newest checkpoint, verified; ValueError (naming the problem) if it has none or it is damaged."""
    found = checkpoints(trial)
    if not found:
        raise ValueError(f"trial {str(trial)!r} has no checkpoint (checkpoint_* folders)")
    newest = found[-1]
    verify(newest)
    if not (newest / RL_MODULE_DIR / TASK_ID).is_dir():
        raise ValueError(f"checkpoint {str(newest)!r} holds no task module ({RL_MODULE_DIR / TASK_ID})")
    return newest


class AlgorithmCheckpoints:
    """Tune `Trainable` mixin: save the algorithm (`self.algo`) and RNG state sealed; verify before restoring.

    Subclasses with more state write it in `save_extra` / read it in `load_extra`.
    """

    algo: Any

    def save_extra(self, checkpoint_dir: Path) -> None:
        """Write state beyond the algorithm's into the checkpoint (before it is sealed)."""

    def load_extra(self, checkpoint_dir: Path) -> None:
        """Read what `save_extra` wrote."""

    def save_checkpoint(self, checkpoint_dir: str) -> None:
        self.algo.save_to_path(checkpoint_dir)
        rng_state.save(self.algo, checkpoint_dir)
        self.save_extra(Path(checkpoint_dir))
        seal(checkpoint_dir)

    def load_checkpoint(self, checkpoint: str) -> None:
        verify(checkpoint)
        self.algo.restore_from_path(checkpoint)
        rng_state.load(self.algo, checkpoint)
        self.load_extra(Path(checkpoint))
