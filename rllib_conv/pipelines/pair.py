"""`rllib-conv pair`: any saved module, population member or scripted partner in each seat of a game of 2 or more seats.

Each seat (its syntax: `rllib-conv pair --help`) becomes a fixed `Partner`: an ego head or
the task module alone of a trained ego's last checkpoint (sampling its policy), a
population member, or a scripted kind built from its parameters. The seats play
`episodes` episodes of one game (`partners.episodes.episode_stream`); the result is their
mean return, its standard error and, where the game has one (the bandit, blocks: the game
record's `exact_return`), the exact expected return computed from the players' action
probabilities.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from rllib_conv import envs, partners
from rllib_conv.common.atomic_files import replaced_atomically
from rllib_conv.common.run_folders import trial_folders
from rllib_conv.modules.multi import TASK_ID
from rllib_conv.partners.base import Partner
from rllib_conv.partners.episodes import score_episodes
from rllib_conv.partners.trained import PolicyPartner
from rllib_conv.pipelines.pair_config import PairConfig, is_run, population_seat, split_seat, trained_game
from rllib_conv.training.checkpoints import last_checkpoint
from rllib_conv.training.evaluate import ego_head_partner, load_module
from rllib_conv.training.experiment import trial_config


@dataclass
class Seat:
    """One seat's player and the game it comes from (None for scripted kinds, which fit any)."""

    text: str
    player: Partner
    game: tuple[str, dict[str, Any]] | None


def _task_partner(module: Any, name: str, seed: int) -> PolicyPartner:
    """The task module alone as a sampling player (its estimate of the marginals)."""
    return PolicyPartner(name, lambda obs, mask: module[TASK_ID].policy(obs, mask).logits, greedy=False, seed=seed)


def module_player(module: Any, module_id: str, name: str, seed: int) -> Partner:
    """Module `module_id` of a loaded ego as a sampling player: `task` (the task module alone) or one of its heads."""
    return _task_partner(module, name, seed) if module_id == TASK_ID else ego_head_partner(module, module_id, seed)


def _module_seat(text: str, trial: Path, module_id: str, seed: int) -> Seat:
    exp = trial_config(trial)
    module = load_module(last_checkpoint(trial))
    choices = [TASK_ID, *module.head_ids()]
    if module_id not in choices:
        raise ValueError(f"seat {text!r}: the ego in {str(trial)!r} has no module {module_id!r}; it has {choices}")
    env, env_config, _ = trained_game(exp)
    return Seat(text, module_player(module, module_id, text, seed), (env, env_config))


def seat(text: str, seed: int = 0) -> Seat:
    """Build the player of the seat `text` (see `rllib-conv pair --help`); ValueError naming the seat."""
    source, what = split_seat(text)
    if source in partners.kinds():
        try:
            params = yaml.safe_load(what) if what else {}
        except yaml.YAMLError as exc:
            raise ValueError(f"seat {text!r}: the parameters are not valid YAML ({' '.join(str(exc).split())})") from None
        if not isinstance(params, dict):
            raise ValueError(f"seat {text!r}: the parameters must be a YAML mapping like {{arms: [0, 1]}}, got {what!r}")
        try:
            return Seat(text, partners.partner_from_spec({"name": text, "kind": source, "params": params}), None)
        except (TypeError, ValueError) as exc:  # unknown or missing constructor arguments, or values the kind refuses
            raise ValueError(f"seat {text!r}: {' '.join(str(exc).split())}") from None
    if is_run(source):
        trials = trial_folders(source)
        if len(trials) > 1:
            raise ValueError(f"seat {text!r}: {source!r} holds {len(trials)} trials; name one trial folder")
        return _module_seat(text, trials[0], what, seed)
    pop, entry = population_seat(text)
    return Seat(text, entry.build(), (pop.env, pop.env_config))


def pair_game(seats: list[Seat], env: str | None = None, env_config: dict[str, Any] | None = None) -> tuple[str, dict[str, Any]]:
    """The game the seats play: `env` and `env_config` when given, else the one the seats that name a game agree on."""
    named = [s.game for s in seats if s.game is not None]
    described = "; ".join(f"{s.text!r}: {s.game[0]} {s.game[1]}" for s in seats if s.game is not None)
    if env is None:
        games = {g for g, _ in named}
        if not games:
            raise ValueError("no seat names a game (scripted kinds fit any): choose one with --env")
        if len(games) > 1:
            raise ValueError(f"the seats come from different games ({described}): choose one with --env")
        env = games.pop()
    if env_config is None:
        configs = {repr(sorted(c.items())): c for g, c in named if g == env}
        if len(configs) > 1:
            raise ValueError(f"the seats come from different {env} settings ({described}): choose one with --env-config")
        env_config = next(iter(configs.values()), {})
    return env, env_config


def pair(cfg: PairConfig) -> pd.DataFrame:
    """Play the seats of `cfg` together; one row: the game, seats, mean return, stderr and the exact return (where the game has one)."""
    seats = [seat(text, cfg.seed) for text in cfg.seats]
    game, env_config = pair_game(seats, cfg.env, cfg.env_config)
    try:
        env = envs.make_scored(game, **env_config)
    except (TypeError, ValueError) as exc:
        if cfg.env_config is None:  # the seats' own settings: not the user's to fix
            raise
        raise ValueError(f"--env-config {cfg.env_config}: {' '.join(str(exc).split())}") from None
    agents = list(env.possible_agents)
    if len(seats) != len(agents):
        # Seats fill the agents in order: say which agents would sit empty, or which seats have no agent.
        odd = [f"{a} has none" for a in agents[len(seats) :]] or [f"{s.text!r} has no agent" for s in seats[len(agents) :]]
        raise ValueError(
            f"{game} {env_config} has {len(agents)} seats ({', '.join(agents)}), got {len(seats)} SEATs ({'; '.join(odd)}): "
            "give one SEAT per agent, in order"
        )
    players = [s.player for s in seats]
    try:
        scores = score_episodes(lambda: envs.make_scored(game, **env_config), dict(zip(agents, players)), cfg.episodes, cfg.seed)
    except RuntimeError as exc:  # torch: a module built for another observation or action size
        raise ValueError(f"the seats do not fit {game} {env_config}: {' '.join(str(exc).split())}") from None
    exact_fn = envs.game(game).exact_return  # the bandit and blocks: from the players' own probabilities
    exact = exact_fn(dict(zip(agents, players)), env_config) if exact_fn is not None else None
    stderr = float(scores.std(ddof=1) / np.sqrt(len(scores))) if len(scores) > 1 else 0.0
    row = {"env": game, "env_config": str(env_config), **{f"seat_{i}": s.text for i, s in enumerate(seats)}}
    row |= {
        "episodes": cfg.episodes,
        "seed": cfg.seed,
        "mean_return": float(scores.mean()),
        "stderr": stderr,
        "exact_return": math.nan if exact is None else exact,
    }
    return pd.DataFrame([row])


def write_pair(cfg: PairConfig, path: str | Path) -> pd.DataFrame:
    """Play the seats of `cfg` together (`pair`) and write the row to the CSV `path`; return it."""
    table = pair(cfg)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with replaced_atomically(path) as tmp:
        table.to_csv(tmp, index=False)
    return table
