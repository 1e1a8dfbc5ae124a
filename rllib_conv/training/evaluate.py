"""Evaluate a trained ego: its action probabilities, its return with a partner (exact for one-step games), loading it."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import torch

from rllib_conv import envs
from rllib_conv.common.run_folders import RL_MODULE_DIR
from rllib_conv.modules.multi import ConventionMultiRLModule
from rllib_conv.partners.base import Partner
from rllib_conv.partners.episodes import score_episodes
from rllib_conv.partners.trained import PolicyPartner, load_rl_module


def _tensors(obs: np.ndarray, mask: np.ndarray | None) -> tuple[torch.Tensor, torch.Tensor | None]:
    return torch.as_tensor(np.asarray(obs), dtype=torch.float32), None if mask is None else torch.as_tensor(
        np.asarray(mask), dtype=torch.float32
    )


@torch.no_grad()
def head_probs(module: ConventionMultiRLModule, head_id: str, obs: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Return the ego's action probabilities [B, A] with head `head_id` on observations [B, obs_dim]."""
    o, m = _tensors(obs, mask)
    z, task_logits = module.task.policy(o, m)
    return torch.softmax(module[head_id].logits(z, task_logits, m), dim=-1).numpy()


@torch.no_grad()
def task_probs(module: ConventionMultiRLModule, obs: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Return the task module's action distribution [B, A] (its estimate of the marginals)."""
    o, m = _tensors(obs, mask)
    return torch.softmax(module.task.policy(o, m).logits, dim=-1).numpy()


def ego_head_partner(module: ConventionMultiRLModule, head_id: str, seed: int = 0) -> PolicyPartner:
    """The ego with head `head_id` as a sampling `Partner`, for `play_episodes` and `player_return` (its weights fixed while it plays)."""

    def logits(obs: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        z, task_logits = module.task.policy(obs, mask)
        return module[head_id].logits(z, task_logits, mask)

    return PolicyPartner(head_id, logits, greedy=False, seed=seed, memo=True)


def ego_task_partner(module: ConventionMultiRLModule, seed: int = 0) -> PolicyPartner:
    """The ego's task module alone (its logits, no head: its estimate of the population's marginal) as a sampling `Partner`."""

    def logits(obs: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        return module.task.policy(obs, mask).logits

    return PolicyPartner("task", logits, greedy=False, seed=seed, memo=True)


def check_episodes(episodes: int, env_name: str, env_config: dict[str, Any]) -> None:
    """ValueError unless `episodes` can score this game: 0 (no sampled episodes) only where the game has an exact return."""
    if episodes == 0 and envs.game(env_name).exact_return is None:
        raise ValueError(
            f"episodes=0 scores by the exact expected return, which {env_name!r} does not have; {env_name!r} needs episodes >= 1"
        )


def player_return(
    ego: Partner,
    env_name: str,
    env_config: dict[str, Any],
    partner: Partner,
    ego_agent: str,
    partner_agent: str,
    episodes: int = 200,
    seed: int = 0,
) -> dict[str, float]:
    """Return the mean return of the `ego` player with `partner` over `episodes` sampled episodes, and its standard error.

    Games with an exact return (the game record's `exact_return`: the bandit, blocks) are also
    scored exactly from the two policies (`exact`); there `episodes=0` plays nothing (`mean`
    and `stderr` NaN). ValueError for `episodes=0` where the game or these players have none.
    """
    return seated_return({ego_agent: ego, partner_agent: partner}, env_name, env_config, episodes, seed)


def seated_return(
    players: dict[str, Partner], env_name: str, env_config: dict[str, Any], episodes: int = 200, seed: int = 0
) -> dict[str, float]:
    """`player_return` for any number of seats: `players` gives the player of every agent of the game."""
    check_episodes(episodes, env_name, env_config)
    out = {"mean": math.nan, "stderr": math.nan}
    if episodes:
        scores = score_episodes(lambda: envs.make_scored(env_name, **env_config), players, episodes, seed)
        out = {
            "mean": float(scores.mean()),
            "stderr": float(scores.std(ddof=1) / np.sqrt(len(scores))) if len(scores) > 1 else 0.0,
        }
    exact = envs.game(env_name).exact_return
    value = None if exact is None else exact(players, env_config)
    if value is not None:
        out["exact"] = value
    elif not episodes:
        names = " with ".join(repr(p.name) for p in players.values())
        raise ValueError(f"episodes=0 needs an exact return, and {names} have none on {env_name!r}")
    return out


def load_module(checkpoint: str | Path) -> ConventionMultiRLModule:
    """Load the ego's MultiRLModule (task module, heads, partners) from an algorithm checkpoint."""
    path = Path(checkpoint) / RL_MODULE_DIR
    if not path.is_dir():
        raise ValueError(f"{str(checkpoint)!r} is not an algorithm checkpoint (no {path.relative_to(checkpoint)})")
    return load_rl_module(path)
