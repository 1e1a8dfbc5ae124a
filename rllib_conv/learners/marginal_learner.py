"""`MarginalPPOLearner`: PPO plus the paper's marginal regulariser, with freezing that freezes.

The paper's loss, per ego: PPO's loss on every head's own rows (`ppo_loss`), plus
`lam * D` (`regulariser.marginal_distance`): D over the states of all the ego's heads' rows
(PPO's bootstrap padding rows are dropped by `DropBootstrapRows` before minibatching), over
all its heads i (one per training partner), with no gradient stopped. `lam = 0` (for every replica) leaves
PPO's loss untouched: each head then runs on its own rows only, and D is still logged,
computed without gradients on each update's last minibatch.

The ego trains packed: a `StackedEgoMultiRLModule` of K independent replicas (seeds) whose
weights live in one `EgoStack`; the loss adds `sum_r lam_r * D_r`, and each D_r reaches only
replica r's weights, so the replicas train as K separate learners would. How the update
runs (one fused minibatch loop for every replica and head) is `FusedUpdateLearner`'s
business (`rllib_conv.learners.packed`); this file is what the paper trains.

Settings come from `config.learners(learner_config_dict=...)`, the fields of
`LearnerSettings` (whose defaults are the only ones):

- `lam` (float, default 0): the regulariser weight; a list gives each replica its own (replicas of several
  experiments, e.g. a lambda sweep, packed in one algorithm).
- `freeze` (list): the groups `"task"` and `"heads"`, whose weights must not change:
  their parameters get `requires_grad=False` and no optimizer.
- `adam_eps` (float, default 1e-5, the paper's code): Adam's epsilon.
- `z_lr_scale` (float, default 1): the task module's z layers (its policy tower) learn at
  `lr * z_lr_scale` through an optimizer of their own; 0 freezes them.
- `shuffle_seeds` (module ID -> seed): each module's own minibatch-shuffling generator.
- `head_l2` (float or a list per replica, default 0; not in the paper): weight of the head penalty H
  (`head_penalty.head_size`) on every ego head's own output. H is always logged.
- `population_entropy` (float alpha, default 0; not in the paper) and `populations` (name ->
  module IDs): MEP's bonus for plain modules (self-play seats of several pairs trained
  together): `- alpha * PE` per population, PE the entropy of the members' mean policy
  (`population_entropy.population_entropy`) on every member's rows of the minibatch. PE is
  always logged, as `population_entropy/<name>`.
- `trajectory_diversity` (float beta, default 0; not in the paper) and `trajectory_discount`
  (gamma, default 0.5): TrajeDi's term for the same populations, `- beta * JSD`, JSD the
  Jensen-Shannon divergence of the members' (discounted local) trajectory distributions
  (`trajectory_diversity`): each member's per-move weights w are computed once per update on
  its whole episodes (`plain_episode_columns`) and `beta * w` (times the member's row count)
  is added to its moves' advantages, after PPO standardized them, so PPO's clipped surrogate
  carries it (beta is in units of a standardized advantage). The JSD estimate is always
  logged, once per update, as `trajectory_diversity/<name>` (on `Rollout` batches, the
  batched sampler's).

Optimizers: the stack has one Adam per group (task, the task's z layers when scaled, heads);
gradients are clipped per replica (task) and per replica head, as each would be alone.
Other modules (self-play seats, plain RLlib modules) get RLlib's usual optimizer per module.
"""

from __future__ import annotations

from functools import cached_property
from typing import Any

import torch
from ray.rllib.core import ALL_MODULES
from ray.rllib.core.columns import Columns
from ray.rllib.evaluation.postprocessing import Postprocessing

from rllib_conv.learners.head_penalty import head_size
from rllib_conv.learners.packed.fused_update import HEADS_OPTIMIZER, TASK_OPTIMIZER, Z_OPTIMIZER, FusedUpdateLearner
from rllib_conv.learners.population_entropy import population_entropy
from rllib_conv.learners.ppo_loss import categorical_logp_entropy
from rllib_conv.learners.regulariser import marginal_distance
from rllib_conv.learners.settings import replica_weights
from rllib_conv.learners.trajectory_diversity import trajectory_diversity
from rllib_conv.modules.packed.stacked_multi import STACK_ID, HeadView, StackedOutput

MARGINAL_REG_KEY = "marginal_reg"
HEAD_L2_KEY = "head_l2"
POPULATION_ENTROPY_KEY = "population_entropy"
TRAJECTORY_DIVERSITY_KEY = "trajectory_diversity"


def _cat_obs(parts: list) -> object:
    """Observations of several modules' rows as one batch (tensors, or dicts of them: our games' masked observations)."""
    if isinstance(parts[0], dict):
        return {key: torch.cat([p[key] for p in parts]) for key in parts[0]}
    return torch.cat(parts)


class MarginalPPOLearner(FusedUpdateLearner):
    """PPO learner for `StackedEgoMultiRLModule`s: the regulariser, the head penalty, real freezing, Adam eps."""

    @cached_property
    def lam(self) -> torch.Tensor:
        """The regulariser weight of every replica ([K]; replicas of a lambda sweep packed together differ)."""
        return self._replica_weights(self.settings.lam)

    @cached_property
    def head_l2(self) -> torch.Tensor:
        """The head penalty's weight of every replica ([K])."""
        return self._replica_weights(self.settings.head_l2)

    def _replica_weights(self, weight: float | list[float]) -> torch.Tensor:
        replicas = self.module[STACK_ID].replicas if STACK_ID in self.module else 1
        return torch.tensor(replica_weights(weight, replicas), dtype=torch.float32, device=self._device)

    @cached_property
    def _weighted(self) -> tuple[bool, bool]:
        """Whether any replica weights D, and H."""
        return bool((self.lam > 0).any()), bool((self.head_l2 > 0).any())

    # --- the regulariser and the head penalty -----------------------------------------------------------

    def stack_terms(self, stacked: StackedOutput) -> dict[str, torch.Tensor]:
        """Per replica: D_r and H_r ([K] each) of one minibatch, each with a gradient only when weighted."""
        rows = stacked.row_weights
        lam, head_l2 = self._weighted
        with torch.set_grad_enabled(lam and torch.is_grad_enabled()):
            reg = marginal_distance(stacked.task_logits, stacked.all_logits, rows)
        with torch.set_grad_enabled(head_l2 and torch.is_grad_enabled()):
            size = head_size(stacked.head_out, rows)
        return {MARGINAL_REG_KEY: reg, HEAD_L2_KEY: size}

    @property
    def loss_reads_all_heads(self) -> bool:
        """D and H read every head on every row: needed in the loss only when some replica weights them."""
        return any(self._weighted)

    def stack_loss(self, terms: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """sum_r lam_r * D_r and sum_r head_l2_r * H_r, those some replica weights (a replica's terms reach only its own
        weights; a replica of weight 0 gets a gradient of 0 from them)."""
        loss = {}
        for key, weights, on in zip((MARGINAL_REG_KEY, HEAD_L2_KEY), (self.lam, self.head_l2), self._weighted):
            if on:
                loss[key] = (weights * terms[key]).sum()
        return loss

    # --- MEP's population entropy and TrajeDi's trajectory diversity (plain modules) -----------------------

    @property
    def alpha(self) -> float:
        """The population entropy's weight."""
        return float(self.settings.population_entropy)

    @property
    def beta(self) -> float:
        """The trajectory diversity's weight."""
        return float(self.settings.trajectory_diversity)

    def plain_episode_columns(self, data: dict[str, dict], lengths: dict[str, list[int]] | None) -> dict[str, dict]:
        """Each population's JSD on the update's episodes (logged) and, when weighted, every member's advantages plus
        beta times its per-move weights (times its row count: PPO's loss is a mean over rows)."""
        populations = {name: ids for name, ids in self.settings.populations.items() if all(mid in data for mid in ids)}
        if lengths is None:
            if self.beta > 0 and populations:
                raise ValueError(
                    "trajectory_diversity needs the batched sampler's Rollouts (episode structure); got RLlib episodes"
                )
            return {}
        columns: dict[str, dict] = {}
        with torch.no_grad():
            for name, members in populations.items():
                logp = []
                for own in members:
                    obs = {Columns.OBS: data[own][Columns.OBS]}
                    actions = data[own][Columns.ACTIONS]
                    logits = [self.module[mid].forward_train(obs)[Columns.ACTION_DIST_INPUTS] for mid in members]
                    logp.append(torch.stack([categorical_logp_entropy(x, actions)[0] for x in logits]))
                td = trajectory_diversity(logp, [lengths[mid] for mid in members], self.settings.trajectory_discount)
                self.metrics.log_value((ALL_MODULES, f"{TRAJECTORY_DIVERSITY_KEY}/{name}"), td.value, reduce="mean")
                if self.beta > 0:
                    for mid, w in zip(members, td.weights):
                        advantages = data[mid][Postprocessing.ADVANTAGES]
                        columns[mid] = {Postprocessing.ADVANTAGES: advantages + self.beta * len(w) * w.to(advantages.dtype)}
        return columns

    def plain_terms(self, minibatch: dict[str, dict]) -> dict[str, torch.Tensor]:
        """PE of each population on this minibatch: every member's policy on all the members' rows (with gradient when weighted)."""
        terms = {}
        with torch.set_grad_enabled(self.alpha > 0 and torch.is_grad_enabled()):
            for name, members in self.settings.populations.items():
                present = [mid for mid in members if mid in minibatch]
                if not present:
                    continue
                obs = {Columns.OBS: _cat_obs([minibatch[mid][Columns.OBS] for mid in present])}
                logits = torch.stack([self.module[mid].forward_train(obs)[Columns.ACTION_DIST_INPUTS] for mid in members])
                terms[f"{POPULATION_ENTROPY_KEY}/{name}"] = population_entropy(logits)
        return terms

    def plain_loss(self, terms: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """- alpha * sum of every population's PE (a bonus: higher entropy of the mean policy, lower loss)."""
        return {POPULATION_ENTROPY_KEY: -self.alpha * sum(terms.values())} if self.alpha > 0 and terms else {}

    @property
    def loss_reads_plain_terms(self) -> bool:
        """PE enters the loss only when weighted."""
        return self.alpha > 0

    # --- optimizers and freezing ---------------------------------------------------------------------

    def configure_optimizers_for_module(self, module_id: str, config: Any = None) -> None:
        module = self.module[module_id]
        if isinstance(module, HeadView):
            return  # a view: its weights are the stack's
        if module_id != STACK_ID:
            return super().configure_optimizers_for_module(module_id, config)
        frozen = set(self.settings.freeze)
        unknown = frozen - {"task", "heads"}
        if unknown:
            raise ValueError(f"freeze: {sorted(unknown)} are not freezable groups; a packed ego freezes 'task' and/or 'heads'")
        scale = float(self.settings.z_lr_scale)
        z_params = module.task_parameters(z_only=True) if scale != 1.0 else []
        z_ids = {id(p) for p in z_params}
        groups = {
            TASK_OPTIMIZER: ([p for p in module.task_parameters() if id(p) not in z_ids], config.lr, "task" in frozen),
            Z_OPTIMIZER: (z_params, config.lr * scale, "task" in frozen or scale == 0.0),
            HEADS_OPTIMIZER: (module.head_parameters(), config.lr, "heads" in frozen),
        }
        for name, (params, lr, freeze) in groups.items():
            if freeze:
                for p in params:
                    p.requires_grad_(False)
            elif params:
                # Adam is invariant to the gradient's scale: a slower z needs a learning rate of its own.
                self.register_optimizer(
                    module_id=module_id,
                    optimizer_name=name,
                    optimizer=torch.optim.Adam(params, eps=float(self.settings.adam_eps), foreach=True),
                    params=params,
                    lr_or_lr_schedule=lr,
                )
