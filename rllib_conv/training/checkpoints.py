"""A trial's checkpoints: the newest one, verified before anything loads from it.

Every trial checkpoint holds the RLlib algorithm state, the RNG state (`rng_state`) and,
written last, the manifest of `rllib_conv.common.sealed`; `AlgorithmTrainable` writes
them, and everything that reads a trained ego back (adaptation, zero-shot, marginals,
the web app, resumes) goes through `last_checkpoint`, which refuses an incomplete or
damaged one with a message naming the file. Tune prunes old checkpoints (`num_to_keep`).
"""

from __future__ import annotations

from pathlib import Path

from rllib_conv.common.run_folders import RL_MODULE_DIR, checkpoints
from rllib_conv.common.sealed import verify
from rllib_conv.modules.multi import TASK_ID


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
