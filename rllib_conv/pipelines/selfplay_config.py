"""`SelfPlayConfig`: the schema of `rllib-conv partners train` (self-play partner populations)."""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field, NonNegativeFloat, PositiveInt, model_validator

from rllib_conv.common.config_files import Strict
from rllib_conv.common.seeds import stream_seed
from rllib_conv.envs.registry import game
from rllib_conv.learners.settings import LearnerSettings
from rllib_conv.training.experiment import ExperimentConfig
from rllib_conv.training.settings import EnvName, FolderName, ModelSettings, PPOSettings, RunSettings


class GateSettings(Strict):
    """The score a self-play pair must reach to be kept, and how it is checked."""

    score: float
    episodes: PositiveInt = 1000
    check_every: PositiveInt = 5
    check_episodes: PositiveInt = 200
    stop: bool = Field(
        True,
        description="stop a pair at the first check that clears the gate; false: every pair trains its whole budget "
        "and the gate is judged at its end (HSP's biased partners, whose own reward is not the game's)",
    )


class HiddenUtilitySettings(Strict):
    """HSP's biased partners: each pair's partner seat is rewarded by a weighted count of its own events, drawn per pair."""

    events: list[str] = Field(
        min_length=1,
        description="the events the partner seat's reward weighs instead of the game's (the game record's `events`: "
        "Overcooked's are the MDP's, e.g. onion_pickup, potting_onion, dish_pickup, soup_pickup, soup_delivery)",
    )
    values: list[float] = Field(
        [-1.0, 0.0, 1.0],
        min_length=1,
        description="each event's weight is drawn from these, uniformly and independently per pair, from the pair's "
        "seed (redrawn while every weight is 0, when a value is not 0); our default, not the paper's",
    )

    def draw(self, seed: int) -> dict[str, float]:
        """The weights of the pair seeded `seed`: one value per event, the same for the same seed."""
        rng = np.random.default_rng(stream_seed(seed, "hidden_utility"))
        while True:
            weights = {event: float(rng.choice(self.values)) for event in self.events}
            if any(weights.values()) or not any(self.values):
                return weights


class SelfPlayConfig(Strict):
    """Self-play partner training: `train_pairs + test_pairs` pairs, pair k seeded `seed + k`.

    `ppo.rollout_per_partner` is the rollout length per iteration. With `shared_seats`
    one module plays every seat (Hanabi; any game of more than two seats, whose members then
    sit in any of the `partner_agent` seats); otherwise each seat has its own module and the
    `partner_agent` seat of each pair becomes a partner. With `fcp` the population is
    Fictitious Co-Play's (Strouse et al., NeurIPS 2021): each passing pair's partner seat
    also at its start and midway, as partners of the pair's split. With `population_entropy`
    the population is Maximum-Entropy Population's (Zhao et al., AAAI 2023): the pairs of each
    split train together in one algorithm, with a bonus for the entropy of their mean policy.
    With `trajectory_diversity` the population is TrajeDi's (Lupu et al., ICML 2021): the
    same joint training, with a bonus for the Jensen-Shannon divergence of the pairs'
    trajectory distributions (the two bonuses may be combined).
    """

    name: FolderName = "selfplay"
    env: EnvName
    env_config: dict[str, Any] = Field(default_factory=dict)
    train_pairs: PositiveInt = 10
    test_pairs: int = Field(10, ge=0)
    seed: int = 0
    pair: int = Field(0, ge=0)
    shared_seats: bool = False
    partner_agent: str | list[str] = Field(
        "player_1",
        description="the seat whose policy becomes a partner; in a game of more than two seats, the list of every "
        "seat but the ego's (e.g. [player_1, player_2]), with shared_seats, so each member can sit in any of them",
    )
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
    trajectory_diversity: NonNegativeFloat | None = Field(
        None,
        description="TrajeDi (Trajectory Diversity): train each split's pairs together as with population_entropy, "
        "rewarding each pair with beta (this value, in units of a standardized advantage) times the Jensen-Shannon "
        "divergence of the pairs' trajectory distributions per seat (each seat's discounted local action likelihoods, estimated on the pairs' own "
        "episodes); 0 trains them together with no bonus; may be combined with population_entropy",
    )
    trajectory_discount: float | None = Field(
        None,
        ge=0.0,
        le=1.0,
        description="TrajeDi's discount gamma of the local action likelihood prod_t' pi(a_t'|s_t')^(gamma^|t-t'|), in "
        "[0, 1]: 0 compares single moves, 1 whole trajectories; only with trajectory_diversity; unset: "
        f"{LearnerSettings.trajectory_discount} (our choice, not the paper's)",
    )
    hidden_utility: HiddenUtilitySettings | None = Field(
        None,
        description="HSP (hidden-utility self-play): the partner seat of each pair is rewarded by a weighted count of "
        "its own events (weights drawn per pair from its seed; the manifest and selfplay_report.csv record them), "
        "the other seat by the game's reward; the gate still scores the game. Games whose record lists events only",
    )
    model: ModelSettings = Field(default_factory=ModelSettings)
    ppo: PPOSettings = Field(default_factory=PPOSettings)
    run: RunSettings = Field(default_factory=RunSettings)
    gate: GateSettings

    @model_validator(mode="after")
    def _one_generator(self) -> "SelfPlayConfig":
        for key in ("population_entropy", "trajectory_diversity"):
            if self.fcp and getattr(self, key) is not None:
                raise ValueError(f"fcp and {key} cannot be combined: FCP's pairs train alone, {key}'s together")
        if self.trajectory_discount is not None and self.trajectory_diversity is None:
            raise ValueError("trajectory_discount is TrajeDi's: set trajectory_diversity too")
        if self.hidden_utility is not None:
            self._check_hidden_utility(self.hidden_utility)
        if len(self.partner_agents) > 1 and not self.shared_seats:
            # A member is one policy for every partner seat (`Population.teams` seats any member anywhere).
            raise ValueError("partner_agent: several partner seats need shared_seats: true (one module plays every seat)")
        if len(set(self.partner_agents)) < len(self.partner_agents):
            raise ValueError(f"partner_agent: seats must differ, got {self.partner_agent}")
        return self

    @property
    def partner_agents(self) -> list[str]:
        """The partner seats, a list (one seat in a two-seat game)."""
        return [self.partner_agent] if isinstance(self.partner_agent, str) else list(self.partner_agent)

    def _check_hidden_utility(self, hidden: HiddenUtilitySettings) -> None:
        if self.joint or self.shared_seats:
            raise ValueError(
                "hidden_utility (HSP) needs each pair alone with a module per seat: drop "
                + ("population_entropy/trajectory_diversity" if self.joint else "shared_seats")
            )
        known = game(self.env).events
        if not known:
            raise ValueError(f"hidden_utility: game {self.env!r} has no events a seat's reward can weigh (its record's `events`)")
        unknown = [event for event in hidden.events if event not in known]
        if unknown:
            raise ValueError(
                f"hidden_utility.events: unknown event(s) {unknown} of game {self.env!r}; events: {', '.join(known)}"
            )

    def pair_env_config(self, seed: int) -> dict[str, Any]:
        """The env config pair `seed` trains in: `env_config`, with HSP's drawn weights on the partner seat."""
        if self.hidden_utility is None:
            return self.env_config
        return {**self.env_config, "hidden_utility": {self.partner_agent: self.hidden_utility.draw(seed)}}

    @property
    def discount(self) -> float:
        """TrajeDi's discount: `trajectory_discount`, else the learner's default."""
        return LearnerSettings.trajectory_discount if self.trajectory_discount is None else self.trajectory_discount

    @property
    def joint(self) -> bool:
        """Whether the pairs of each split train together (MEP or TrajeDi: `population_entropy` or `trajectory_diversity` set)."""
        return self.population_entropy is not None or self.trajectory_diversity is not None

    def resolve(self) -> "SelfPlayConfig":
        """Return a copy with the game's defaults filled in (see `ExperimentConfig.resolve`)."""
        as_exp = ExperimentConfig(population="-", model=self.model, ppo=self.ppo, run=self.run).resolve(self.env)
        return self.model_copy(update={"model": as_exp.model, "ppo": as_exp.ppo, "run": as_exp.run})
