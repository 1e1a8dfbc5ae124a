"""Expose any registered PettingZoo env (AEC or parallel) to RLlib as a `MultiAgentEnv`.

Observations become `{"observations": float32 vector, "action_mask": float32 vector}`,
the keys RLlib's action-masking modules read. The mask comes from the PettingZoo
observation's `action_mask`, else from `info["action_mask"]`, else all ones.

AEC games are stepped one agent at a time: each RLlib step carries the observation of
the agent to move next, and an agent's reward is the AEC cumulative reward since its
own last move, so nothing is lost when the other player's move ends the game.
Asked to (`record_seen_moves`), it keeps the other seats' moves as one seat sees them
(`envs.seen_moves`: what the information-parity controls of adaptation learn from).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from pettingzoo.utils.env import AECEnv, ParallelEnv
from ray.rllib.env.multi_agent_env import MultiAgentEnv
from ray.tune.registry import register_env

from rllib_conv.envs import registry
from rllib_conv.envs.seen_moves import SeenMoves
from rllib_conv.envs.spaces import MASK_KEY, OBS_KEY

RLLIB_OBS_KEY = "observations"
RLLIB_MASK_KEY = "action_mask"
RLLIB_ENV_PREFIX = "rllib_conv/"


def _inner_obs_space(space: gym.Space) -> gym.Space:
    if isinstance(space, gym.spaces.Dict) and OBS_KEY in space.spaces:
        return space.spaces[OBS_KEY]
    return space


class PettingZooMultiAgentEnv(MultiAgentEnv):
    """A PettingZoo env seen through RLlib's `MultiAgentEnv` API with Dict masked observations."""

    def __init__(self, env: AECEnv | ParallelEnv) -> None:
        super().__init__()
        self.env = env
        self.is_aec = isinstance(env, AECEnv)
        self._seen: SeenMoves | None = None  # `record_seen_moves`
        if not self.is_aec and not isinstance(env, ParallelEnv):
            raise TypeError(f"expected a PettingZoo AECEnv or ParallelEnv, got {type(env).__name__}")
        self.possible_agents = list(env.possible_agents)
        self.agents = list(self.possible_agents)
        self._flatten: dict[str, gym.Space | None] = {}
        obs_spaces, act_spaces = {}, {}
        for agent in self.possible_agents:
            act = env.action_space(agent)
            if not isinstance(act, gym.spaces.Discrete):
                raise ValueError(f"agent {agent!r}: only Discrete action spaces are supported, got {act}")
            inner = _inner_obs_space(env.observation_space(agent))
            if isinstance(inner, gym.spaces.Box):
                self._flatten[agent] = None
                box = gym.spaces.Box(inner.low.astype(np.float32), inner.high.astype(np.float32), dtype=np.float32)
            else:
                # Discrete/MultiDiscrete/... observations are flattened (one-hot) for the MLPs.
                self._flatten[agent] = inner
                box = gym.spaces.flatten_space(inner)
                box = gym.spaces.Box(box.low.astype(np.float32), box.high.astype(np.float32), dtype=np.float32)
            obs_spaces[agent] = gym.spaces.Dict(
                {
                    RLLIB_OBS_KEY: box,
                    RLLIB_MASK_KEY: gym.spaces.Box(0.0, 1.0, shape=(int(act.n),), dtype=np.float32),
                }
            )
            act_spaces[agent] = act
        self.observation_spaces = obs_spaces
        self.action_spaces = act_spaces
        self.observation_space = gym.spaces.Dict(obs_spaces)
        self.action_space = gym.spaces.Dict(act_spaces)

    def _convert(self, agent: str, obs: Any, info: dict | None) -> dict[str, np.ndarray]:
        if isinstance(obs, dict) and OBS_KEY in obs:
            vec, mask = obs[OBS_KEY], obs.get(MASK_KEY)
        else:
            vec, mask = obs, None
        if mask is None and info:
            mask = info.get("action_mask")
        if self._flatten[agent] is not None:
            vec = gym.spaces.flatten(self._flatten[agent], vec)
        n = self.action_spaces[agent].n
        mask = np.ones(n, dtype=np.float32) if mask is None else np.asarray(mask, dtype=np.float32)
        return {RLLIB_OBS_KEY: np.asarray(vec, dtype=np.float32), RLLIB_MASK_KEY: mask}

    def get_rng_state(self) -> dict | None:
        """The game's RNG state (games keeping a numpy Generator in `_rng`), for exact resumes."""
        rng = getattr(self.env.unwrapped, "_rng", None)
        return rng.bit_generator.state if isinstance(rng, np.random.Generator) else None

    def set_rng_state(self, state: dict | None) -> None:
        """Continue from `state` at the next reset, which then ignores its seed (see `reset`)."""
        self._pending_rng_state = state

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        pending = getattr(self, "_pending_rng_state", None)
        if pending is not None:
            # A resumed run: RLlib re-seeds every env on its first reset, but the game should
            # continue its random stream from where the checkpoint left it. A game that makes
            # its generator at its first reset (Hanabi) has none yet: it gets one to continue.
            game = self.env.unwrapped
            if not isinstance(getattr(game, "_rng", None), np.random.Generator):
                game._rng = np.random.default_rng()
            game._rng.bit_generator.state = pending
            self._pending_rng_state, seed = None, None
        if self.is_aec:
            self.env.reset(seed=seed, options=options)
            agent = self.env.agent_selection
            info = self.env.infos.get(agent, {})
            self.agents = list(self.env.agents)
            return self._seen_start({agent: self._convert(agent, self.env.observe(agent), info)}), {agent: info}
        obs, infos = self.env.reset(seed=seed, options=options)
        self.agents = list(self.env.agents)
        return self._seen_start({a: self._convert(a, o, infos.get(a)) for a, o in obs.items()}), infos

    def record_seen_moves(self, ego: str) -> None:
        """From now on keep the other seats' moves as seat `ego` sees them (`envs.seen_moves`), until `take_seen_moves`."""
        self._seen = SeenMoves(ego)

    def take_seen_moves(self, seated: bool = False) -> tuple[np.ndarray, ...] | None:
        """The moves kept since the last call (`SeenMoves.take`, or with `seated` `SeenMoves.take_seated`); None if none or not recording."""
        if self._seen is None:
            return None
        return self._seen.take_seated() if seated else self._seen.take()

    def _seen_start(self, obs: dict[str, dict[str, np.ndarray]]) -> dict[str, dict[str, np.ndarray]]:
        seen = self._seen
        if seen is not None:
            seen.start()
            self._seen_obs(obs)
        return obs

    def _seen_obs(self, obs: dict[str, dict[str, np.ndarray]]) -> None:
        seen = self._seen
        if seen is not None:
            for agent, o in obs.items():
                seen.saw(agent, o[RLLIB_OBS_KEY])

    def _seen_moves(self, actions: dict[str, Any]) -> None:
        seen = self._seen
        if seen is not None:  # the ego's own move first: in a simultaneous step the partner's is recorded beside it
            for agent in sorted(actions, key=lambda a: a != seen.ego):
                seen.moved(agent, actions[agent])

    def step(self, action_dict: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        if not self.is_aec:
            self._seen_moves(action_dict)
            obs, rewards, terms, truncs, infos = self.env.step(action_dict)
            obs = {a: self._convert(a, o, infos.get(a)) for a, o in obs.items()}
            self._seen_obs(obs)
            return obs, rewards, *self._mark_all_done(dict(terms), dict(truncs)), infos
        agent = self.env.agent_selection
        if agent not in action_dict:
            raise ValueError(f"it is {agent}'s turn but the action dict has only {sorted(action_dict)}")
        self._seen_moves({agent: action_dict[agent]})
        self.env.step(action_dict[agent])
        obs, rewards, terms, truncs, infos = {}, {}, {}, {}, {}
        # Collect the next mover's observation; finished agents get their final
        # observation and reward and are stepped out with None (PettingZoo's dead step).
        while self.env.agents:
            o, r, term, trunc, info = self.env.last()
            a = self.env.agent_selection
            obs[a] = self._convert(a, o, info)
            rewards[a] = rewards.get(a, 0.0) + float(r)
            terms[a], truncs[a], infos[a] = term, trunc, info
            if term or trunc:
                self.env.step(None)
            else:
                break
        self._seen_obs(obs)
        return obs, rewards, *self._mark_all_done(terms, truncs), infos

    def _mark_all_done(self, terms: dict, truncs: dict) -> tuple[dict, dict]:
        """Set RLlib's `__all__` flags: the episode ends when PettingZoo has no agents left.

        `agents` keeps the agents that just received their final observation, since
        RLlib expects every agent in a step's result to be listed.
        """
        self.agents = list(self.env.agents) or [a for a in self.possible_agents if a in terms]
        done = not self.env.agents
        terms["__all__"] = done and all(terms.values())
        truncs["__all__"] = done and not terms["__all__"]
        return terms, truncs

    def render(self) -> Any:
        return self.env.render()

    def close(self) -> None:
        self.env.close()


class RLlibGame(PettingZooMultiAgentEnv):
    """A registered game built from an RLlib `env_config`: `{"game": name, "game_config": {...}}`.

    Pass the class itself to `config.environment(RLlibGame, env_config=game_env_config(...))`:
    unlike a Tune-registered name it is importable, so checkpoints restore in any process.
    A user-registered game's factory travels in `env_config["factory"]` (pickled with the config).
    """

    def __init__(self, config: dict | None = None) -> None:
        config = dict(config or {})
        if "game" not in config:
            raise ValueError("RLlibGame needs env_config['game'], the registered name of the game")
        factory = config.get("factory") or registry.factory(config["game"])
        super().__init__(factory(**dict(config.get("game_config", {}))))


def game_env_config(name: str, game_config: dict) -> dict:
    """The RLlib `env_config` for `RLlibGame`: games every process finds by name, others with their factory."""
    env_config = {"game": name, "game_config": dict(game_config)}
    if not registry.found_by_name(name):
        env_config["factory"] = registry.factory(name)
    return env_config


def to_rllib(name: str) -> str:
    """Register the PettingZoo env `name` with Tune and return the env id for RLlib configs.

    Use it as `config.environment(to_rllib("bandit"), env_config={"symmetric": 2})`;
    `env_config` is passed to `rllib_conv.envs.make(name, **env_config)` on every runner.
    """
    factory = registry.factory(name)
    env_id = RLLIB_ENV_PREFIX + name

    def creator(env_config: dict) -> PettingZooMultiAgentEnv:
        return PettingZooMultiAgentEnv(factory(**dict(env_config)))

    register_env(env_id, creator)
    return env_id
