"""`ExperimentConfig`: one ego-training experiment (game, partners, method, regulariser, sizes, PPO, run).

It is the schema of `rllib-conv train` and `sweep` (any value may be a Tune grid; see
`rllib_conv.common.config_files`), and what every later pipeline reads back from a
trained ego's `config.yaml` (`trial_config`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import Field, model_validator

from rllib_conv.common import config_files
from rllib_conv.common.config_files import Checked, Strict
from rllib_conv.common.methods import MethodName, method
from rllib_conv.common.run_folders import CONFIG_FILE, checkpoints, read_trial_config
from rllib_conv.envs.registry import game as game_record
from rllib_conv.learners.settings import LearnerSettings
from rllib_conv.training.settings import (
    EnvName,
    FolderName,
    MAMLSettings,
    MappingSettings,
    ModelSettings,
    PPOSettings,
    RunSettings,
)


class ExperimentConfig(Strict):
    """One ego-training experiment: game, partners, method, regulariser, sizes, PPO, run."""

    name: FolderName = "experiment"
    env: EnvName | None = None
    env_config: dict[str, Any] = Field(default_factory=dict)
    population: str
    method: MethodName = "modular"
    lam: float = Field(LearnerSettings.lam, ge=0.0)
    freeze: list[str] = Field(default_factory=list)
    # Learning-rate multiplier for the task module's z layers (0 freezes them, 1 is plain PPO).
    z_lr_scale: float = Field(LearnerSettings.z_lr_scale, ge=0.0)
    # Weight of the head penalty (not in the paper; see MarginalPPOLearner): heads carry conventions only.
    head_l2: float = Field(LearnerSettings.head_l2, ge=0.0)
    seed: int = 0
    model: ModelSettings = Field(default_factory=ModelSettings)
    ppo: PPOSettings = Field(default_factory=PPOSettings)
    run: RunSettings = Field(default_factory=RunSettings)
    maml: MAMLSettings = Field(default_factory=MAMLSettings)
    mapping: MappingSettings = Field(default_factory=MappingSettings)

    @model_validator(mode="after")
    def _consistent(self) -> "ExperimentConfig":
        if not method(self.method).regularised and self.lam > 0:
            raise ValueError(f"lam must be 0 for method {self.method!r} (it has no learned task logits to regularise)")
        if not method(self.method).head_penalty and self.head_l2 > 0:
            raise ValueError(
                f"head_l2 must be 0 for method {self.method!r} (only modular heads sit on task logits that can take over)"
            )
        return self

    def resolve(self, game: str) -> "ExperimentConfig":
        """Return a copy for `game` with every unset game-dependent field set to the paper's value."""
        d = game_record(game).training_defaults().as_dict()
        out = self.model_copy(deep=True)
        out.env = game
        out.model.hidden = out.model.hidden or d["hidden"]
        for key in ("rollout_per_partner", "minibatch_size", "num_epochs"):
            if getattr(out.ppo, key) is None:
                setattr(out.ppo, key, d[key])
        if self.ppo.minibatch_size is None and out.ppo.minibatch_size > out.ppo.rollout_per_partner:
            # A shorter rollout than the game's, with its minibatch left to the game: RLlib would refuse a minibatch
            # larger than the train batch inside the trial, so the default shrinks to one rollout.
            out.ppo.minibatch_size = out.ppo.rollout_per_partner
        out.run.timesteps = out.run.timesteps or d["timesteps"]
        return out

    def learner_settings(self) -> LearnerSettings:
        """What the learner needs of this experiment: regulariser, head penalty, freezing, Adam."""
        return self.ppo.learner_settings(
            lam=self.lam, freeze=tuple(self.freeze), z_lr_scale=self.z_lr_scale, head_l2=self.head_l2
        )


def trial_config(trial: str | Path) -> ExperimentConfig:
    """The resolved ego config a trained-ego trial folder was run with (its `config.yaml`).

    ValueError naming the file when it is not what was saved (`common.sealed.verify_file`),
    not YAML, or not a valid config: a damaged config must not pass for another experiment.
    """
    path = Path(trial) / CONFIG_FILE
    return config_files.check(read_trial_config(trial), ExperimentConfig, {}, f"trial config {str(path)!r}")[0]


def check_trial(trial: str | Path) -> ExperimentConfig:
    """A trained-ego trial folder's config (`trial_config`), after checking it has a checkpoint (the pipeline verifies its files)."""
    exp = trial_config(trial)
    if not checkpoints(trial):
        raise ValueError(f"trial {str(trial)!r} has no checkpoint (checkpoint_* folders)")
    return exp


def load(path: str | Path, overrides: list[str] = ()) -> Checked[ExperimentConfig]:
    """Read an experiment YAML with `--set` overrides, checked: the raw dict for Tune and every grid combination validated."""
    return config_files.load_checked(path, overrides, schema=ExperimentConfig)


def checked(raw: dict[str, Any], source: str = "config") -> Checked[ExperimentConfig]:
    """The experiment `raw`, checked: every grid combination validated (ValueError naming `source` and the bad key)."""
    return config_files.checked(raw, ExperimentConfig, source)
