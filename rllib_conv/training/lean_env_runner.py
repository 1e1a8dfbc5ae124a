"""`LeanEnvRunner`: RLlib's `MultiAgentEnvRunner` with its per-step and per-episode metric logging batched.

It is the base of `BatchedEnvRunner`, the one env runner training uses: the batched loop
counts its metrics here, and the calls that loop leaves to RLlib (evaluation-style calls:
`num_episodes`, `explore=False`, random actions) sample through this class. On its own it
is RLlib's sampling path, the reference `tests/training/test_batched_env_runner.py`
checks the batched loop against; no config selects it.

RLlib logs four metric values per agent per env step and a dozen per episode, each through
its `MetricsLogger`; on our short episodes of small games that bookkeeping costs as much as
sampling itself. This runner keeps the same numbers (env, agent and module steps; episode
returns, lengths and per-agent / per-module returns over the same smoothing window of
`metrics_num_episodes_for_smoothing` episodes) in plain counters and windows, and hands them
to the logger once per `get_metrics` call. Sampling itself is RLlib's, unchanged. It also
logs each replica's own env steps (`ReplicatedGame.take_moves`), which RLlib has no count of,
and, once asked to (`record_module_returns`), keeps every finished episode's return per module
until `take_module_returns` (the fine-tune guard of adaptation reads them).
"""

from __future__ import annotations

import math
from collections import Counter, defaultdict, deque
from typing import Any

from ray.rllib.env.multi_agent_env_runner import MultiAgentEnvRunner
from ray.rllib.utils.metrics import (
    EPISODE_AGENT_RETURN_MEAN,
    EPISODE_AGENT_STEPS,
    EPISODE_DURATION_SEC_MEAN,
    EPISODE_LEN_MAX,
    EPISODE_LEN_MEAN,
    EPISODE_LEN_MIN,
    EPISODE_MODULE_RETURN_MEAN,
    EPISODE_RETURN_MAX,
    EPISODE_RETURN_MEAN,
    EPISODE_RETURN_MIN,
    NUM_AGENT_STEPS_SAMPLED,
    NUM_AGENT_STEPS_SAMPLED_LIFETIME,
    NUM_ENV_STEPS_SAMPLED,
    NUM_ENV_STEPS_SAMPLED_LIFETIME,
    NUM_EPISODES,
    NUM_EPISODES_LIFETIME,
    NUM_MODULE_STEPS_SAMPLED,
    NUM_MODULE_STEPS_SAMPLED_LIFETIME,
)

# Env steps each replica of a `ReplicatedGame` played (`training/replica_steps.py` reads them).
NUM_REPLICA_STEPS_SAMPLED_LIFETIME = "num_replica_steps_sampled_lifetime"


class LeanEnvRunner(MultiAgentEnvRunner):
    """A `MultiAgentEnvRunner` whose metrics are counted in plain Python and logged once per `get_metrics`."""

    def _lean_state(self) -> dict[str, Any]:
        state = self.__dict__.get("_lean")
        if state is None:
            win = max(1, int(math.ceil(self.config.metrics_num_episodes_for_smoothing / (self.config.num_env_runners or 1))))
            state = self.__dict__["_lean"] = {
                "window": win,
                "env_steps": 0,
                "episodes": 0,
                "agent_steps": Counter(),
                "module_steps": Counter(),
                "episode": {key: deque(maxlen=win) for key in ("len", "ret", "sec")},
                "agents": defaultdict(lambda: deque(maxlen=win)),
                "agent_len": defaultdict(lambda: deque(maxlen=win)),
                "modules": defaultdict(lambda: deque(maxlen=win)),
                "finished": None,  # module ID -> returns of finished episodes, while recording
            }
        return state

    def record_module_returns(self) -> None:
        """From now on keep each module's return in every finished episode, for `take_module_returns`."""
        lean = self._lean_state()
        if lean["finished"] is None:
            lean["finished"] = defaultdict(list)

    def take_module_returns(self) -> dict[str, list[float]]:
        """Each module's returns in the episodes finished since the last call (in finishing order), and forget them."""
        finished = self._lean_state()["finished"]
        if finished is None:
            raise RuntimeError("take_module_returns before record_module_returns: this runner keeps no returns")
        out = {mid: list(values) for mid, values in finished.items()}
        finished.clear()
        return out

    def _increase_sampled_metrics(self, num_steps: int, next_obs: dict, episode: Any) -> int:
        lean = self._lean_state()
        lean["env_steps"] += num_steps
        if episode.is_done:
            lean["episodes"] += 1
        for aid in next_obs:
            lean["agent_steps"][str(aid)] += 1
            lean["module_steps"][episode.module_for(aid)] += 1
        return num_steps

    def _log_episode_metrics(self, length, ret, sec, agents=None, modules=None, agent_steps=None) -> None:
        lean = self._lean_state()
        for key, value in (("len", length), ("ret", ret), ("sec", sec)):
            lean["episode"][key].append(value)
        for aid, value in (agents or {}).items():
            lean["agents"][aid].append(value)
        for aid, value in (agent_steps or {}).items():
            lean["agent_len"][aid].append(value)
        for mid, value in (modules or {}).items():
            lean["modules"][mid].append(value)
            if lean["finished"] is not None:
                lean["finished"][mid].append(value)

    def _flush(self) -> None:
        """Log what was counted since the last flush, with RLlib's keys and reductions."""
        lean, log = self._lean_state(), self.metrics.log_value
        log(NUM_ENV_STEPS_SAMPLED, lean["env_steps"], reduce="sum")
        log(NUM_ENV_STEPS_SAMPLED_LIFETIME, lean["env_steps"], reduce="lifetime_sum", with_throughput=True)
        log(NUM_EPISODES, lean["episodes"], reduce="sum")
        log(NUM_EPISODES_LIFETIME, lean["episodes"], reduce="lifetime_sum")
        for aid, n in lean["agent_steps"].items():
            log((NUM_AGENT_STEPS_SAMPLED, aid), n, reduce="sum")
            log((NUM_AGENT_STEPS_SAMPLED_LIFETIME, aid), n, reduce="lifetime_sum")
        for mid, n in lean["module_steps"].items():
            log((NUM_MODULE_STEPS_SAMPLED, mid), n, reduce="sum")
            log((NUM_MODULE_STEPS_SAMPLED_LIFETIME, mid), n, reduce="lifetime_sum")
        for r, n in enumerate(self._replica_moves()):
            log((NUM_REPLICA_STEPS_SAMPLED_LIFETIME, str(r)), n, reduce="lifetime_sum")
        lean["env_steps"], lean["episodes"] = 0, 0
        lean["agent_steps"].clear()
        lean["module_steps"].clear()
        episode = lean["episode"]
        if episode["ret"]:
            # Window means (and extremes) over the last `window` episodes, as RLlib's windowed stats give.
            def mean(values: deque) -> float:
                return float(sum(values) / len(values))

            log(EPISODE_LEN_MEAN, mean(episode["len"]), window=1)
            log(EPISODE_RETURN_MEAN, mean(episode["ret"]), window=1)
            log(EPISODE_DURATION_SEC_MEAN, mean(episode["sec"]), window=1)
            log(EPISODE_LEN_MIN, min(episode["len"]), reduce="min", window=1)
            log(EPISODE_RETURN_MIN, min(episode["ret"]), reduce="min", window=1)
            log(EPISODE_LEN_MAX, max(episode["len"]), reduce="max", window=1)
            log(EPISODE_RETURN_MAX, max(episode["ret"]), reduce="max", window=1)
            for key, table in (
                (EPISODE_AGENT_RETURN_MEAN, lean["agents"]),
                (EPISODE_AGENT_STEPS, lean["agent_len"]),
                (EPISODE_MODULE_RETURN_MEAN, lean["modules"]),
            ):
                for name, values in table.items():
                    log((key, name), mean(values), window=1)

    def _replica_moves(self) -> list[int]:
        """Env steps per replica since the last flush, summed over this runner's `ReplicatedGame`s (none for other envs)."""
        takes = [env.unwrapped.take_moves() for env in getattr(self.env, "envs", []) if hasattr(env.unwrapped, "take_moves")]
        return [sum(per_env) for per_env in zip(*takes)]  # every sub-env holds the same replicas

    def get_metrics(self) -> Any:
        result = super().get_metrics()  # logs this call's finished episodes through `_log_episode_metrics`
        self._flush()
        return result | self.metrics.reduce()
