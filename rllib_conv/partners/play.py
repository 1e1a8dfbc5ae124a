"""Play fixed partners against each other in any registered PettingZoo game."""

from __future__ import annotations

import numpy as np
from pettingzoo.utils.env import AECEnv, ParallelEnv

from rllib_conv.envs.spaces import MASK_KEY, OBS_KEY
from rllib_conv.partners.base import Partner


def _split(obs) -> tuple[np.ndarray, np.ndarray | None]:
    if isinstance(obs, dict) and OBS_KEY in obs:
        return obs[OBS_KEY], obs.get(MASK_KEY)
    return obs, None


def play_episodes(env: AECEnv | ParallelEnv, seats: dict[str, Partner], num_episodes: int, seed: int = 0) -> np.ndarray:
    """Play `num_episodes` with `seats[agent]` choosing for each agent; return each episode's score.

    The score of an episode is the total reward of the first seat (the games are fully
    cooperative, so every seat gets the same total). Episodes are seeded `seed, seed+1, ...`
    and each partner is seeded once with `seed`, so results are reproducible.
    """
    missing = set(env.possible_agents) - set(seats)
    if missing:
        raise ValueError(f"seats must give a partner for every agent; missing {sorted(missing)}")
    for i, partner in enumerate(seats.values()):
        partner.seed(seed + 7919 * i)
    first = env.possible_agents[0]
    scores = np.zeros(num_episodes)
    for ep in range(num_episodes):
        if isinstance(env, AECEnv):
            env.reset(seed=seed + ep)
            for agent in env.agent_iter():
                obs, reward, term, trunc, _ = env.last()
                if agent == first:
                    scores[ep] += reward
                if term or trunc:
                    env.step(None)
                    continue
                vec, mask = _split(obs)
                mask = np.ones(env.action_space(agent).n, dtype=np.int8) if mask is None else mask
                env.step(seats[agent].act(vec, mask))
        else:
            obs, _ = env.reset(seed=seed + ep)
            while env.agents:
                actions = {}
                for agent in env.agents:
                    vec, mask = _split(obs[agent])
                    mask = np.ones(env.action_space(agent).n, dtype=np.int8) if mask is None else mask
                    actions[agent] = seats[agent].act(vec, mask)
                obs, rewards, _, _, _ = env.step(actions)
                scores[ep] += rewards.get(first, 0.0)
    return scores
