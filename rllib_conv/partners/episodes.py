"""Play fixed partners against each other in any registered PettingZoo game."""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterator

import numpy as np
from pettingzoo.utils.env import AECEnv, ParallelEnv

from rllib_conv.common.seeds import seat_seed
from rllib_conv.envs.spaces import MASK_KEY, OBS_KEY
from rllib_conv.partners.base import Partner


def _split(obs) -> tuple[np.ndarray, np.ndarray | None]:
    if isinstance(obs, dict) and OBS_KEY in obs:
        return obs[OBS_KEY], obs.get(MASK_KEY)
    return obs, None


def _tell_others(seats: dict[str, Partner], agent: str, observation: np.ndarray, mask: np.ndarray, action: int) -> None:
    for other, partner in seats.items():
        if other != agent:
            partner.observe_other(observation, mask, action, agent)


def episode_stream(
    env: AECEnv | ParallelEnv,
    seats: dict[str, Partner],
    seed: int = 0,
    on_infos: Callable[[dict[str, dict]], None] | None = None,
) -> Iterator[tuple[float, int]]:
    """Play episodes without end with `seats[agent]` choosing for each agent; yield each one's (score, env steps).

    The score of an episode is the total reward of the first seat (the games are fully
    cooperative, so every seat gets the same total). Env steps count moves as RLlib's
    adapter does: one per agent move in AEC games, one per joint step in parallel ones.
    Episodes are seeded `seed, seed+1, ...` and the partner in seat i is seeded once
    (`common.seeds.seat_seed`), so play is reproducible. Every seat hears `start_episode` before each episode and
    `observe_other` after each move of another seat (what a partner adapting during play needs).
    `on_infos`, if given, hears every step's infos by agent (in AEC games, the mover's as it observes).
    """
    missing = set(env.possible_agents) - set(seats)
    if missing:
        raise ValueError(f"seats must give a partner for every agent; missing {sorted(missing)}")
    for i, partner in enumerate(seats.values()):
        partner.seed(seat_seed(seed, i))
    first = env.possible_agents[0]
    for ep in itertools.count():
        score, steps = 0.0, 0
        for partner in seats.values():
            partner.start_episode()
        if isinstance(env, AECEnv):
            env.reset(seed=seed + ep)
            for agent in env.agent_iter():
                obs, reward, term, trunc, info = env.last()
                if on_infos is not None:
                    on_infos({agent: info})
                if agent == first:
                    score += reward
                if term or trunc:
                    env.step(None)
                    continue
                vec, mask = _split(obs)
                mask = np.ones(env.action_space(agent).n, dtype=np.int8) if mask is None else mask
                action = seats[agent].act(vec, mask)
                _tell_others(seats, agent, vec, mask, action)
                env.step(action)
                steps += 1
        else:
            obs, _ = env.reset(seed=seed + ep)
            while env.agents:
                actions, moves = {}, []
                for agent in env.agents:
                    vec, mask = _split(obs[agent])
                    mask = np.ones(env.action_space(agent).n, dtype=np.int8) if mask is None else mask
                    actions[agent] = seats[agent].act(vec, mask)
                    moves.append((agent, vec, mask, actions[agent]))
                for move in moves:  # simultaneous moves: each seat hears the others' only after choosing its own
                    _tell_others(seats, *move)
                obs, rewards, _, _, infos = env.step(actions)
                if on_infos is not None:
                    on_infos(infos)
                score += rewards.get(first, 0.0)
                steps += 1
        yield float(score), steps


def play_episodes(env: AECEnv | ParallelEnv, seats: dict[str, Partner], num_episodes: int, seed: int = 0) -> np.ndarray:
    """Play `num_episodes` (see `episode_stream`); return each episode's score."""
    return np.array([score for score, _ in itertools.islice(episode_stream(env, seats, seed), num_episodes)], dtype=float)
