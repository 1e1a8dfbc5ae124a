"""`MarginalPPOLearner`: PPO plus the paper's marginal regulariser, with freezing that freezes, over packed replicas.

The ego is a `StackedEgoMultiRLModule`: K independent replica egos whose weights live in
one `EgoStack`. Per minibatch and per replica r, over the states of its ego heads' rows
(PPO's bootstrap padding rows are dropped by `DropBootstrapRows` before minibatching),
the regulariser is

    D_r = mean_s sum_a | softmax(task_r logits)(a|s) - mean_i softmax(task_r + head_ri logits)(a|s) |

over all of replica r's heads i (one per training partner), with no gradient stopping. The
loss adds `lam * sum_r D_r`; each D_r reaches only replica r's weights, so the replicas
train as K separate learners would. `lam = 0` leaves PPO's loss untouched (D is still
logged, computed without gradients). Settings come from `config.learners(learner_config_dict=...)`,
the fields of `LearnerSettings` (whose defaults are the only ones):

- `lam` (float, default 0): the regulariser weight.
- `freeze` (list): the groups `"task"` and `"heads"`, whose weights must not change:
  their parameters get `requires_grad=False` and no optimizer.
- `adam_eps` (float, default 1e-5, the paper's code): Adam's epsilon.
- `z_lr_scale` (float, default 1): the task module's z layers (its policy tower) learn at
  `lr * z_lr_scale` through an optimizer of their own; 0 freezes them.
- `fused_update` (bool, default True): run the learner's own minibatch loop (see
  `MarginalPPOLearner.update`) instead of RLlib's; same arithmetic, a fraction of the cost.
- `shuffle_seeds` (module ID -> seed): each module's own minibatch-shuffling generator.
- `head_l2` (float, default 0; not in the paper): weight of the head penalty

      H_r = mean_{i,s} sum_a (h_ri(a|s) - mean_b h_ri(b|s))^2

  on every ego head's own output h_ri (before the task logits are added; centred, since
  a constant shift leaves the policy unchanged; illegal actions count too, their outputs
  never reach the policy). Where the task module alone already
  plays the partners' common response (the rules), PPO leaves heads and task module
  free to split the logits any way; H makes the task module carry them, so a head
  holds only what differs between partners (the conventions), and a frozen head stays
  out of the way when the task module is re-trained on a new task. H is always logged.

Optimizers: the stack has one Adam per group (task, the task's z layers when scaled, heads);
gradients are clipped per replica (task) and per replica head, as each would be alone.
Other modules (self-play seats, plain RLlib modules) get RLlib's usual optimizer per module.
"""

from __future__ import annotations

from functools import cached_property
from typing import Any

import torch
from ray.rllib.algorithms.ppo.torch.ppo_torch_learner import PPOTorchLearner
from ray.rllib.core import ALL_MODULES
from ray.rllib.core.columns import Columns
from ray.rllib.core.learner.learner import DEFAULT_OPTIMIZER, ENTROPY_KEY, POLICY_LOSS_KEY, VF_LOSS_KEY
from ray.rllib.core.learner.training_data import TrainingData
from ray.rllib.evaluation.postprocessing import Postprocessing

from rllib_conv.learners.drop_bootstrap_rows import DropBootstrapRows
from rllib_conv.learners.fused_step import FusedAdamStep, clip_segments
from rllib_conv.learners.minibatches import CyclicMinibatchPlan, ModulePermuters, global_permute
from rllib_conv.learners.ppo_loss import PPOLossTerms, ppo_loss
from rllib_conv.learners.rollout import Rollout, rollout_train_batch
from rllib_conv.learners.settings import LearnerSettings
from rllib_conv.modules.multi import TASK_ID, replica_id
from rllib_conv.modules.stacked_multi import STACK_ID, STACKED, HeadView, StackedEgoMultiRLModule, StackedOutput

MARGINAL_REG_KEY = "marginal_reg"
HEAD_L2_KEY = "head_l2"
# The batch columns the losses read (the rest stays out of every minibatch copy).
TRAIN_COLUMNS = (Columns.OBS, Columns.ACTIONS, Columns.ACTION_LOGP, Postprocessing.ADVANTAGES, Postprocessing.VALUE_TARGETS)
# The stack's optimizers and how many leading dims of their tensors are independent replicas (clip segments).
TASK_OPTIMIZER, Z_OPTIMIZER, HEADS_OPTIMIZER = DEFAULT_OPTIMIZER, "z", "heads"
SEGMENT_DIMS = {TASK_OPTIMIZER: 1, Z_OPTIMIZER: 1, HEADS_OPTIMIZER: 2}


def _segment_dims(module_id: str, optimizer_name: str) -> int:
    """The clip segments of an optimizer (RLlib names optimizers `<module ID>_<name>`): replicas for the stack's, none else."""
    return SEGMENT_DIMS[optimizer_name.removeprefix(f"{module_id}_")] if module_id == STACK_ID else 0


def _take(data: Any, rows: torch.Tensor) -> Any:
    """`data` (a tensor or a dict of them, e.g. Dict observations) at `rows`."""
    return {k: _take(v, rows) for k, v in data.items()} if isinstance(data, dict) else data.index_select(0, rows)


def _masked_mean(x: torch.Tensor, valid: torch.Tensor, dims: int) -> torch.Tensor:
    """The mean of `x` over its last `dims` dims, counting only `valid` entries (same shape as those dims)."""
    axes = tuple(range(-dims, 0))
    return (x * valid).sum(axes) / valid.sum(axes).clamp(min=1)


def marginal_distance(task_logits: torch.Tensor, head_logits: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
    """Mean over rows of sum_a |softmax(task) - mean_i softmax(head_i)| per replica.

    `task_logits` [..., N, A], `head_logits` [..., H, N, A], `valid` [..., N] (default all rows): returns [...].
    """
    mean_policy = torch.softmax(head_logits, dim=-1).mean(dim=-3)
    per_row = (torch.softmax(task_logits, dim=-1) - mean_policy).abs().sum(dim=-1)
    return per_row.mean(-1) if valid is None else _masked_mean(per_row, valid.to(per_row.dtype), 1)


def head_size(head_outputs: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
    """Mean over heads and rows of sum_a (h(a) - mean_b h(b))^2: head outputs [..., H, N, A], `valid` [..., N] -> [...]."""
    centred = head_outputs - head_outputs.mean(dim=-1, keepdim=True)
    per_row = centred.pow(2).sum(dim=-1)  # [..., H, N]
    if valid is None:
        return per_row.mean((-2, -1))
    return _masked_mean(per_row, valid.unsqueeze(-2).expand_as(per_row).to(per_row.dtype), 2)


class MarginalPPOLearner(PPOTorchLearner):
    """PPO learner for `StackedEgoMultiRLModule`s: regulariser, real freezing, Adam eps, the fused minibatch loop."""

    def build(self) -> None:
        super().build()
        # After PPO's GAE piece: advantages need the bootstrap rows, the losses do not.
        if self._learner_connector is not None:
            self._learner_connector.append(DropBootstrapRows())

    @cached_property
    def settings(self) -> LearnerSettings:
        """The regulariser, head penalty, freezing and Adam settings from `learner_config_dict`."""
        cfg = dict(self.config.learner_config_dict)
        return LearnerSettings(**{**cfg, "freeze": tuple(cfg.get("freeze", ()))})

    @cached_property
    def permuters(self) -> ModulePermuters:
        """The per-module shuffling generators (`shuffle_seeds`); their states are saved with checkpoints."""
        return ModulePermuters(self.settings.shuffle_seeds)

    def _permute(self, module_id: str, n: int) -> Any:
        """A permutation of `n` rows for `module_id`: from its own generator if it has one, else NumPy's global RNG."""
        return self.permuters(module_id, n) if module_id in self.settings.shuffle_seeds else global_permute(module_id, n)

    @property
    def lam(self) -> float:
        """The regulariser weight."""
        return float(self.settings.lam)

    @property
    def head_l2(self) -> float:
        """The head penalty's weight."""
        return float(self.settings.head_l2)

    @property
    def stacked(self) -> bool:
        """Whether the module is a stack of replica egos (else plain RLlib modules, e.g. self-play seats)."""
        return isinstance(self.module, StackedEgoMultiRLModule)

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

    def postprocess_gradients_for_module(self, *, module_id: str, config: Any = None, module_gradients_dict: dict) -> dict:
        if module_id != STACK_ID:
            return super().postprocess_gradients_for_module(module_id=module_id, config=config, module_gradients_dict=module_gradients_dict)
        # RLlib's own loop: clip each replica's (and each replica head's) gradients apart.
        for name, optimizer in self.get_optimizers_for_module(module_id):
            grads = list(self.filter_param_dict_for_optimizer(module_gradients_dict, optimizer).values())
            clip_segments([g for g in grads if g is not None], _segment_dims(module_id, name), config.grad_clip)
        return module_gradients_dict

    # --- the regulariser and the head penalty -----------------------------------------------------------

    def _shared_terms(self, stacked: StackedOutput) -> tuple[torch.Tensor, torch.Tensor]:
        """Per replica: D_r and H_r ([K] each) of one minibatch, each with a gradient only when weighted."""
        k, h, b = stacked.valid.shape
        rows = stacked.valid.reshape(k, h * b)
        with torch.set_grad_enabled(self.lam > 0 and torch.is_grad_enabled()):
            reg = marginal_distance(stacked.task_logits, stacked.all_logits, rows)
        with torch.set_grad_enabled(self.head_l2 > 0 and torch.is_grad_enabled()):
            size = head_size(stacked.head_out, rows)
        return reg, size

    def _weighted(self, reg: torch.Tensor, size: torch.Tensor) -> dict[str, torch.Tensor]:
        """The loss terms lam * sum_r D_r and head_l2 * sum_r H_r, those with a weight (a replica's terms reach only its own weights)."""
        terms = {}
        if self.lam > 0:
            terms[MARGINAL_REG_KEY] = self.lam * reg.sum()
        if self.head_l2 > 0:
            terms[HEAD_L2_KEY] = self.head_l2 * size.sum()
        return terms

    def _log_shared(self, reg: torch.Tensor, size: torch.Tensor) -> None:
        """Log D_r and H_r under each replica's `task#r` key and their mean over replicas under ALL_MODULES."""
        for r in range(len(reg)):
            self.metrics.log_value((replica_id(TASK_ID, r), MARGINAL_REG_KEY), reg[r], reduce="mean")
            self.metrics.log_value((replica_id(TASK_ID, r), HEAD_L2_KEY), size[r], reduce="mean")
        self.metrics.log_value((ALL_MODULES, MARGINAL_REG_KEY), reg.mean(), reduce="mean")
        self.metrics.log_value((ALL_MODULES, HEAD_L2_KEY), size.mean(), reduce="mean")

    def compute_losses(self, *, fwd_out: dict[str, Any], batch: dict[str, Any]) -> dict[str, Any]:
        shared = fwd_out.pop(STACK_ID, None)  # the stack has no batch and no PPO loss of its own
        losses = super().compute_losses(fwd_out=fwd_out, batch=batch)
        if shared is not None:
            reg, size = self._shared_terms(shared[STACKED])
            self._log_shared(reg.detach(), size.detach())
            losses.update(self._weighted(reg, size))  # summed into the loss like any other term
        return losses

    # --- the learner's own minibatch loop ---------------------------------------------------------

    def _make_batch_if_necessary(self, training_data: TrainingData) -> Any:
        """The train batch: from `Rollout`s (the batched sampler's) with RLlib's arithmetic, else RLlib's learner connector."""
        episodes = training_data.episodes
        if not episodes or not any(isinstance(e, Rollout) for e in episodes):
            return super()._make_batch_if_necessary(training_data)
        if not all(isinstance(e, Rollout) for e in episodes):
            raise TypeError("a train batch mixes Rollouts and RLlib episodes: every env runner of an algorithm must sample the same way")
        return rollout_train_batch(episodes, self.module, self.config.gamma, self.config.lambda_)


    def update(
        self,
        batch: Any = None,
        batches: Any = None,
        batch_refs: Any = None,
        episodes: Any = None,
        episodes_refs: Any = None,
        data_iterators: Any = None,
        training_data: TrainingData | None = None,
        *,
        timesteps: dict[str, Any] | None = None,
        num_total_minibatches: int = 0,
        num_epochs: int = 1,
        minibatch_size: int | None = None,
        shuffle_batch_per_epoch: bool = False,
        _no_metrics_reduce: bool = False,
        **kwargs: Any,
    ) -> Any:
        """One PPO update over `num_epochs` epochs of minibatches, with the same arithmetic as RLlib's `Learner.update`.

        RLlib's loop copies every minibatch into a new `MultiAgentBatch`, logs a dozen
        metrics per module per minibatch and steps each optimizer separately; on our small
        networks that bookkeeping is nearly all of the time. Here the train batch is built
        by the same learner connector, its tensors are sliced by `CyclicMinibatchPlan`
        (RLlib's minibatch order and shuffles), the loss is `ppo_loss` plus the
        regulariser (on a stacked ego: every replica and head at once), and one
        `FusedAdamStep` clips and steps every optimizer. Metrics are logged once per
        update. With `fused_update: false` RLlib's own loop runs instead.
        """
        if not self.settings.fused_update or data_iterators is not None or num_total_minibatches:
            return super().update(
                batch, batches, batch_refs, episodes, episodes_refs, data_iterators, training_data,
                timesteps=timesteps, num_total_minibatches=num_total_minibatches, num_epochs=num_epochs,
                minibatch_size=minibatch_size, shuffle_batch_per_epoch=shuffle_batch_per_epoch,
                _no_metrics_reduce=_no_metrics_reduce, **kwargs,
            )
        self._check_is_built()
        self.before_gradient_based_update(timesteps=timesteps or {})
        if training_data is None:
            training_data = TrainingData(batch=batch, batches=batches, batch_refs=batch_refs, episodes=episodes, episodes_refs=episodes_refs)
        training_data.validate()
        training_data.solve_refs()
        self._weights_seq_no += 1
        train_batch = self._make_batch_if_necessary(training_data=training_data)
        for module_id in list(train_batch.policy_batches):
            if not self.should_module_be_updated(module_id, train_batch):
                del train_batch.policy_batches[module_id]
        if train_batch.policy_batches:
            data = {mid: {c: b[c] for c in TRAIN_COLUMNS} for mid, b in train_batch.policy_batches.items()}
            sizes = {mid: len(b) for mid, b in train_batch.policy_batches.items()}
            shuffle = shuffle_batch_per_epoch and num_epochs > 1
            plan = CyclicMinibatchPlan(sizes, minibatch_size or max(sizes.values()), num_epochs, shuffle, self._permute)
            (self._stacked_epochs if self.stacked else self._plain_epochs)(data, plan)
            self._log_steps_trained_metrics(train_batch)
        self.after_gradient_based_update(timesteps=timesteps or {})
        return None if _no_metrics_reduce else self.metrics.reduce()

    def _fused_step(self) -> FusedAdamStep:
        """The fused optimizer step over every registered optimizer (rebuilt when optimizers change)."""
        named = [(mid, name) for mid, names in self._module_optimizers.items() for name in names]
        optimizers = [self.get_optimizer(mid, name) for mid, name in named]
        cached = getattr(self, "_fused_cache", None)
        if cached is None or [id(o) for o in cached.optimizers] != [id(o) for o in optimizers]:
            if self.config.grad_clip is not None and self.config.grad_clip_by != "global_norm":
                raise ValueError(f"the fused update clips by global norm only; got grad_clip_by={self.config.grad_clip_by!r}")
            segments = [_segment_dims(mid, name) for mid, name in named]
            self._fused_cache = FusedAdamStep(optimizers, self.config.grad_clip, segments)
        return self._fused_cache

    def _backward_and_step(self, total: Any) -> None:
        fused = self._fused_step()
        fused.zero_grad()
        if isinstance(total, torch.Tensor) and total.grad_fn is not None:
            total.backward()
            fused.step()

    def _log_terms(self, terms: dict[str, PPOLossTerms]) -> None:
        """Log one minibatch's PPO terms per module (RLlib keeps only the last minibatch's too: window 1)."""
        for mid, t in terms.items():
            self.metrics.log_dict(
                {POLICY_LOSS_KEY: t.policy_loss.detach(), VF_LOSS_KEY: t.vf_loss.detach(), ENTROPY_KEY: t.entropy.detach(), self.TOTAL_LOSS_KEY: t.total.detach()},
                key=mid,
                window=1,
            )

    def _ppo_settings(self, module_id: str) -> dict[str, float]:
        config = self.config.get_config_for_module(module_id)
        return {
            "clip_param": config.clip_param,
            "vf_loss_coeff": config.vf_loss_coeff,
            "vf_clip_param": config.vf_clip_param,
            "entropy_coeff": self.entropy_coeff_schedulers_per_module[module_id].get_current_value(),
        }

    def _plain_epochs(self, data: dict[str, dict], plan: CyclicMinibatchPlan) -> None:
        """The minibatch updates of plain modules (one forward per module, e.g. self-play seats)."""
        settings = {mid: self._ppo_settings(mid) for mid in data}
        for rows in plan:
            minibatch = {mid: {c: _take(v, rows[mid]) for c, v in cols.items()} for mid, cols in data.items()}
            fwd_out = self.module.forward_train(minibatch)
            terms = {}
            for mid, mb in minibatch.items():
                out = fwd_out[mid]
                values = self.module[mid].compute_values(mb, embeddings=out.get(Columns.EMBEDDINGS))
                terms[mid] = ppo_loss(out[Columns.ACTION_DIST_INPUTS], values, mb[Columns.ACTIONS], mb, **settings[mid])
            self._backward_and_step(sum(t.total for t in terms.values()))
        self._log_terms(terms)

    def _stacked_epochs(self, data: dict[str, dict], plan: CyclicMinibatchPlan) -> None:
        """The minibatch updates of a stacked ego: each minibatch gathered into [K, H, B] tensors, one batched loss."""
        stack = self.module.stack
        k, h = stack.replicas, stack.heads
        views = {mid: self.module[mid] for mid in data}
        cell = {mid: (v.replica, v.head) for mid, v in views.items()}
        longest = max(len(cols[Columns.ACTIONS]) for cols in data.values())

        def grid(get: Any) -> torch.Tensor:
            """One column of every module, padded into [K, H, longest, ...] (zeros where a module has no row)."""
            first = get(next(iter(data.values())))
            out = first.new_zeros((k, h, longest, *first.shape[1:]))
            for mid, cols in data.items():
                t = get(cols)
                out[cell[mid]][: len(t)] = t
            return out

        obs = grid(lambda c: c[Columns.OBS]["observations"])
        mask = grid(lambda c: c[Columns.OBS]["action_mask"]) if "action_mask" in next(iter(data.values()))[Columns.OBS] else None
        columns = {c: grid(lambda cols, c=c: cols[c]) for c in (Columns.ACTIONS, Columns.ACTION_LOGP, Postprocessing.ADVANTAGES, Postprocessing.VALUE_TARGETS)}
        present = torch.zeros((k, h), dtype=torch.bool)
        for r, hh in cell.values():
            present[r, hh] = True
        kk = torch.arange(k).view(k, 1, 1)
        hh_ = torch.arange(h).view(1, h, 1)
        settings = self._ppo_settings(next(iter(data)))  # one config for every head of the stack
        shared_log: list[tuple[torch.Tensor, torch.Tensor]] = []
        for rows in plan:
            b = len(next(iter(rows.values())))
            idx = torch.zeros((k, h, b), dtype=torch.long)
            for mid, r in rows.items():
                idx[cell[mid]] = r
            valid = present.unsqueeze(-1).expand(k, h, b)
            stacked = self.module.forward_stacked(obs[kk, hh_, idx], None if mask is None else mask[kk, hh_, idx], valid)
            mb = {c: t[kk, hh_, idx] for c, t in columns.items()}
            terms = ppo_loss(stacked.logits, stacked.values, mb[Columns.ACTIONS], mb, valid=valid, **settings)
            reg, size = self._shared_terms(stacked)
            shared_log.append((reg.detach(), size.detach()))
            self._backward_and_step(terms.total.sum() + sum(self._weighted(reg, size).values()))
        self._log_terms(
            {mid: PPOLossTerms(*(t[r, hh] for t in (terms.total, terms.policy_loss, terms.vf_loss, terms.entropy))) for mid, (r, hh) in cell.items()}
        )
        self._log_shared(torch.stack([r for r, _ in shared_log]).mean(0), torch.stack([s for _, s in shared_log]).mean(0))
