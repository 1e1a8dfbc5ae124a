"""`SelfPlayConfig`: the schema of `rllib-conv partners train` (self-play partner populations)."""

from __future__ import annotations

from typing import Any

from pydantic import Field, NonNegativeFloat, PositiveInt, model_validator

from rllib_conv.common.config_files import Strict
from rllib_conv.training.experiment import ExperimentConfig
from rllib_conv.training.settings import EnvName, FolderName, ModelSettings, PPOSettings, RunSettings


class GateSettings(Strict):
    """The score a self-play pair must reach to be kept, and how it is checked."""

    score: float
    episodes: PositiveInt = 1000
    check_every: PositiveInt = 5
    check_episodes: PositiveInt = 200


class SelfPlayConfig(Strict):
    """Self-play partner training: `train_pairs + test_pairs` pairs, pair k seeded `seed + k`.

    `ppo.rollout_per_partner` is the rollout length per iteration. With `shared_seats`
    one module plays both seats (Hanabi); otherwise each seat has its own module and the
    `partner_agent` seat of each pair becomes a partner. With `fcp` the population is
    Fictitious Co-Play's (Strouse et al., NeurIPS 2021): each passing pair's partner seat
    also at its start and midway, as partners of the pair's split. With `population_entropy`
    the population is Maximum-Entropy Population's (Zhao et al., AAAI 2023): the pairs of each
    split train together in one algorithm, with a bonus for the entropy of their mean policy.
    """

    name: FolderName = "selfplay"
    env: EnvName
    env_config: dict[str, Any] = Field(default_factory=dict)
    train_pairs: PositiveInt = 10
    test_pairs: int = Field(10, ge=0)
    seed: int = 0
    pair: int = Field(0, ge=0)
    shared_seats: bool = False
    partner_agent: str = "player_1"
    greedy_partners: bool = True
    fcp: bool = Field(
        False,
        description="also keep each passing pair's partner seat as it was before training and midway (the gate check "
        "nearest half its final score) as partners <name>-init and <name>-mid: Fictitious Co-Play's partners",
    )
    population_entropy: NonNegativeFloat | None = Field(
        None,
        description="MEP (Maximum-Entropy Population): train each split's pairs together in one algorithm, every pair "
        "with its own seat modules and seeds, adding to each pair's loss -alpha (this value) times the entropy of the "
        "pairs' mean policy per seat on the same observations; 0 trains them together with no bonus (then each "
        "pair trains as it would in a population of one); unset: each pair is a trial of its own",
    )
    model: ModelSettings = Field(default_factory=ModelSettings)
    ppo: PPOSettings = Field(default_factory=PPOSettings)
    run: RunSettings = Field(default_factory=RunSettings)
    gate: GateSettings

    @model_validator(mode="after")
    def _one_generator(self) -> "SelfPlayConfig":
        if self.fcp and self.population_entropy is not None:
            raise ValueError("fcp and population_entropy cannot be combined: choose FCP's or MEP's partners")
        return self

    @property
    def joint(self) -> bool:
        """Whether the pairs of each split train together (MEP, `population_entropy` set)."""
        return self.population_entropy is not None

    def resolve(self) -> "SelfPlayConfig":
        """Return a copy with the game's defaults filled in (see `ExperimentConfig.resolve`)."""
        as_exp = ExperimentConfig(population="-", model=self.model, ppo=self.ppo, run=self.run).resolve(self.env)
        return self.model_copy(update={"model": as_exp.model, "ppo": as_exp.ppo, "run": as_exp.run})
