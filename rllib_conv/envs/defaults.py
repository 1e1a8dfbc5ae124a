"""The paper's settings per game: network size, PPO batches, training budgets, adaptation and zero-shot protocols.

From the paper's Tables 2-4 and its released code (`shared/notes/original-code.md`).
Configs leave these unset and take them from here for their game; a user's own game gets
`FALLBACK_DEFAULTS` (and, for adaptation and zero-shot, settings derived from its rollout).
"""

from __future__ import annotations

# Layer size, rollout steps per partner, minibatch, epochs, training env steps.
GAME_DEFAULTS: dict[str, dict[str, int]] = {
    "bandit": {"hidden": 30, "rollout_per_partner": 64, "minibatch_size": 16, "num_epochs": 20, "timesteps": 10_000},
    "blocks": {"hidden": 80, "rollout_per_partner": 640, "minibatch_size": 160, "num_epochs": 5, "timesteps": 1_000_000},
    "hanabi": {"hidden": 500, "rollout_per_partner": 640, "minibatch_size": 160, "num_epochs": 5, "timesteps": 500_000},
}
FALLBACK_DEFAULTS = {"hidden": 64, "rollout_per_partner": 256, "minibatch_size": 64, "num_epochs": 10, "timesteps": 100_000}

# The paper's adaptation protocol: evaluate every `every` env steps up to `steps`; one PPO
# update of `minibatch_size` x `num_epochs` per `every` steps (Table 3 and the notes).
ADAPT_DEFAULTS: dict[str, dict[str, int]] = {
    "bandit": {"every": 16, "steps": 240, "minibatch_size": 16, "num_epochs": 50},
    "blocks": {"every": 640, "steps": 25_600, "minibatch_size": 160, "num_epochs": 5},
    "hanabi": {"every": 640, "steps": 25_600, "minibatch_size": 160, "num_epochs": 5},
}

# Zero-shot step 1 runs until the test heads have converged on the old task: on blocks
# ~19.5 of 20 by 300k steps (at 100k, BaselineModular's heads, which learn the rules too,
# reach ~11.5). Step 2 re-trains the task module on the new task.
ZEROSHOT_DEFAULTS: dict[str, dict[str, int]] = {
    "bandit": {"head_steps": 2_560, "task_steps": 10_000},
    "blocks": {"head_steps": 300_000, "task_steps": 400_000},
}
