"""Turn an `ExperimentConfig` into an RLlib `PPOConfig` for the modular ego and its partners."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import torch
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core import COMPONENT_LEARNER, COMPONENT_RL_MODULE
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec

from rllib_conv import envs, partners
from rllib_conv.config import SINGLE_HEAD_METHODS, ExperimentConfig, PPOSettings, RunSettings
from rllib_conv.envs.rllib_adapter import (
    PettingZooMultiAgentEnv,
    RLlibGame,
    game_env_config,
)
from rllib_conv.learners.marginal_learner import MarginalPPOLearner
from rllib_conv.modules import (
    AGG_HEAD_ID,
    TASK_ID,
    ConventionMultiRLModule,
    FixedPartnerModule,
    PartnerHeadModule,
    PartnerMapping,
    TaskModule,
    ego_id,
    partner_id,
)
from rllib_conv.partners.population import PartnerEntry, Population


@dataclass
class EgoSetup:
    """Everything derived from an experiment: resolved config, population, seats, module IDs."""

    exp: ExperimentConfig
    population: Population
    env_config: dict
    ego_agent: str
    partner_agent: str
    train: list[PartnerEntry]

    @property
    def head_ids(self) -> list[str]:
        """The ego heads being trained (one per training partner; one for BaselineAgg)."""
        return [AGG_HEAD_ID] if self.exp.method in SINGLE_HEAD_METHODS else [ego_id(e.name) for e in self.train]


def resolve(exp: ExperimentConfig) -> EgoSetup:
    """Load the population, check it fits the game, and fill in the game's defaults."""
    pop = partners.get(exp.population)
    return setup_for(exp, pop, pop.entries("train"))


def setup_for(exp: ExperimentConfig, pop: Population, train: list[PartnerEntry]) -> EgoSetup:
    """The setup training the ego of `exp` against the partners `train` of `pop`."""
    if exp.env is not None and exp.env != pop.env:
        raise ValueError(f"env {exp.env!r} does not match population {pop.name!r}, which is for {pop.env!r}")
    env_config = {**pop.env_config, **exp.env_config}
    probe = envs.make(pop.env, **env_config)
    if len(probe.possible_agents) != 2 or pop.partner_agent not in probe.possible_agents:
        raise ValueError(
            f"population {pop.name!r}: partner_agent {pop.partner_agent!r} must be one of the game's two agents "
            f"{probe.possible_agents}"
        )
    if not train:
        raise ValueError(f"population {pop.name!r} has no partners to train with")
    ego_agent = next(a for a in probe.possible_agents if a != pop.partner_agent)
    return EgoSetup(exp.resolve(pop.env), pop, env_config, ego_agent, pop.partner_agent, train)


def module_specs(setup: EgoSetup, load: dict[str, str] | None = None) -> dict[str, RLModuleSpec]:
    """Return the RLModuleSpecs: the task module, the ego heads and the fixed partners.

    `load` maps module IDs to module checkpoint folders whose weights they start from.
    """
    exp = setup.exp
    env = PettingZooMultiAgentEnv(envs.make(setup.population.env, **setup.env_config))
    ego_obs, ego_act = env.observation_spaces[setup.ego_agent], env.action_spaces[setup.ego_agent]
    sizes = {"hidden": exp.model.hidden, "z_dim": exp.model.z_dim}
    task_config = dict(sizes)
    if exp.method == "oracle":
        task_config["oracle"] = {"env": setup.population.env, "env_config": setup.env_config}
    specs = {TASK_ID: RLModuleSpec(module_class=TaskModule, observation_space=ego_obs, action_space=ego_act, model_config=task_config)}
    head_config = {**sizes, "use_task_logits": exp.method != "no_task_logits"}
    for mid in setup.head_ids:
        specs[mid] = RLModuleSpec(module_class=PartnerHeadModule, observation_space=ego_obs, action_space=ego_act, model_config=head_config)
    p_obs, p_act = env.observation_spaces[setup.partner_agent], env.action_spaces[setup.partner_agent]
    for i, entry in enumerate(setup.train):
        spec = {"name": entry.name, "kind": entry.kind, "params": entry.params}
        specs[partner_id(entry.name)] = RLModuleSpec(
            module_class=FixedPartnerModule,
            observation_space=p_obs,
            action_space=p_act,
            model_config={"partner": spec, "seed": exp.seed * 1000 + i},
        )
    for mid, path in (load or {}).items():
        specs[mid].load_state_path = str(path)
    return specs


def base_ppo_config(game: str, env_config: dict, ppo: PPOSettings, run: RunSettings, seed: int, batch_size: int) -> PPOConfig:
    """The PPOConfig pieces shared by ego and self-play training (env, runners, learner, PPO)."""
    return (
        PPOConfig()
        .environment(
            RLlibGame,
            env_config=game_env_config(game, env_config),
            # RLlib's checker steps the env with unmasked random actions, which our games
            # rightly reject as illegal; the games are tested with PettingZoo's own checks.
            disable_env_checking=True,
        )
        .env_runners(
            num_env_runners=run.num_env_runners,
            num_envs_per_env_runner=run.num_envs_per_env_runner,
            rollout_fragment_length="auto",
            # RLlib 2.60 converts every finished episode to numpy again on every sampling
            # step (quadratic in episodes per sample call); one-step games suffer most.
            episodes_to_numpy=False,
        )
        .fault_tolerance(
            restart_failed_env_runners=True,
            restart_failed_sub_environments=run.restart_failed_sub_environments,
        )
        .training(
            lr=ppo.lr,
            gamma=ppo.gamma,
            lambda_=ppo.gae_lambda,
            clip_param=ppo.clip_param,
            entropy_coeff=ppo.entropy_coeff if isinstance(ppo.entropy_coeff, float) else [list(p) for p in ppo.entropy_coeff],
            vf_loss_coeff=ppo.vf_loss_coeff,
            grad_clip=ppo.grad_clip,
            grad_clip_by="global_norm",
            train_batch_size_per_learner=batch_size,
            minibatch_size=ppo.minibatch_size,
            num_epochs=ppo.num_epochs,
            use_kl_loss=False,
            kl_coeff=0.0,
            # The paper's code (SB3) does not clip the value loss; RLlib's default of 10
            # would clip every blocks return (up to 20) and stall the critic.
            vf_clip_param=math.inf,
        )
        .debugging(seed=seed)
    )


def build_ppo_config(setup: EgoSetup, load: dict[str, str] | None = None) -> PPOConfig:
    """Return the PPOConfig training the ego against `setup`'s partners (starting weights from `load`)."""
    exp, ppo = setup.exp, setup.exp.ppo
    specs = module_specs(setup, load)
    mapping = PartnerMapping(
        [e.name for e in setup.train], setup.ego_agent, setup.partner_agent, shared_head=exp.method in SINGLE_HEAD_METHODS
    )
    return (
        base_ppo_config(setup.population.env, setup.env_config, ppo, exp.run, exp.seed, ppo.rollout_per_partner * len(setup.train))
        .multi_agent(
            # A list, not a set: module build order (and so initial weights) must not depend on
            # string hashing, which differs per process (Tune runs each trial in its own).
            policies=list(specs),
            policy_mapping_fn=mapping,
            policies_to_train=[TASK_ID, *setup.head_ids],
        )
        .rl_module(rl_module_spec=MultiRLModuleSpec(multi_rl_module_class=ConventionMultiRLModule, rl_module_specs=specs))
        .learners(
            learner_class=MarginalPPOLearner,
            learner_config_dict={
                "lam": exp.lam,
                "freeze": list(exp.freeze),
                "adam_eps": ppo.adam_eps,
                "z_lr_scale": exp.z_lr_scale,
                "head_l2": exp.head_l2,
            },
        )
    )


def push_learner_weights(algo: Any) -> None:
    """Send the learner's module weights to every env runner, local and remote (as PPO does after an update)."""
    state = algo.learner_group.get_state(components=f"{COMPONENT_LEARNER}/{COMPONENT_RL_MODULE}", inference_only=True)
    # No weights sequence number: env runners skip states whose number they have seen, and
    # weights changed outside an update (MAML's outer step, a reset layer) keep the old one.
    module_state = {COMPONENT_RL_MODULE: state[COMPONENT_LEARNER][COMPONENT_RL_MODULE]}
    algo.env_runner_group.sync_env_runner_states(config=algo.config, rl_module_state=module_state)


Weights = dict[str, dict[str, torch.Tensor]]  # module ID -> state dict


def snapshot(module: Any, module_ids: tuple[str, ...]) -> Weights:
    """A detached copy of the weights of `module_ids` in a MultiRLModule."""
    return {mid: {k: v.detach().clone() for k, v in module[mid].state_dict().items()} for mid in module_ids}


def load_weights(module: Any, weights: Weights) -> None:
    """Write `weights` into the MultiRLModule's sub-modules in place (optimizers keep their tensors)."""
    with torch.no_grad():
        for mid, params in weights.items():
            for k, v in module[mid].state_dict().items():
                v.copy_(params[k])
