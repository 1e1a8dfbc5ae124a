"""Turn `EgoSetup`s into one RLlib `PPOConfig`: the modular ego and its partners, one or several replicas.

A `Replica` is one independent ego of the algorithm: its setup, the weights it starts
from, and its seed. Several replicas (the seeds of one experiment, or the curves of one
adaptation) train in one algorithm on a `ReplicatedGame`, each with its own modules
(`task#r`, `ego@p#r`, `partner@p#r`) seeded from its own seed alone: initial weights,
exploration, minibatch shuffles and games. A replica therefore trains exactly as it would
alone, while the env runner and the learner pay their per-step and per-update costs once
for all of them.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from typing import Any

from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec

from rllib_conv import envs
from rllib_conv.common.methods import method
from rllib_conv.common.seeds import partner_seed, sampling_seed, shuffle_seed, stream_seed
from rllib_conv.envs.replicated_game import ReplicatedGame, replicated_env_config
from rllib_conv.envs.rllib_adapter import PettingZooMultiAgentEnv
from rllib_conv.learners.marginal_learner import MarginalPPOLearner
from rllib_conv.modules import TASK_ID, FixedPartnerModule, PartnerHeadModule, PartnerMapping, TaskModule, partner_id
from rllib_conv.modules.multi import replica_id
from rllib_conv.modules.packed.ego_stack import EgoStack
from rllib_conv.modules.packed.stacked_multi import STACK_ID, HeadView, StackedEgoMultiRLModule
from rllib_conv.modules.partner_schedule import FixedTeam, PartnerFunction, RoundRobin, WeightedPartners
from rllib_conv.partners.trained import load_rl_module
from rllib_conv.training.batched_env_runner import BatchedEnvRunner
from rllib_conv.training.ego_setup import EgoSetup
from rllib_conv.training.settings import MappingSettings, PPOSettings, RunSettings
from rllib_conv.training.weights import push_learner_weights

# The algorithm's own seed (RLlib's global seeding and sub-environment offsets); every
# replica's randomness comes from its own seed, so this constant changes no result.
BASE_SEED = 0


@dataclass
class Replica:
    """One independent ego of a packed algorithm: its setup, the weights it starts from (base module ID -> folder), its seed."""

    setup: EgoSetup
    load: dict[str, str] = field(default_factory=dict)
    seed: int | None = None

    @property
    def own_seed(self) -> int:
        """The seed of everything random in this replica (default: its experiment's seed)."""
        return self.setup.exp.seed if self.seed is None else int(self.seed)


# What replicas of one algorithm share: they differ in seed, partners, starting weights and the loss weights below only.
PACKED_KEYS = ("method", "freeze", "z_lr_scale", "model", "ppo", "run", "maml", "mapping")
# Loss weights the learner takes per replica (`LearnerSettings`): a lambda sweep's egos train in one algorithm.
REPLICA_WEIGHTS = ("lam", "head_l2")


def packing_key(setup: EgoSetup) -> str:
    """A key equal for exactly the setups that can be replicas of one algorithm (game, env config, settings, seats, partner count)."""
    exp = setup.exp
    shared = {k: getattr(exp, k) for k in PACKED_KEYS}
    parts = (
        setup.population.env,
        setup.env_config,
        {k: v.model_dump() if hasattr(v, "model_dump") else v for k, v in shared.items()},
    )
    fixed = setup.team is not None  # one team per replica (`partner_schedule.FixedTeam`) or every team
    return json.dumps([*parts, setup.ego_agent, setup.partner_agents, len(setup.train), fixed], sort_keys=True, default=str)


def _check_packable(replicas: list[Replica]) -> None:
    """Replicas share one env and one learner config: the same game, env config, method, sizes, PPO and learner settings."""
    if not replicas:
        raise ValueError("an algorithm needs at least one replica")
    first = replicas[0].setup
    for rep in replicas[1:]:
        s = rep.setup
        if packing_key(s) != packing_key(first):
            differs = [k for k in PACKED_KEYS if getattr(s.exp, k) != getattr(first.exp, k)]
            if s.population.env != first.population.env or s.env_config != first.env_config:
                differs.append("game")
            if len(s.train) != len(first.train) or (s.ego_agent, s.partner_agents) != (first.ego_agent, first.partner_agents):
                differs.append("partner count or seats")
            raise ValueError(
                f"replicas must differ in seed, partners, weights, {' and '.join(REPLICA_WEIGHTS)} only; "
                f"replica {rep.own_seed} differs in {differs}"
            )


def module_specs(setup: EgoSetup, load: dict[str, str] | None = None, seed: int | None = None) -> dict[str, RLModuleSpec]:
    """Return the RLModuleSpecs of one plain ego (`ConventionMultiRLModule`): task module, ego heads, fixed partners.

    The layout of an exported trained ego. `load` maps module IDs to module checkpoint
    folders whose weights they start from; with `seed` every module's randomness (initial
    weights, a stochastic partner) comes from that seed, as in a packed algorithm.
    """
    exp = setup.exp
    ego_obs, ego_act, p_obs, p_act = _spaces(setup)
    task_config, head_config = _module_configs(setup)
    if setup.seat_heads:  # each team head is saved as the sum of its seats' heads: one head as wide as all of them
        head_config = {**head_config, "hidden": head_config["hidden"] * len(setup.partner_agents)}
        head_config["z_dim"] = task_config["z_dim"] or task_config["hidden"]
    seeded = lambda mid: {} if seed is None else {"init_seed": stream_seed(seed, mid)}  # noqa: E731
    specs = {
        TASK_ID: RLModuleSpec(
            module_class=TaskModule,
            observation_space=ego_obs,
            action_space=ego_act,
            model_config={**task_config, **seeded(TASK_ID)},
        )
    }
    for mid in setup.head_ids:
        specs[mid] = RLModuleSpec(
            module_class=PartnerHeadModule,
            observation_space=ego_obs,
            action_space=ego_act,
            model_config={**head_config, **seeded(mid)},
        )
    specs.update(_partner_specs(setup, p_obs, p_act, exp.seed if seed is None else seed, replica=None, seeded=seed is not None))
    for mid, path in (load or {}).items():
        specs[mid].load_state_path = str(path)
    return specs


def seat_head_specs(setup: EgoSetup) -> dict[str, RLModuleSpec]:
    """The RLModuleSpecs of a seat-head ego's weight heads (`EgoSetup.weight_heads`), each a plain head as in team mode."""
    ego_obs, ego_act, _, _ = _spaces(setup)
    _, head_config = _module_configs(setup)
    return {
        mid: RLModuleSpec(
            module_class=PartnerHeadModule, observation_space=ego_obs, action_space=ego_act, model_config=head_config
        )
        for mid in setup.weight_heads
    }


def _spaces(setup: EgoSetup) -> tuple:
    """The ego's and the partner's observation and action spaces, as the RLlib adapter gives them."""
    env = PettingZooMultiAgentEnv(envs.make(setup.population.env, **setup.env_config))
    return (
        env.observation_spaces[setup.ego_agent],
        env.action_spaces[setup.ego_agent],
        env.observation_spaces[setup.partner_agent],
        env.action_spaces[setup.partner_agent],
    )


def _module_configs(setup: EgoSetup) -> tuple[dict, dict]:
    """The model configs of the ego's task module and heads (sizes, the oracle, whether task logits are used)."""
    exp = setup.exp
    sizes = {"hidden": exp.model.hidden, "z_dim": exp.model.z_dim}
    task_config = dict(sizes)
    if method(exp.method).task_logits == "oracle":
        task_config["oracle"] = {"env": setup.population.env, "env_config": setup.env_config}
    return task_config, {**sizes, "use_task_logits": method(exp.method).task_logits != "unused"}


def _partner_specs(
    setup: EgoSetup, obs_space: Any, act_space: Any, seed: int, replica: int | None, seeded: bool
) -> dict[str, RLModuleSpec]:
    """The fixed partners' specs; a stochastic partner's RNG seeded from `seed` (per module when `seeded`)."""
    specs = {}
    for i, entry in enumerate(setup.train):
        mid = partner_id(entry.name)
        spec = {"name": entry.name, "kind": entry.kind, "params": entry.params}
        module_seed = stream_seed(seed, mid) if seeded else partner_seed(seed, i)
        specs[replica_id(mid, replica)] = RLModuleSpec(
            module_class=FixedPartnerModule,
            observation_space=obs_space,
            action_space=act_space,
            model_config={"partner": spec, "seed": module_seed},
        )
    return specs


def stacked_specs(replicas: list[Replica]) -> dict[str, RLModuleSpec]:
    """The specs of a `StackedEgoMultiRLModule`: the `EgoStack` of every replica, a `HeadView` per head, the fixed partners."""
    first = replicas[0].setup
    ego_obs, ego_act, p_obs, p_act = _spaces(first)
    task_config, head_config = _module_configs(first)
    stack_config = {
        "replicas": len(replicas),
        "heads": len(first.head_ids),
        "head_members": first.head_members,
        "task": task_config,
        "head": head_config,
        # The seeds a replica's plain modules get (`module_specs(seed=...)`): it starts as it would alone.
        "task_seeds": [stream_seed(rep.own_seed, TASK_ID) for rep in replicas],
        "head_seeds": [[stream_seed(rep.own_seed, mid) for mid in rep.setup.weight_heads] for rep in replicas],
        "sample_seeds": [sampling_seed(rep.own_seed) for rep in replicas],
        # A game that can list its ego's every state has few distinct ones: heads run once per distinct observation.
        "few_situations": envs.game(first.population.env).states is not None,
    }
    specs = {
        STACK_ID: RLModuleSpec(module_class=EgoStack, observation_space=ego_obs, action_space=ego_act, model_config=stack_config)
    }
    for r, rep in enumerate(replicas):
        for h, mid in enumerate(rep.setup.head_ids):
            specs[replica_id(mid, r)] = RLModuleSpec(
                module_class=HeadView, observation_space=ego_obs, action_space=ego_act, model_config={"replica": r, "head": h}
            )
        specs.update(_partner_specs(rep.setup, p_obs, p_act, rep.own_seed, replica=r, seeded=True))
    return specs


def base_ppo_config(
    env_class: type, env_config: dict, ppo: PPOSettings, run: RunSettings, seed: int, batch_size: int
) -> PPOConfig:
    """The PPOConfig pieces shared by ego and self-play training (env, runners, learner, PPO).

    `env_class` and `env_config` are the RLlib env: `ReplicatedGame` for egos, `RLlibGame`
    for self-play pairs (their configs come from `replicated_env_config` / `game_env_config`);
    `BatchedEnvRunner` samples it.
    """
    return (
        PPOConfig()
        .environment(
            env_class,
            env_config=env_config,
            # RLlib's checker steps the env with unmasked random actions, which our games
            # rightly reject as illegal; the games are tested with PettingZoo's own checks.
            disable_env_checking=True,
        )
        .env_runners(
            # Samples without RLlib's episode objects, the same train batches (`tests/training/test_batched_env_runner.py`).
            env_runner_cls=BatchedEnvRunner,
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


def partner_schedule(mapping: MappingSettings, seeds: list[int]) -> Any:
    """The `partner_schedule` of an experiment's `mapping` settings, one generator per replica seeded from `seeds`."""
    if mapping.kind == "weighted":
        return WeightedPartners(mapping.weights or {}, seeds)
    if mapping.kind == "function":
        return PartnerFunction(mapping.function or "", seeds)
    return RoundRobin()


def build_ppo_config(setup: EgoSetup | list[Replica], load: dict[str, str] | None = None) -> PPOConfig:
    """Return the PPOConfig training one ego (`setup`, starting weights from `load`) or several packed `Replica`s.

    Each replica is one copy of the game in a `ReplicatedGame`, with its own modules and
    seeds (see the module docstring); a single setup is one replica with its experiment's seed.
    """
    replicas = [Replica(setup, dict(load or {}))] if isinstance(setup, EgoSetup) else list(setup)
    _check_packable(replicas)
    first = replicas[0].setup
    exp, ppo = first.exp, first.exp.ppo
    specs = stacked_specs(replicas)
    mapping = PartnerMapping(
        [e.name for e in first.train],
        first.ego_agent,
        first.partner_agents,
        shared_head=method(exp.method).single_head,
        replica_partners=[[e.name for e in rep.setup.train] for rep in replicas],
        schedule=FixedTeam([rep.setup.team for rep in replicas])
        if first.team is not None
        else partner_schedule(exp.mapping, [stream_seed(rep.own_seed, "mapping") for rep in replicas]),
    )
    trained = [STACK_ID, *(replica_id(mid, r) for r, rep in enumerate(replicas) for mid in rep.setup.head_ids)]
    settings = replace(exp.learner_settings(), **replica_weight_settings(replicas))
    shuffle_seeds = {
        replica_id(mid, r): shuffle_seed(rep.own_seed, mid) for r, rep in enumerate(replicas) for mid in rep.setup.head_ids
    }
    batch = ppo.rollout_per_partner * len(first.teams)  # per partner, or per team of partners where there are several seats
    env_config = replicated_env_config(first.population.env, first.env_config, [rep.own_seed for rep in replicas], BASE_SEED)
    config = base_ppo_config(ReplicatedGame, env_config, ppo, exp.run, BASE_SEED, batch)
    return (
        config.multi_agent(
            # A list, not a set: module build order must not depend on string hashing,
            # which differs per process (Tune runs each trial in its own).
            policies=list(specs),
            policy_mapping_fn=mapping,
            policies_to_train=trained,
        )
        .rl_module(rl_module_spec=MultiRLModuleSpec(multi_rl_module_class=StackedEgoMultiRLModule, rl_module_specs=specs))
        .learners(
            learner_class=MarginalPPOLearner, learner_config_dict={**settings.config_dict(), "shuffle_seeds": shuffle_seeds}
        )
    )


def replica_weight_settings(replicas: list[Replica]) -> dict[str, float | tuple[float, ...]]:
    """The learner's loss weights (`REPLICA_WEIGHTS`): one float where every replica has the same, else one per replica."""
    out = {}
    for key in REPLICA_WEIGHTS:
        values = tuple(float(getattr(rep.setup.exp, key)) for rep in replicas)
        out[key] = values[0] if len(set(values)) == 1 else values
    return out


def load_replica_weights(algo: Any, replicas: list[Replica]) -> None:
    """Write each replica's starting weights (`Replica.load`: module ID -> plain module checkpoint) into the stack; sync env runners.

    `task` loads a replica's task module; a head ID (`ego@p`, `ego`) loads that head, a seat head's
    (`ego@<seat>=<partner>`, `EgoSetup.weight_heads`) that seat head.
    """
    if not any(rep.load for rep in replicas):
        return
    states = {(r, mid): load_rl_module(path).state_dict() for r, rep in enumerate(replicas) for mid, path in rep.load.items()}

    def load(learner: Any) -> None:
        stack = learner.module[STACK_ID]
        for (r, mid), state in states.items():
            if mid == TASK_ID:
                stack.load_task(r, state)
            elif mid in replicas[r].setup.head_ids:
                stack.load_head(r, replicas[r].setup.head_ids.index(mid), state)
            else:
                stack.load_weight_head(r, replicas[r].setup.weight_heads.index(mid), state)

    algo.learner_group.foreach_learner(load)
    push_learner_weights(algo)


def build_algorithm(replicas: list[Replica]) -> Any:
    """The built RLlib algorithm of `replicas`, each starting from its `load` weights."""
    algo = build_ppo_config(replicas).build_algo()
    load_replica_weights(algo, replicas)
    return algo
