"""Play fixed partners against each other in any registered PettingZoo game."""

from __future__ import annotations

import itertools
from collections import defaultdict
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


def _with_mask(env: AECEnv | ParallelEnv, agent: str, obs) -> tuple[np.ndarray, np.ndarray]:
    """The observation vector and action mask (all ones where the game has none) of `agent`'s `obs`."""
    vec, mask = _split(obs)
    return vec, np.ones(env.action_space(agent).n, dtype=np.int8) if mask is None else mask


def _seat(env: AECEnv | ParallelEnv, seats: dict[str, Partner], seed: int) -> None:
    """Check that `seats` gives a partner for every agent of `env` and seed seat i with `seat_seed(seed, i)`."""
    missing = set(env.possible_agents) - set(seats)
    if missing:
        raise ValueError(f"seats must give a partner for every agent; missing {sorted(missing)}")
    for i, partner in enumerate(seats.values()):
        partner.seed(seat_seed(seed, i))


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
    _seat(env, seats, seed)
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
                vec, mask = _with_mask(env, agent, obs)
                action = seats[agent].act(vec, mask)
                _tell_others(seats, agent, vec, mask, action)
                env.step(action)
                steps += 1
        else:
            obs, _ = env.reset(seed=seed + ep)
            while env.agents:
                actions, moves = {}, []
                for agent in env.agents:
                    vec, mask = _with_mask(env, agent, obs[agent])
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


# Games a batched series plays side by side. A constant, not a choice: which rows a sampling seat's draws fall on
# depends on it, so a series' scores depend on its seed alone.
BATCH_WIDTH = 64


def score_episodes(
    make_env: Callable[[], AECEnv | ParallelEnv], seats: dict[str, Partner], num_episodes: int, seed: int = 0
) -> np.ndarray:
    """`play_episodes` on an env from `make_env`, or, where every seat is `batchable`, `play_batched`: the scores of a series.

    The one entry point for scoring a series: batched, greedy seats play the same episodes and sampling seats other
    samples of the same distribution (see `play_batched`), with one policy call per step for up to `BATCH_WIDTH`
    games instead of one per move.
    """
    if all(partner.batchable for partner in seats.values()):
        return play_batched(make_env, seats, num_episodes, seed)
    return play_episodes(make_env(), seats, num_episodes, seed)


def play_batched(
    make_env: Callable[[], AECEnv | ParallelEnv],
    seats: dict[str, Partner],
    num_episodes: int,
    seed: int = 0,
    width: int = BATCH_WIDTH,
) -> np.ndarray:
    """`play_episodes` with up to `width` games side by side; each seat chooses for every game waiting on it at once.

    Episode e is reset with `seed + e` and seat i seeded once with `seat_seed(seed, i)`, as in `episode_stream`, and
    an episode's score counts the same rewards. Seats choosing greedily (or by any function of their inputs) therefore
    play the very episodes `play_episodes` plays; a sampling seat draws from the same probabilities in another order,
    so its episodes are other samples of the same distribution. Only for `batchable` seats (ValueError naming the
    others): they keep no state between moves, so hearing no `start_episode` or `observe_other` changes nothing.
    """
    unbatchable = sorted(partner.name for partner in seats.values() if not partner.batchable)
    if unbatchable:
        raise ValueError(f"partners {unbatchable} keep state between moves and cannot play batched; use play_episodes")
    scores = np.zeros(num_episodes, dtype=float)
    games = [make_env() for _ in range(min(width, num_episodes))]
    if not games:
        return scores
    _seat(games[0], seats, seed)
    first, aec = games[0].possible_agents[0], isinstance(games[0], AECEnv)
    episode = [-1] * len(games)  # the episode each game plays; -1 once the series needs no more
    observations: list[dict] = [{} for _ in games]  # parallel games: each agent's last observation
    started = 0

    def start(k: int) -> bool:
        nonlocal started
        if started == num_episodes:
            episode[k] = -1
            return False
        episode[k], started = started, started + 1
        reset = games[k].reset(seed=seed + episode[k])
        if not aec:
            observations[k] = reset[0]
        return True

    live = [k for k in range(len(games)) if start(k)]
    while live:
        waiting: dict[str, list[tuple[int, np.ndarray, np.ndarray]]] = defaultdict(list)
        for k in live:
            if aec:
                _next_aec_move(games[k], k, first, scores, episode, start, waiting)
            else:
                _next_parallel_moves(games[k], k, observations, start, waiting)
        joint: dict[int, dict[str, int]] = defaultdict(dict)
        for agent, rows in waiting.items():
            actions = seats[agent].act_batch(np.stack([r[1] for r in rows]), np.stack([r[2] for r in rows]))
            for (k, _, _), action in zip(rows, actions):
                if aec:
                    games[k].step(int(action))
                else:
                    joint[k][agent] = int(action)
        for k, actions in joint.items():
            observations[k], rewards, _, _, _ = games[k].step(actions)
            scores[episode[k]] += rewards.get(first, 0.0)
        live = [k for k in live if episode[k] >= 0]
    return scores


def _next_aec_move(env: AECEnv, k: int, first: str, scores, episode, start, waiting) -> None:
    """Step game k through ended seats (and finished episodes: the next one starts) to its next move, queued under its agent."""
    while True:
        if not env.agents:
            if not start(k):
                return
            continue
        agent = env.agent_selection
        obs, reward, term, trunc, _ = env.last()
        if agent == first:
            scores[episode[k]] += reward
        if term or trunc:
            env.step(None)
            continue
        waiting[agent].append((k, *_with_mask(env, agent, obs)))
        return


def _next_parallel_moves(env: ParallelEnv, k: int, observations: list[dict], start, waiting) -> None:
    """Queue every agent's move of game k (a finished episode first makes way for the next one)."""
    if not env.agents and not start(k):
        return
    for agent in env.agents:
        waiting[agent].append((k, *_with_mask(env, agent, observations[k][agent])))
