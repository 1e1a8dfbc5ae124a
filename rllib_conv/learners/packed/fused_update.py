"""`FusedUpdateLearner`: PPO's update as one loop over batched minibatches, with RLlib's arithmetic at a fraction of its cost.

RLlib's `Learner.update` copies every minibatch into a new `MultiAgentBatch`, logs a dozen
metrics per module per minibatch and steps each optimizer separately; on our small networks
that bookkeeping is nearly all of the time. `FusedUpdateLearner.update` builds the same train
batch (RLlib's learner connector, or `rollout_train_batch` for the batched sampler's
`Rollout`s), slices its tensors by `CyclicMinibatchPlan` (RLlib's minibatch order and
shuffles), computes `ppo_loss` for every replica and head of a packed ego at once (a
`StackedEgoMultiRLModule`: one [K, H, B] forward) plus the subclass's terms on the stack
(`stack_terms`, e.g. the marginal regulariser; on plain modules such as self-play seats
`plain_terms`, e.g. MEP's population entropy, with per-row columns computed once per update
on whole episodes, `plain_episode_columns`, e.g. TrajeDi's bonus to the advantages), and clips and steps every optimizer with one
`FusedAdamStep`. Metrics are logged once per update.

This is the one update that trains. RLlib's own loop is kept only as the reference it is
checked against (`tests/learners/test_fused_update.py` calls `PPOTorchLearner.update` past the override): the
hooks that loop calls, `compute_losses` and `postprocess_gradients_for_module`, are here
for it, with the same terms and per-replica clipping.
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
from rllib_conv.learners.packed.fused_step import FusedAdamStep, clip_segments
from rllib_conv.learners.packed.minibatches import CyclicMinibatchPlan, ModulePermuters, global_permute
from rllib_conv.learners.packed.rollout import Rollout, rollout_train_batch, segment_lengths
from rllib_conv.learners.ppo_loss import PPOLossTerms, ppo_loss
from rllib_conv.learners.settings import LearnerSettings
from rllib_conv.modules.multi import TASK_ID, replica_id
from rllib_conv.modules.packed.stacked_multi import STACK_ID, STACKED, StackedEgoMultiRLModule, StackedOutput

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


def _cells(idx: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The advanced index that takes rows `idx` [K, H, B] of every (replica, head) of a [K, H, N, ...] tensor."""
    k, h, _ = idx.shape
    return torch.arange(k).view(k, 1, 1), torch.arange(h).view(1, h, 1), idx


def _gather(idx: torch.Tensor, obs: torch.Tensor, mask: torch.Tensor | None) -> tuple[torch.Tensor, torch.Tensor | None]:
    """The minibatch's observations and action masks: rows `idx` of the padded [K, H, N, ...] grids."""
    cells = _cells(idx)
    return obs[cells], None if mask is None else mask[cells]


class FusedUpdateLearner(PPOTorchLearner):
    """A PPO learner whose `update` is the fused minibatch loop (see the module docstring).

    Subclasses add terms computed on a packed ego's batched output: `stack_terms` gives
    them per replica (logged under `task#r` and, averaged, under ALL_MODULES), `stack_loss`
    what of them enters the loss.
    """

    def build(self) -> None:
        super().build()
        # After PPO's GAE piece: advantages need the bootstrap rows, the losses do not.
        if self._learner_connector is not None:
            self._learner_connector.append(DropBootstrapRows())

    @cached_property
    def settings(self) -> LearnerSettings:
        """What the learner reads from `learner_config_dict` (`LearnerSettings`)."""
        cfg = dict(self.config.learner_config_dict)
        # Algorithm checkpoints written before the fused update became the only one carry its old switch.
        cfg.pop("fused_update", None)
        return LearnerSettings(**{**cfg, "freeze": tuple(cfg.get("freeze", ()))})

    @cached_property
    def permuters(self) -> ModulePermuters:
        """The per-module shuffling generators (`shuffle_seeds`); their states are saved with checkpoints."""
        return ModulePermuters(self.settings.shuffle_seeds)

    def _permute(self, module_id: str, n: int) -> Any:
        """A permutation of `n` rows for `module_id`: from its own generator if it has one, else NumPy's global RNG."""
        return self.permuters(module_id, n) if module_id in self.settings.shuffle_seeds else global_permute(module_id, n)

    def _autocast(self) -> torch.autocast:
        """The forward and loss's precision (`LearnerSettings.precision`): bfloat16 matrix products under autocast, or float32."""
        return torch.autocast(
            torch.device(self._device).type, dtype=torch.bfloat16, enabled=self.settings.precision == "bfloat16"
        )

    @property
    def stacked(self) -> bool:
        """Whether the module is a stack of replica egos (else plain RLlib modules, e.g. self-play seats)."""
        return isinstance(self.module, StackedEgoMultiRLModule)

    # --- the subclass's terms on a packed ego ------------------------------------------------------------

    def stack_terms(self, stacked: StackedOutput) -> dict[str, torch.Tensor]:
        """Per-replica terms ([K] each) of one minibatch, by metric name; none here."""
        return {}

    def stack_loss(self, terms: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """The loss terms (scalars, by name) made of `stack_terms`' output; none here."""
        return {}

    @property
    def loss_reads_all_heads(self) -> bool:
        """Whether `stack_loss` needs every head on every row (`StackedOutput.all_logits`); none here.

        When it does not, each minibatch runs every head on its own rows only, and
        `stack_terms` are logged from the update's last minibatch alone.
        """
        return False

    # --- the subclass's terms on plain modules (self-play seats) ------------------------------------------

    def plain_terms(self, minibatch: dict[str, dict]) -> dict[str, torch.Tensor]:
        """Scalar terms of one minibatch of plain modules (module ID -> its columns), by metric name; none here."""
        return {}

    def plain_loss(self, terms: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """The loss terms (scalars, by name) made of `plain_terms`' output; none here."""
        return {}

    @property
    def loss_reads_plain_terms(self) -> bool:
        """Whether `plain_loss` needs `plain_terms` with gradients; else they are logged from the update's last minibatch."""
        return False

    def plain_episode_columns(self, data: dict[str, dict], lengths: dict[str, list[int]] | None) -> dict[str, dict]:
        """Per-row columns of plain modules that replace or join theirs (module ID -> column -> [rows]), computed once
        per update on its whole episodes before the minibatches slice them; none here.

        `data` holds every module's rows in sampled order, `lengths` each module's segments
        (episode chunks) laid end to end over them, or None where the batch did not come
        from `Rollout`s (RLlib's episodes).
        """
        return {}

    def _log_stack_terms(self, terms: dict[str, torch.Tensor]) -> None:
        """Log each term per replica under `task#r` and its mean over replicas under ALL_MODULES."""
        for key, per_replica in terms.items():
            for r in range(len(per_replica)):
                self.metrics.log_value((replica_id(TASK_ID, r), key), per_replica[r], reduce="mean")
        for key, per_replica in terms.items():
            self.metrics.log_value((ALL_MODULES, key), per_replica.mean(), reduce="mean")

    # --- the update -------------------------------------------------------------------------------------

    def _make_batch_if_necessary(self, training_data: TrainingData) -> Any:
        """The train batch: from `Rollout`s (the batched sampler's) with RLlib's arithmetic, else RLlib's learner connector."""
        episodes = training_data.episodes
        if not episodes or not any(isinstance(e, Rollout) for e in episodes):
            return super()._make_batch_if_necessary(training_data)
        if not all(isinstance(e, Rollout) for e in episodes):
            raise TypeError(
                "a train batch mixes Rollouts and RLlib episodes: every env runner of an algorithm must sample the same way"
            )
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
        """One PPO update over `num_epochs` epochs of minibatches, with the same arithmetic as RLlib's `Learner.update`."""
        if data_iterators is not None or num_total_minibatches:
            # Only remote learners sharing minibatch counts, or offline data, pass these; this project builds neither.
            raise ValueError("the fused update runs one local learner on sampled data (num_learners=0, no data iterators)")
        self._check_is_built()
        self.before_gradient_based_update(timesteps=timesteps or {})
        if training_data is None:
            training_data = TrainingData(
                batch=batch, batches=batches, batch_refs=batch_refs, episodes=episodes, episodes_refs=episodes_refs
            )
        training_data.validate()
        training_data.solve_refs()
        self._weights_seq_no += 1
        train_batch = self._make_batch_if_necessary(training_data=training_data)
        for module_id in list(train_batch.policy_batches):
            if not self.should_module_be_updated(module_id, train_batch):
                del train_batch.policy_batches[module_id]
        if train_batch.policy_batches:
            data = {mid: {c: b[c] for c in TRAIN_COLUMNS} for mid, b in train_batch.policy_batches.items()}
            if not self.stacked:
                episodes = training_data.episodes
                rollouts = bool(episodes) and all(isinstance(e, Rollout) for e in episodes)
                for mid, cols in self.plain_episode_columns(data, segment_lengths(episodes) if rollouts else None).items():
                    data[mid].update(cols)
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
                {
                    POLICY_LOSS_KEY: t.policy_loss.detach(),
                    VF_LOSS_KEY: t.vf_loss.detach(),
                    ENTROPY_KEY: t.entropy.detach(),
                    self.TOTAL_LOSS_KEY: t.total.detach(),
                },
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
        logged: list[dict[str, torch.Tensor]] = []
        steps = list(plan)
        for i, rows in enumerate(steps):
            minibatch = {mid: {c: _take(v, rows[mid]) for c, v in cols.items()} for mid, cols in data.items()}
            with self._autocast():
                fwd_out = self.module.forward_train(minibatch)
                terms = {}
                for mid, mb in minibatch.items():
                    out = fwd_out[mid]
                    values = self.module[mid].compute_values(mb, embeddings=out.get(Columns.EMBEDDINGS))
                    terms[mid] = ppo_loss(out[Columns.ACTION_DIST_INPUTS], values, mb[Columns.ACTIONS], mb, **settings[mid])
                extra = {}
                if self.loss_reads_plain_terms:
                    extra = self.plain_terms(minibatch)
                    logged.append({key: t.detach() for key, t in extra.items()})
                elif i == len(steps) - 1:  # terms outside the loss are only logged: from the last minibatch, no gradient
                    with torch.no_grad():
                        logged.append(self.plain_terms(minibatch))
            self._backward_and_step(sum(t.total for t in terms.values()) + sum(self.plain_loss(extra).values()))
        self._log_terms(terms)
        for key in logged[0] if logged else ():
            self.metrics.log_value((ALL_MODULES, key), torch.stack([step[key] for step in logged]).mean(), reduce="mean")

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
        columns = {
            c: grid(lambda cols, c=c: cols[c])
            for c in (Columns.ACTIONS, Columns.ACTION_LOGP, Postprocessing.ADVANTAGES, Postprocessing.VALUE_TARGETS)
        }
        present = torch.zeros((k, h), dtype=torch.bool)
        for r, hh in cell.values():
            present[r, hh] = True
        settings = self._ppo_settings(next(iter(data)))  # one config for every head of the stack
        logged: list[dict[str, torch.Tensor]] = []
        steps = list(plan)
        self._fused_step()  # parameters in their flat buffers before the first forward (a compiled loss keeps their layout)
        for i, rows in enumerate(steps):
            b = len(next(iter(rows.values())))
            idx = torch.zeros((k, h, b), dtype=torch.long)
            for mid, r in rows.items():
                idx[cell[mid]] = r
            valid = present.unsqueeze(-1).expand(k, h, b)
            with self._autocast():
                terms, extra, total = self._minibatch_loss(obs, mask, columns, idx, valid, settings)
                if self.loss_reads_all_heads:
                    logged.append({key: t.detach() for key, t in extra.items()})
                elif i == len(steps) - 1:  # terms outside the loss are only logged: from the last minibatch, no gradient
                    with torch.no_grad():
                        logged.append(self.stack_terms(self.module.forward_stacked(*_gather(idx, obs, mask), valid)))
            self._backward_and_step(total)
        self._log_terms(
            {
                mid: PPOLossTerms(*(t[r, hh] for t in (terms.total, terms.policy_loss, terms.vf_loss, terms.entropy)))
                for mid, (r, hh) in cell.items()
            }
        )
        self._log_stack_terms({key: torch.stack([step[key] for step in logged]).mean(0) for key in logged[0]})

    def _minibatch_loss(
        self,
        obs: torch.Tensor,
        mask: torch.Tensor | None,
        columns: dict[str, torch.Tensor],
        idx: torch.Tensor,
        valid: torch.Tensor,
        settings: dict[str, float],
    ) -> tuple[PPOLossTerms, dict[str, torch.Tensor], torch.Tensor]:
        """One minibatch of a stacked ego, rows `idx` [K, H, B] of the padded columns: (PPO terms, stack terms in the loss, total loss).

        Tensors in, tensors out, so that it can be compiled as one graph (`benchmarks/compiled_step.py`).
        """
        mb_obs, mb_mask = _gather(idx, obs, mask)
        stacked = self.module.forward_stacked(mb_obs, mb_mask, valid, all_heads=self.loss_reads_all_heads)
        mb = {c: t[_cells(idx)] for c, t in columns.items()}
        terms = ppo_loss(stacked.logits, stacked.values, mb[Columns.ACTIONS], mb, valid=valid, **settings)
        extra = self.stack_terms(stacked) if self.loss_reads_all_heads else {}
        return terms, extra, terms.total.sum() + sum(self.stack_loss(extra).values())

    # --- RLlib's own loop: the reference the fused update is tested against, never run in training ------------------

    def compute_losses(self, *, fwd_out: dict[str, Any], batch: dict[str, Any]) -> dict[str, Any]:
        shared = fwd_out.pop(STACK_ID, None)  # the stack has no batch and no PPO loss of its own
        losses = super().compute_losses(fwd_out=fwd_out, batch=batch)
        if not self.stacked and self.loss_reads_plain_terms:
            losses.update(self.plain_loss(self.plain_terms(batch)))
        if shared is not None:
            terms = self.stack_terms(shared[STACKED])
            self._log_stack_terms({key: t.detach() for key, t in terms.items()})
            losses.update(self.stack_loss(terms))  # summed into the loss like any other term
        return losses

    def postprocess_gradients_for_module(self, *, module_id: str, config: Any = None, module_gradients_dict: dict) -> dict:
        if module_id != STACK_ID:
            return super().postprocess_gradients_for_module(
                module_id=module_id, config=config, module_gradients_dict=module_gradients_dict
            )
        # Clip each replica's (and each replica head's) gradients apart, as the fused step does.
        for name, optimizer in self.get_optimizers_for_module(module_id):
            grads = list(self.filter_param_dict_for_optimizer(module_gradients_dict, optimizer).values())
            clip_segments([g for g in grads if g is not None], _segment_dims(module_id, name), config.grad_clip)
        return module_gradients_dict
