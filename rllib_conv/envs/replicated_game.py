"""`ReplicatedGame`: K independent copies of one game stepped together as one RLlib `MultiAgentEnv`.

Replicas are independent runs packed into one algorithm: the seeds of one experiment, or the
adaptation curves of one trained ego. Replica `r` plays its own copy of the game, its agents
are named `<agent>#<r>` (`player_0#2`), and its game is seeded from its own seed alone, so it
sees the same episodes whether it runs alone or beside others:

- RLlib seeds sub-environment `i` of an env runner with `seed + i` on its first reset (the
  runner's seed is the algorithm's, plus its worker index); the game copy of replica `r` is
  seeded with `game_seed(replica_seeds[r], that offset)` (`rllib_conv.common.seeds`).
- One `step` moves every copy that is still playing (one mover each in turn-based games), so
  every replica advances one env step per RLlib env step; an episode ends when every copy
  has ended. Copies of a game whose length varies (Hanabi) wait for the longest one, so a
  replica's own env steps are counted per copy (`take_moves`).

Rewards, observations and masks are those of `PettingZooMultiAgentEnv`, per copy; game
infos are dropped (the masks are in the observations), which spares RLlib copying them.

Every episode is one game per copy. (Several one-step games in one RLlib episode would
halve RLlib's per-episode cost on the bandit, but not leave the science alone: PPO
standardizes advantages over a batch that includes one artificial bootstrap row per
episode, so fewer episodes per batch change every advantage; `docs/speed.md`.)
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from ray.rllib.env.multi_agent_env import MultiAgentEnv

from rllib_conv.common.seeds import game_seed
from rllib_conv.envs import registry
from rllib_conv.envs.rllib_adapter import PettingZooMultiAgentEnv

SEPARATOR = "#"


def replica_agent(agent: str, replica: int) -> str:
    """The RLlib agent ID of `agent` in replica `replica`."""
    return f"{agent}{SEPARATOR}{replica}"


def split_agent(agent_id: str) -> tuple[str, int]:
    """`player_0#2` -> (`player_0`, 2)."""
    agent, _, replica = agent_id.rpartition(SEPARATOR)
    return agent, int(replica)


class ReplicatedGame(MultiAgentEnv):
    """K copies of a registered game (`env_config`: `game`, `game_config`, `replica_seeds`, `base_seed`; `factory` for user games)."""

    def __init__(self, config: dict | None = None) -> None:
        super().__init__()
        config = dict(config or {})
        if "game" not in config:
            raise ValueError("ReplicatedGame needs env_config['game'], the registered name of the game")
        factory = config.get("factory") or registry.factory(config["game"])
        self.replica_seeds = [int(s) for s in config.get("replica_seeds", [0])]
        self.base_seed = int(config.get("base_seed", 0))
        self.copies = [PettingZooMultiAgentEnv(factory(**dict(config.get("game_config", {})))) for _ in self.replica_seeds]
        # Agent IDs per copy and back, made once: a step names every agent of every copy.
        self._ids = [{a: replica_agent(a, r) for a in env.possible_agents} for r, env in enumerate(self.copies)]
        self._where = {aid: (a, r) for r, ids in enumerate(self._ids) for a, aid in ids.items()}
        self.possible_agents = [aid for ids in self._ids for aid in ids.values()]
        self.agents = list(self.possible_agents)
        self.observation_spaces = {aid: self.copies[r].observation_spaces[a] for aid, (a, r) in self._where.items()}
        self.action_spaces = {aid: self.copies[r].action_spaces[a] for aid, (a, r) in self._where.items()}
        self.observation_space = gym.spaces.Dict(self.observation_spaces)
        self.action_space = gym.spaces.Dict(self.action_spaces)
        self._done = [False] * len(self.copies)
        self._moves = [0] * len(self.copies)  # env steps per copy since the last `take_moves`

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        obs = {}
        for r, env in enumerate(self.copies):
            o, _ = env.reset(
                seed=None if seed is None else game_seed(self.replica_seeds[r], seed - self.base_seed), options=options
            )
            ids = self._ids[r]
            obs.update({ids[a]: v for a, v in o.items()})
        self._done = [False] * len(self.copies)
        self.agents = [self._ids[r][a] for r, env in enumerate(self.copies) for a in env.agents]
        return obs, {}

    def step(self, action_dict: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        per_copy: list[dict[str, Any]] = [{} for _ in self.copies]
        for agent_id, action in action_dict.items():
            agent, r = self._where[agent_id]
            per_copy[r][agent] = action
        out: tuple[dict, ...] = ({}, {}, {}, {})
        for r, env in enumerate(self.copies):
            if self._done[r]:
                continue
            results = env.step(per_copy[r])[:4]
            self._moves[r] += 1
            ended = bool(results[2].get("__all__") or results[3].get("__all__"))
            ids = self._ids[r]
            for merged, part in zip(out, results):
                merged.update({ids[a]: v for a, v in part.items() if a != "__all__"})
            self._done[r] = ended
        obs, rewards, terms, truncs = out
        done = all(self._done)
        terms["__all__"] = done and not any(truncs.values())
        truncs["__all__"] = done and not terms["__all__"]
        self.agents = [self._ids[r][a] for r, env in enumerate(self.copies) if not self._done[r] for a in env.agents]
        if not self.agents:  # RLlib expects every agent of a step's result to be listed
            self.agents = [a for a in obs]
        return obs, rewards, terms, truncs, {}

    def take_moves(self) -> list[int]:
        """Each copy's env steps since the last call (then zero): what a replica played, exactly.

        RLlib's per-module step counts are counts of observations, which in a turn-based game
        include each agent's final one: on blocks 7 per 6-move episode.
        """
        moves, self._moves = self._moves, [0] * len(self.copies)
        return moves

    def record_seen_moves(self, egos: list[str]) -> None:
        """From now on keep, per copy r, the other seats' moves as seat `egos[r]` sees them (`envs.seen_moves`)."""
        if len(egos) != len(self.copies):
            raise ValueError(f"{len(egos)} ego seats for {len(self.copies)} copies")
        for env, ego in zip(self.copies, egos):
            env.record_seen_moves(ego)

    def take_seen_moves(self, seated: bool = False) -> list[tuple[np.ndarray, ...] | None]:
        """Per copy: the moves kept since the last call (`SeenMoves.take`, or with `seated` `take_seated`), None where none."""
        return [env.take_seen_moves(seated) for env in self.copies]

    def get_rng_state(self) -> list[dict | None]:
        """Every copy's game RNG state, for exact resumes."""
        return [env.get_rng_state() for env in self.copies]

    def set_rng_state(self, state: list[dict | None]) -> None:
        """Continue every copy from `state` at the next reset."""
        for env, s in zip(self.copies, state):
            env.set_rng_state(s)

    def render(self) -> Any:
        return [env.render() for env in self.copies]

    def close(self) -> None:
        for env in self.copies:
            env.close()


def replicated_env_config(name: str, game_config: dict, replica_seeds: list[int], base_seed: int) -> dict:
    """The RLlib `env_config` of `ReplicatedGame`: games every process finds by name, others with their factory."""
    env_config = {
        "game": name,
        "game_config": dict(game_config),
        "replica_seeds": list(replica_seeds),
        "base_seed": int(base_seed),
    }
    if not registry.found_by_name(name):
        env_config["factory"] = registry.factory(name)
    return env_config
