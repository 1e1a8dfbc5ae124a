"""`ZeroShotConfig`: the schema of `rllib-conv zeroshot` (the paper's three zero-shot steps)."""

from __future__ import annotations

from pydantic import NonNegativeFloat, PositiveInt

from rllib_conv.common.config_files import Strict
from rllib_conv.training.settings import EntropyCoeff, FolderName


class ZeroShotConfig(Strict):
    """Zero-shot coordination on a new task with known partners (the paper's three steps).

    1. Fresh heads for the test partners on the old task, task module frozen (`head_steps`,
       regulariser weight `head_lam`, default the run's lam: trained as the training
       partners' heads were, they leave the rules to the task module).
    2. The task module re-trained on the new task with the training partners' heads frozen
       (`task_steps`, regulariser weight `task_lam`, default the run's lam; the z layers
       learn at `task_z_lr_scale` times the learning rate: 1 as in training, 0 frozen);
       `reset_task_logits` re-initialises the task logits layer first, and `task_entropy`
       adds an entropy bonus, so the new rules get explored.
    3. The new task module with the test partners' heads, evaluated on the new task with no
       further training (`episodes` episodes; exactly on the bandit).
    `new_population` defaults to the run's population + "-newtask".
    """

    name: FolderName = "zeroshot"
    runs: list[str]
    new_population: str | None = None
    head_steps: PositiveInt | None = None
    task_steps: PositiveInt | None = None
    reset_task_logits: bool = True
    # Trained heads carry some of the old rules too; without exploration the task module
    # never tries the new rule actions (the original code's 0.49 on the bandit).
    task_entropy: EntropyCoeff = 0.05
    task_lam: NonNegativeFloat | None = None
    task_z_lr_scale: NonNegativeFloat = 1.0
    head_lam: NonNegativeFloat | None = None
    episodes: PositiveInt = 200
    seed: int = 0
    # Egos run together as replicas of one algorithm (speed only: each runs as it would alone).
    max_pack: PositiveInt = 32
