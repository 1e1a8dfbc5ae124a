"""Carroll et al.'s reward-shaping schedule: the shaping factor falls linearly from 1 to 0.

Overcooked's sparse reward (20 per soup delivered) is too rare for PPO to find from scratch,
so Carroll et al. (NeurIPS 2019) add the MDP's shaped reward (3 for an ingredient put in a
pot, 3 for a useful dish pickup, 5 for picking up a cooked soup) times a factor that
anneals from 1 to 0 over the first `shaping_horizon` env steps of training; after that the
agents train on the sparse reward alone. Their `human_aware_rl` computes it as here
(`fraction = max(1 - steps / horizon, 0)`; factor `start * fraction + end * (1 - fraction)`).

How a trainer anneals it: either give the env `shaping_horizon` (each env instance then
anneals by its own step count, so with N envs sampling in parallel pass the training
horizon divided by N), or keep `shaping_horizon=None` and call `env.set_shaping(
shaping_factor(global_env_steps, horizon))` on every env from a callback after each
training iteration (RLlib: `algorithm.env_runner_group.foreach_env(...)` reaching the
`OvercookedEnv` inside the adapter), which is what `human_aware_rl` does.
"""

from __future__ import annotations


def shaping_factor(env_steps: int, shaping_horizon: int, start: float = 1.0, end: float = 0.0) -> float:
    """The shaping factor after `env_steps` env steps: `start` at 0, `end` from `shaping_horizon` on, linear between."""
    if not isinstance(shaping_horizon, int) or isinstance(shaping_horizon, bool) or shaping_horizon <= 0:
        raise ValueError(f"shaping_horizon must be a positive integer (env steps), got {shaping_horizon!r}")
    if env_steps < 0:
        raise ValueError(f"env_steps must be >= 0, got {env_steps!r}")
    fraction = max(1.0 - env_steps / shaping_horizon, 0.0)
    return start * fraction + end * (1.0 - fraction)
