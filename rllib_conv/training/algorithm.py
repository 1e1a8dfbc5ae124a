"""Turn an `EgoSetup` into an RLlib `PPOConfig` for the modular ego and its partners."""

from __future__ import annotations

import math

from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec

from rllib_conv import envs
from rllib_conv.common.methods import method
from rllib_conv.envs.rllib_adapter import PettingZooMultiAgentEnv, RLlibGame, game_env_config
from rllib_conv.learners.marginal_learner import MarginalPPOLearner
from rllib_conv.modules import (
    TASK_ID,
    ConventionMultiRLModule,
    FixedPartnerModule,
    PartnerHeadModule,
    PartnerMapping,
    TaskModule,
    partner_id,
)
from rllib_conv.training.ego_setup import EgoSetup
from rllib_conv.training.settings import PPOSettings, RunSettings


def module_specs(setup: EgoSetup, load: dict[str, str] | None = None) -> dict[str, RLModuleSpec]:
    """Return the RLModuleSpecs: the task module, the ego heads and the fixed partners.

    `load` maps module IDs to module checkpoint folders whose weights they start from.
    """
    exp = setup.exp
    env = PettingZooMultiAgentEnv(envs.make(setup.population.env, **setup.env_config))
    ego_obs, ego_act = env.observation_spaces[setup.ego_agent], env.action_spaces[setup.ego_agent]
    sizes = {"hidden": exp.model.hidden, "z_dim": exp.model.z_dim}
    task_config = dict(sizes)
    if method(exp.method).task_logits == "oracle":
        task_config["oracle"] = {"env": setup.population.env, "env_config": setup.env_config}
    specs = {TASK_ID: RLModuleSpec(module_class=TaskModule, observation_space=ego_obs, action_space=ego_act, model_config=task_config)}
    head_config = {**sizes, "use_task_logits": method(exp.method).task_logits != "unused"}
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
        [e.name for e in setup.train], setup.ego_agent, setup.partner_agent, shared_head=method(exp.method).single_head
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
        .learners(learner_class=MarginalPPOLearner, learner_config_dict=exp.learner_settings().config_dict())
    )
