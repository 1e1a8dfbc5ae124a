"""`ZeroShotConfig`: the schema of `rllib-conv zeroshot` (the paper's three zero-shot steps)."""

from __future__ import annotations

from pydantic import Field, NonNegativeFloat, PositiveInt

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

    name: FolderName = Field("zeroshot", description="name of the output CSV and Tune experiment")
    runs: list[str] = Field(description="trained-ego trial folders or experiment folders")
    new_population: str | None = Field(
        None, description="population of the same partners on the new task (default: POPULATION-newtask)"
    )
    head_steps: PositiveInt | None = Field(
        None, description="step 1: env steps training the test partners' heads on the old task (default: the game's)"
    )
    task_steps: PositiveInt | None = Field(
        None, description="step 2: env steps re-training the task module on the new task (default: the game's)"
    )
    reset_task_logits: bool = Field(True, description="step 2: re-initialise the task logits layer first")
    # Trained heads carry some of the old rules too; without exploration the task module
    # never tries the new rule actions (the original code's 0.49 on the bandit).
    task_entropy: EntropyCoeff = Field(
        0.05, description="step 2: entropy bonus, a constant or a schedule [[0, 0.05], [STEP, VALUE]]"
    )
    task_lam: NonNegativeFloat | None = Field(None, description="step 2: regulariser weight (default: the run's lam)")
    task_z_lr_scale: NonNegativeFloat = Field(1.0, description="step 2: learning-rate scale of the z layers (0 freezes them)")
    head_lam: NonNegativeFloat | None = Field(None, description="step 1: regulariser weight (default: the run's lam)")
    episodes: PositiveInt = Field(200, description="step 3: evaluation episodes")
    seed: int = Field(0, description="seed of the evaluation episodes")
    # Egos run together as replicas of one algorithm (speed only: each runs as it would alone).
    max_pack: PositiveInt = Field(32, description="egos run together in one algorithm, for speed (each runs as it would alone)")
