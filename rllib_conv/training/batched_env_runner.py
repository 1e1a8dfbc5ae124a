"""`BatchedEnvRunner`: RLlib's sampling loop for packed egos, writing a `Rollout` instead of episode objects.

Once the learner's minibatch loop was our own, most of an iteration on our small games went
to RLlib's episode objects, not to the game or the networks: a `MultiAgentEpisode` (with its
per-agent `SingleAgentEpisode`s and lookback buffers) for every game, env-to-module connectors
over them at every step, and the learner connector reading them back (`docs/speed.md`). This
runner plays the same loop as `MultiAgentEnvRunner._sample`, step for step:

- each iteration one forward pass (`forward_exploration`) over the observations of every
  agent to act, each module's rows in sub-environment order (the order RLlib's connectors
  batch them in, so every replica draws the same actions from its generator);
- then every sub-environment steps, except one whose episode ended in the previous
  iteration, which is reset instead (gymnasium's next-step autoreset, as RLlib's vector env
  does it); a new agent asks the policy mapping for its module when it first observes;
- each agent's rows follow `MultiAgentEpisode.add_env_step`'s rules (`RunningEpisode`): in
  turn-based games a move waits for the mover's next observation;
- it stops once it has played `num_timesteps` env steps; episodes still running are cut
  into chunks and continue in the next call, a waiting move with them;

and hands the learner each agent's moves as `Rollout` segments, in the order RLlib's learner
connector would read them (done episodes as they ended, then the running chunks).
`MarginalPPOLearner` makes the train batch from them with RLlib's own GAE arithmetic, so the
batch equals the episode path's row for row and training is unchanged on the bandit, blocks
and Hanabi (`tests/training/test_batched_env_runner.py`, with `LeanEnvRunner`, RLlib's own
sampling, as the reference). Metrics are counted as `LeanEnvRunner` counts them.

It samples this way when every sub-environment is one of our games (`ReplicatedGame`, or
`PettingZooMultiAgentEnv` such as a self-play pair's `RLlibGame`) and the module is a
`StackedEgoMultiRLModule` (whose heads and fixed partners return their actions) or a
multi-module of `TaskModule`s (self-play seats), whose actions are drawn from the module's
exploration distribution as RLlib's `GetActions` draws them, one module after another in the
order their rows first appear (lane, then the env's observation order). RLlib's own path
draws them in the order of a Python set of agent IDs, which follows the process's string
hash seed: with two seats moving at once (the bandit) its self-play pairs trained
differently from one process to the next; here they do not. For evaluation-style calls
(`num_episodes`, `explore=False`, random actions), other modules or
`restart_failed_sub_environments` it is RLlib's runner. Switching between the two resets
every sub-environment (episodes in flight are dropped).
"""

from __future__ import annotations

import time
import uuid
from collections import defaultdict
from typing import Any

import numpy as np
import torch
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.apis.value_function_api import ValueFunctionAPI
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModule
from ray.rllib.env.env_runner import NUM_ENV_STEP_FAILURES_LIFETIME
from ray.rllib.utils.metrics import SAMPLE_TIMER

from rllib_conv.common.arrays import to_numpy
from rllib_conv.envs.replicated_game import ReplicatedGame
from rllib_conv.envs.rllib_adapter import RLLIB_MASK_KEY, RLLIB_OBS_KEY, PettingZooMultiAgentEnv
from rllib_conv.learners.packed.rollout import Rollout
from rllib_conv.modules.packed.stacked_multi import StackedEgoMultiRLModule
from rllib_conv.modules.task_module import TaskModule
from rllib_conv.training.lean_env_runner import LeanEnvRunner


class RunningEpisode:
    """One sub-environment's episode: its agents' modules, their moves in the current chunk, totals for metrics.

    `record` follows `MultiAgentEpisode.add_env_step`'s rules, so each agent's rows are the ones
    RLlib's episode would hold: an agent joins when it first observes; a move waits ("hangs")
    until the mover observes again (turn-based games), and takes the rewards it got meanwhile;
    an agent that ends without a last observation ends on its previous one; an episode whose
    agents are all out, in any mix, counts as terminated, and an episode-wide flag reaches every
    agent. Offers what the policy mapping and `LeanEnvRunner`'s counters read of an RLlib episode
    (`id_`, `is_done`, `module_for`).
    """

    def __init__(self, obs: dict[str, dict], mapping: Any) -> None:
        self.id_ = uuid.uuid4().hex
        self.is_done = False
        self.mapping = mapping
        self.modules: dict[str, str] = {}
        self.obs: dict[str, list] = {}
        self.actions: dict[str, list] = {}
        self.logp: dict[str, list] = {}
        self.rewards: dict[str, list] = {}
        self.hanging: dict[str, tuple[Any, float]] = {}  # agent -> (move, log-probability) awaiting its next observation
        self.hanging_reward: dict[str, float] = defaultdict(float)  # what a hanging move has earned so far
        self.ended: dict[str, tuple[bool, bool]] = {}  # agent -> (terminated, truncated), once it is out
        self.chunk_steps = 0
        self.length = 0
        self.returns: dict[str, float] = defaultdict(float)
        self.moves: dict[str, int] = defaultdict(int)
        self.start = time.perf_counter()
        for aid, o in obs.items():  # RLlib's `add_env_reset` maps the agents in this order
            self._join(aid, o)
        self.observed: list[str] = list(obs)  # who observed the last step

    def module_for(self, agent_id: str) -> str:
        return self.modules[agent_id]

    def to_act(self) -> list[str]:
        """The agents that observed the last step and are still playing."""
        return [aid for aid in self.observed if aid not in self.ended]

    def _join(self, aid: str, o: dict) -> None:
        self.modules[aid] = self.mapping(aid, self)
        self.obs[aid], self.actions[aid], self.logp[aid], self.rewards[aid] = [o], [], [], []

    def _step(self, aid: str, o: dict, action: Any, logp: float, reward: float) -> None:
        self.obs[aid].append(o)
        self.actions[aid].append(action)
        self.logp[aid].append(logp)
        self.rewards[aid].append(reward)
        self.returns[aid] += reward
        self.moves[aid] += 1

    def record(self, actions: dict, logp: dict, obs: dict, rewards: dict, terms: dict, truncs: dict) -> None:
        """Add one env step (see the class docstring for whose rows it extends)."""
        all_term, all_trunc = bool(terms.get("__all__")), bool(truncs.get("__all__"))
        out_now = {a for flags in (terms, truncs) for a, v in flags.items() if v and a != "__all__"}
        term_all = all_term or all(a in self.ended or a in out_now for a in self.modules)
        touched = (
            set(obs)
            | set(actions)
            | set(rewards)
            | set(terms)
            | set(truncs)
            | (set(self.modules) if all_term or all_trunc else set())
        ) - {"__all__"}
        for aid in touched:
            if aid in self.ended:
                continue
            o, action, reward = obs.get(aid), actions.get(aid), float(rewards.get(aid) or 0.0)
            term, trunc = bool(terms.get(aid)) or term_all, bool(truncs.get(aid)) or all_trunc
            if o is not None and action is not None:
                self._step(aid, o, action, logp.get(aid, 0.0), reward)
            elif o is not None:
                if aid in self.hanging:
                    move, lp = self.hanging.pop(aid)
                    self._step(aid, o, move, lp, self.hanging_reward.pop(aid, 0.0) + reward)
                elif term or trunc:
                    continue  # a last observation with no move to close: RLlib keeps nothing of it
                elif aid not in self.modules:
                    self._join(aid, o)
                    continue
                else:
                    raise ValueError(f"agent {aid!r} observed twice without moving")
            elif action is not None:
                if trunc:
                    raise ValueError(f"agent {aid!r} moved and was truncated without a last observation")
                if term:
                    self._step(aid, self.obs[aid][-1], action, logp.get(aid, 0.0), reward)
                else:
                    self.hanging[aid] = (action, logp.get(aid, 0.0))
                    self.hanging_reward[aid] = reward
            elif term or trunc:
                if aid in self.hanging:
                    if trunc:
                        raise ValueError(f"agent {aid!r} moved and was truncated without a last observation")
                    move, lp = self.hanging.pop(aid)
                    self._step(aid, self.obs[aid][-1], move, lp, self.hanging_reward.pop(aid, 0.0) + reward)
            elif aid in self.modules:
                self.hanging_reward[aid] += reward
            if term or trunc:
                self.hanging.pop(aid, None)
                self.hanging_reward.pop(aid, None)
                if aid in self.modules:
                    self.ended[aid] = (term, trunc)
        self.observed = list(obs)
        self.chunk_steps += 1
        self.length += 1
        self.is_done = term_all or all_trunc

    def metrics(self) -> tuple:
        """What RLlib logs of a finished episode: length, return, seconds, returns per agent and per module, moves per agent."""
        per_module: dict[str, float] = defaultdict(float)
        for aid, r in self.returns.items():
            per_module[self.modules[aid]] += r
        agents = {str(a): r for a, r in self.returns.items()}
        moves = {str(a): n for a, n in self.moves.items()}
        return self.length, sum(self.returns.values()), time.perf_counter() - self.start, agents, dict(per_module), moves

    def emit(self, rollout: Rollout, learning: set[str]) -> None:
        """Append each learning agent's moves of this chunk to `rollout`, then start the next chunk from the last observations.

        A move still hanging stays with the next chunk, which starts from the observation it was made on.
        """
        for aid, mid in self.modules.items():
            if self.actions[aid] and mid in learning:
                terminated, truncated = self.ended.get(aid, (False, False))
                rollout.rows(mid).add(self.obs[aid], self.actions[aid], self.logp[aid], self.rewards[aid], terminated, truncated)
            self.obs[aid] = self.obs[aid][-1:]
            self.actions[aid], self.logp[aid], self.rewards[aid] = [], [], []
        self.chunk_steps = 0


class BatchedEnvRunner(LeanEnvRunner):
    """A `LeanEnvRunner` that samples packed egos without RLlib's episode objects (see the module docstring)."""

    def _batched(self) -> bool:
        """Whether this runner's envs and module can be sampled here (decided once: they never change)."""
        cached = self.__dict__.get("_can_batch")
        if cached is None:
            games = [env.unwrapped for env in self.env.envs] if self.env is not None else []
            cached = self.__dict__["_can_batch"] = (
                bool(games)
                and all(isinstance(g, (ReplicatedGame, PettingZooMultiAgentEnv)) for g in games)
                and (
                    isinstance(self.module, StackedEgoMultiRLModule)
                    or (
                        isinstance(self.module, MultiRLModule)
                        and all(isinstance(m, TaskModule) for m in self.module._rl_modules.values())
                    )
                )
                and not self.config.restart_failed_sub_environments
                and self.config.batch_mode == "truncate_episodes"
                and self.config.count_steps_by == "env_steps"
            )
        return cached

    def sample(
        self,
        *,
        num_timesteps: int | None = None,
        num_episodes: int | None = None,
        explore: bool | None = None,
        random_actions: bool = False,
        force_reset: bool = False,
    ) -> list:
        explore = self.config.explore if explore is None else explore
        lanes = self.__dict__.get("_lanes")
        if num_episodes is not None or random_actions or not explore or not self._batched():
            self.__dict__["_lanes"] = None
            reset = force_reset or lanes is not None  # the envs are mid-episode for RLlib's own bookkeeping
            return super().sample(
                num_timesteps=num_timesteps,
                num_episodes=num_episodes,
                explore=explore,
                random_actions=random_actions,
                force_reset=reset,
            )
        if num_timesteps is None:
            num_timesteps = self.config.get_rollout_fragment_length(self.worker_index) * self.num_envs
        with self.metrics.log_time(SAMPLE_TIMER):
            return [self._sample_rollout(num_timesteps, force_reset or lanes is None)]

    def _learning(self) -> set[str]:
        """The modules whose rows the learner needs (those with values); fixed partners' are not kept."""
        return {mid for mid, m in self.module._rl_modules.items() if isinstance(m, ValueFunctionAPI)}

    def _sample_rollout(self, num_timesteps: int, reset: bool) -> Rollout:
        mapping = self.config.policy_mapping_fn
        learning = self._learning()
        rollout = Rollout()
        lanes: list[RunningEpisode | None]
        if reset or self._needs_initial_reset:
            obs, _ = self._try_env_reset(seed=self._seed if self._needs_initial_reset else None)
            self._needs_initial_reset = False  # only the first reset is seeded (RLlib's `_reset_envs_and_episodes`)
            lanes = [RunningEpisode(obs[i], mapping) for i in range(self.num_envs)]
        else:
            lanes = self.__dict__["_lanes"]
        env_ts = 0
        while env_ts < num_timesteps:
            actions, logp = self._act(lanes)
            for i, episode in enumerate(lanes):
                if episode is None:  # ended in the last iteration: reset now, as RLlib's vector env does
                    obs, _ = self._env_call(i, "reset")
                    lanes[i] = RunningEpisode(obs, mapping)
                    continue
                obs, rewards, terms, truncs, _ = self._env_call(i, "step", actions[i])
                episode.record(actions[i], logp[i], obs, rewards, terms, truncs)
                env_ts += self._increase_sampled_metrics(1, obs, episode)
                rollout.num_agent_steps += len(obs)
                if episode.is_done:
                    episode.emit(rollout, learning)
                    self._log_episode_metrics(*episode.metrics())
                    lanes[i] = None
        for episode in lanes:  # running episodes go out as chunks and continue next call
            if episode is not None and episode.chunk_steps:
                episode.emit(rollout, learning)
        self.__dict__["_lanes"] = lanes
        rollout.num_env_steps = env_ts
        return rollout

    def _env_call(self, i: int, method: str, *args: Any) -> Any:
        """Sub-environment `i`'s `reset()` or `step(actions)`; a failure is raised as RLlib's runner raises it (`RuntimeError from` it)."""
        try:
            return getattr(self.env.envs[i], method)(*args)
        except Exception as e:
            self.metrics.log_value(NUM_ENV_STEP_FAILURES_LIFETIME, 1, reduce="lifetime_sum")
            raise RuntimeError(
                f"sub-environment {i} failed in {method}(); run.restart_failed_sub_environments: true recreates it instead"
            ) from e

    def _act(self, lanes: list[RunningEpisode | None]) -> tuple[list[dict], list[dict]]:
        """One forward pass for every agent to act, rows per module in lane order; actions and log-probabilities per lane."""
        rows: dict[str, list[tuple[int, str]]] = {}
        for i, episode in enumerate(lanes):
            if episode is not None:
                for aid in episode.to_act():
                    rows.setdefault(episode.modules[aid], []).append((i, aid))
        actions: list[dict] = [{} for _ in lanes]
        logp: list[dict] = [{} for _ in lanes]
        if not rows:
            return actions, logp
        batch = {}
        for mid, where in rows.items():
            last = [lanes[i].obs[aid][-1] for i, aid in where]
            batch[mid] = {
                Columns.OBS: {key: torch.from_numpy(np.stack([o[key] for o in last])) for key in (RLLIB_OBS_KEY, RLLIB_MASK_KEY)}
            }
        out = self.module.forward_exploration(batch)
        for mid, where in rows.items():
            if Columns.ACTIONS not in out[mid]:
                self._draw(mid, out[mid])
            acts = to_numpy(out[mid][Columns.ACTIONS])
            lps = to_numpy(out[mid][Columns.ACTION_LOGP]) if Columns.ACTION_LOGP in out[mid] else None
            for j, (i, aid) in enumerate(where):
                actions[i][aid] = acts[j]
                if lps is not None:
                    logp[i][aid] = lps[j]
        return actions, logp

    def _draw(self, module_id: str, out: dict) -> None:
        """Draw a module's actions from its exploration distribution into `out`, with their log-probabilities (RLlib's `GetActions`)."""
        dist = self.module[module_id].get_exploration_action_dist_cls().from_logits(out[Columns.ACTION_DIST_INPUTS])
        out[Columns.ACTIONS] = dist.sample()
        out[Columns.ACTION_LOGP] = dist.logp(out[Columns.ACTIONS])
