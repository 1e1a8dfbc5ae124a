"""How many env steps one replica of a packed algorithm has played, from RLlib's result dict."""

from __future__ import annotations

from typing import Any

from rllib_conv.modules.multi import partner_id, replica_id
from rllib_conv.training.ego_setup import EgoSetup


def is_parallel(algo: Any) -> bool:
    """Whether the algorithm's game moves every agent at every step (a parallel game; else turn-based)."""
    return not algo.env_runner.env.envs[0].unwrapped.copies[0].is_aec


def replica_env_steps(result: dict[str, Any], setup: EgoSetup, replica: int, parallel: bool) -> int:
    """Replica `replica`'s env steps so far: the algorithm's in a parallel game (every copy moves at every
    step); in a turn-based one, its own agents' moves (a copy whose episode ended waits for the others)."""
    runners = result.get("env_runners", {})
    if parallel:
        return int(runners.get("num_env_steps_sampled_lifetime", 0))
    module_steps = runners.get("num_module_steps_sampled_lifetime", {})
    own = {*setup.head_ids, *(partner_id(e.name) for e in setup.train)}
    return int(sum(module_steps.get(replica_id(m, replica), 0) for m in own))
