"""How many env steps one replica of a packed algorithm has played, from RLlib's result dict."""

from __future__ import annotations

from typing import Any

from rllib_conv.training.lean_env_runner import NUM_REPLICA_STEPS_SAMPLED_LIFETIME


def replica_env_steps(result: dict[str, Any], replica: int) -> int:
    """Replica `replica`'s env steps so far: the moves its own game copies made (`ReplicatedGame.take_moves`,
    logged by `LeanEnvRunner`). In a turn-based game a copy whose episode ended waits for the others, so
    this is not the algorithm's env step count; nor is it RLlib's per-module count, which counts
    observations (on blocks 7 per 6-move episode)."""
    steps = result.get("env_runners", {}).get(NUM_REPLICA_STEPS_SAMPLED_LIFETIME, {})
    return int(steps.get(str(replica), 0))
