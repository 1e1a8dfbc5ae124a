"""`StackedEgoMultiRLModule`: K replica egos in one MultiRLModule, their weights in one `EgoStack`, run batched.

Module IDs: `stack` (the `EgoStack`: every replica's task module and heads; no agent maps
to it), `ego@<partner>#<r>` (a `HeadView`: head `h` of replica `r`, what the ego agent of
replica r maps to when it plays that partner; `ego#<r>` for single-network methods) and
`partner@<partner>#<r>` (the fixed partner). RLlib batches, minibatches and computes values
per module ID as usual; every forward pass of the multi module, though, gathers the rows
of all heads of all replicas and runs each layer once for all of them (`EgoStack`).

Exploration draws each replica's actions from that replica's own generator, over its
rows in a fixed order (its heads in order, each head's rows as RLlib batched them), so a
replica explores exactly as it would alone.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import torch
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.apis.value_function_api import ValueFunctionAPI
from ray.rllib.core.rl_module.torch import TorchRLModule

from rllib_conv.modules.packed.ego_stack import HEAD_POLICY, EgoStack, pad_rows, unpad
from rllib_conv.modules.shared_wiring import SharedWiringMultiRLModule
from rllib_conv.modules.task_module import split_obs

STACK_ID = "stack"
# fwd_out[STACK_ID] in training: the batched tensors the learner's losses read (`StackedOutput`).
STACKED = "stacked"


class HeadView(TorchRLModule, ValueFunctionAPI):
    """Head `head` of replica `replica` of the multi module's `EgoStack` (no weights of its own).

    `model_config`: `replica`, `head`. Built inside a `StackedEgoMultiRLModule`, which points it at the stack.
    """

    def setup(self) -> None:
        self.replica, self.head = int(self.model_config["replica"]), int(self.model_config["head"])
        self.__dict__["_stack"] = None  # not a registered child: the stack's weights belong to the stack

    @property
    def stack(self) -> EgoStack:
        """The `EgoStack` holding this head's weights; raises outside a `StackedEgoMultiRLModule`."""
        if self.__dict__["_stack"] is None:
            raise RuntimeError("HeadView has no stack; build it inside a StackedEgoMultiRLModule")
        return self.__dict__["_stack"]

    def set_shared(self, stack: EgoStack) -> None:
        """Point this view at the stack (not registered as a child)."""
        self.__dict__["_stack"] = stack

    @property
    def index(self) -> int:
        """This head's position among the stack's K x H heads."""
        return self.replica * self.stack.heads + self.head

    def _rows(self, batch: dict[str, Any], value: bool = True) -> tuple[Any, torch.Tensor, torch.Tensor | None]:
        obs, mask = split_obs(batch)
        replica = torch.tensor([self.replica])
        return self.stack.task_forward(obs[None], None if mask is None else mask[None], replica, value), obs, mask

    def _forward(self, batch: dict[str, Any], **kwargs: Any) -> dict[str, Any]:
        task, _, mask = self._rows(batch, value=False)
        out = self.stack._heads("head_pi", HEAD_POLICY, task.z, torch.tensor([self.index]))
        logits = self.stack.policy_logits(out[0], task.logits[0], mask)
        return {Columns.ACTION_DIST_INPUTS: logits}

    def compute_values(self, batch: dict[str, Any], embeddings: Any = None) -> torch.Tensor:
        if embeddings is not None:  # the multi module's train forward computed them
            return embeddings
        task, _, _ = self._rows(batch)
        return task.value[0] + self.stack.head_values(task.z, torch.tensor([self.index]))[0]


@dataclass
class StackedOutput:
    """What one training forward computes for the learner, batched over replicas K and heads H (rows B per head).

    `logits` [K, H, B, A]: each head's policy logits on its own rows; `values` [K, H, B];
    `all_logits` [K, H, M, A] and `head_out` (before the task logits) [K, H, M, A]: every head
    on every row of its replica (M = N = H x B rows), or on every distinct situation of them
    (`EgoStack.few_situations`), None when the forward ran each head on its own rows only;
    `task_logits` [K, M, A]; `valid` [K, H, B]: the rows that exist (padding is False);
    `row_weights` [K, M]: how many valid rows each of the M stands for (the regulariser's
    and the head penalty's weights: 1 or 0 per row, a count per situation).
    """

    logits: torch.Tensor
    values: torch.Tensor
    all_logits: torch.Tensor | None
    head_out: torch.Tensor | None
    task_logits: torch.Tensor
    valid: torch.Tensor
    row_weights: torch.Tensor


class StackedEgoMultiRLModule(SharedWiringMultiRLModule):
    """MultiRLModule of K replica egos whose forward passes run every replica and head at once (see the module docstring)."""

    SHARED_ID = STACK_ID
    DEPENDENT = HeadView

    @property
    def stack(self) -> EgoStack:
        """The stacked weights of every replica."""
        return self._rl_modules[STACK_ID]

    # --- acting (env runners) ---------------------------------------------------------------------

    @torch.no_grad()  # acting needs no gradient: env runners call this outside any no_grad
    def _forward_acting(self, batch: dict[str, Any], explore: bool) -> dict[str, Any]:
        """Every head in `batch` on its rows: each replica's task module once on all its heads' rows, each layer batched."""
        stack = self.stack
        views = {mid: self._rl_modules[mid] for mid in batch if isinstance(self._rl_modules.get(mid), HeadView)}
        out = {
            mid: self._rl_modules[mid].forward_exploration(b) if explore else self._rl_modules[mid].forward_inference(b)
            for mid, b in batch.items()
            if mid not in views and mid in self
        }
        if not views:
            return out
        # Rows by replica, its heads in stack order: the order a replica's exploration draws in.
        order = sorted(views, key=lambda mid: (views[mid].replica, views[mid].head))
        replicas = sorted({views[mid].replica for mid in order})
        rows = {mid: split_obs(batch[mid]) for mid in order}
        per_replica = {r: [mid for mid in order if views[mid].replica == r] for r in replicas}
        obs, sizes = pad_rows([torch.cat([rows[mid][0] for mid in per_replica[r]]) for r in replicas])
        has_mask = all(rows[mid][1] is not None for mid in order)
        mask = pad_rows([torch.cat([rows[mid][1] for mid in per_replica[r]]) for r in replicas])[0] if has_mask else None
        task = stack.task_forward(obs, mask, _subset(replicas, stack.replicas), value=False)
        z_parts, l_parts, m_parts, lengths = [], [], [], {}
        for g, r in enumerate(replicas):
            start = 0
            for mid in per_replica[r]:
                n = len(rows[mid][0])
                z_parts.append(task.z[g, start : start + n])
                l_parts.append(task.logits[g, start : start + n])
                m_parts.append(None if mask is None else mask[g, start : start + n])
                lengths[mid] = n
                start += n
        z, head_sizes = pad_rows(z_parts)
        head_out = stack._heads(
            "head_pi", HEAD_POLICY, z, _subset([views[mid].index for mid in order], stack.replicas * stack.heads)
        )
        logits_pad = stack.policy_logits(head_out, pad_rows(l_parts)[0], None if mask is None else pad_rows(m_parts)[0])
        logits = dict(zip(order, unpad(logits_pad, head_sizes)))
        if not explore:
            out.update({mid: {Columns.ACTION_DIST_INPUTS: logits[mid]} for mid in order})
            return out
        for r in replicas:
            mids = per_replica[r]
            block = torch.cat([logits[mid] for mid in mids])
            actions = torch.multinomial(torch.softmax(block, dim=-1), 1, generator=stack.samplers[r]).squeeze(-1)
            logp = (block - block.logsumexp(dim=-1, keepdim=True)).gather(-1, actions.unsqueeze(-1)).squeeze(-1)
            start = 0
            for mid in mids:
                n = lengths[mid]
                out[mid] = {
                    Columns.ACTION_DIST_INPUTS: logits[mid],
                    Columns.ACTIONS: actions[start : start + n],
                    Columns.ACTION_LOGP: logp[start : start + n],
                }
                start += n
        return out

    def _forward_inference(self, batch: dict[str, Any], **kwargs: Any) -> dict[str, Any]:
        return self._forward_acting(batch, explore=False)

    def _forward_exploration(self, batch: dict[str, Any], **kwargs: Any) -> dict[str, Any]:
        return self._forward_acting(batch, explore=True)

    # --- training ---------------------------------------------------------------------------------

    def forward_stacked(
        self, obs: torch.Tensor, mask: torch.Tensor | None, valid: torch.Tensor, all_heads: bool = True
    ) -> StackedOutput:
        """The training forward on rows already stacked per (replica, head): obs [K, H, B, d], mask [K, H, B, A], valid [K, H, B].

        `all_heads=False` runs each head on its own rows only (H times less head work):
        `all_logits` and `head_out` are then None, for losses that read neither (no
        regulariser, no head penalty). The own logits and values are the same either way.
        A stack of several heads in a game with few situations (`EgoStack.few_situations`)
        runs every head on the distinct (observation, mask) rows alone (`_forward_situations`).
        """
        stack = self.stack
        k, h, b = obs.shape[:3]
        x = obs.reshape(k, h * b, -1)
        m = None if mask is None else mask.reshape(k, h * b, -1)
        if stack.few_situations and all_heads and h > 1:  # one head, or each on its own rows: too little work to share
            return self._forward_situations(x, m, valid)
        task = stack.task_forward(x, m)
        z_own = task.z.reshape(k * h, b, -1)
        values = stack.head_values(z_own).reshape(k, h, b) + task.value.reshape(k, h, b)
        rows = valid.reshape(k, h * b)
        if not all_heads:
            head_own = stack._heads("head_pi", HEAD_POLICY, z_own).reshape(k, h, b, -1)
            own = stack.policy_logits(head_own, task.logits.reshape(k, h, b, -1), mask)
            return StackedOutput(own, values, None, None, task.logits, valid, rows)
        head_out = stack.head_outputs(task.z)  # [K, H, N, A]
        all_logits = stack.policy_logits(head_out, task.logits.unsqueeze(1), None if m is None else m.unsqueeze(1))
        own = all_logits.reshape(k, h, h, b, -1).diagonal(dim1=1, dim2=2).permute(0, 3, 1, 2)  # [K, H, B, A]
        return StackedOutput(own, values, all_logits, head_out, task.logits, valid, rows)

    def _forward_situations(self, x: torch.Tensor, m: torch.Tensor | None, valid: torch.Tensor) -> StackedOutput:
        """`forward_stacked` run once per distinct (observation, mask) of the rows x [K, N, d], m [K, N, A].

        Every output of a row is a function of its observation and mask alone, so the
        stack runs every head on the U distinct ones (U is the bandit's few contexts, where
        N is hundreds of rows) and each row takes its situation's logits and values: the
        same numbers and gradients at a fraction of the work. The regulariser's rows are
        then the situations, each weighted by how many valid rows it stands for.
        """
        stack = self.stack
        k, h, b = valid.shape
        d = x.shape[-1]
        keys = x if m is None else torch.cat([x, m.to(x.dtype)], dim=-1)
        distinct, inverse = torch.unique(keys.reshape(k * h * b, -1), dim=0, return_inverse=True)
        u = len(distinct)
        u_obs = distinct[:, :d].expand(k, u, d)
        u_mask = None if m is None else distinct[:, d:].to(m.dtype).expand(k, u, m.shape[-1])
        task = stack.task_forward(u_obs, u_mask)
        head_out = stack.head_outputs(task.z)  # [K, H, U, A]
        all_logits = stack.policy_logits(head_out, task.logits.unsqueeze(1), None if u_mask is None else u_mask.unsqueeze(1))
        zz = task.z.unsqueeze(1).expand(k, h, u, task.z.shape[-1]).reshape(k * h, u, -1)
        u_values = stack.head_values(zz).reshape(k, h, u) + task.value.unsqueeze(1)
        row = inverse.view(k, h, b)  # each row's situation; head h's own rows are block h of its replica's rows
        own = all_logits.gather(2, row.unsqueeze(-1).expand(k, h, b, all_logits.shape[-1]))
        weights = torch.zeros((k, u), dtype=x.dtype).scatter_add_(1, inverse.view(k, h * b), valid.reshape(k, h * b).to(x.dtype))
        return StackedOutput(own, u_values.gather(2, row), all_logits, head_out, task.logits, valid, weights)

    def stack_batch(
        self, batch: dict[str, Any]
    ) -> tuple[list[str], torch.Tensor, torch.Tensor | None, torch.Tensor, dict[str, int]]:
        """Per-module rows of `batch` as [K, H, B, ...] (padded): (head IDs in batch, obs, mask, valid, rows per head)."""
        stack = self.stack
        views = {mid: self._rl_modules[mid] for mid in batch if isinstance(self._rl_modules.get(mid), HeadView)}
        parts = {mid: split_obs(batch[mid]) for mid in views}
        longest = max(len(o) for o, _ in parts.values())
        first_obs, first_mask = next(iter(parts.values()))
        obs = first_obs.new_zeros((stack.replicas, stack.heads, longest, first_obs.shape[-1]))
        mask = None if first_mask is None else first_mask.new_zeros((stack.replicas, stack.heads, longest, first_mask.shape[-1]))
        valid = torch.zeros((stack.replicas, stack.heads, longest), dtype=torch.bool)
        for mid, (o, msk) in parts.items():
            v = views[mid]
            obs[v.replica, v.head, : len(o)] = o
            if mask is not None:
                mask[v.replica, v.head, : len(o)] = msk
            valid[v.replica, v.head, : len(o)] = True
        return list(views), obs, mask, valid, {mid: len(o) for mid, (o, _) in parts.items()}

    def _forward_train(self, batch: dict[str, Any], **kwargs: Any) -> dict[str, Any]:
        """RLlib's train forward: every head's logits and values on its own rows, and the batched `StackedOutput`."""
        mids, obs, mask, valid, lengths = self.stack_batch(batch)
        out = {
            mid: self._rl_modules[mid].forward_train(b, **kwargs)
            for mid, b in batch.items()
            if mid in self and mid not in lengths
        }
        stacked = self.forward_stacked(obs, mask, valid)
        for mid in mids:
            v, n = self._rl_modules[mid], lengths[mid]
            out[mid] = {
                Columns.ACTION_DIST_INPUTS: stacked.logits[v.replica, v.head, :n],
                Columns.EMBEDDINGS: stacked.values[v.replica, v.head, :n],
            }
        out[STACK_ID] = {STACKED: stacked}
        return out


def _subset(index: list[int], n: int) -> torch.Tensor | None:
    """`index` as the tensor that picks those of `n` stacked weights, or None when it is all of them in order.

    None lets the batched layers use the stacked weights as they are, not a copy of them
    (a copy of every 500x500 layer per acting step on Hanabi).
    """
    return None if index == list(range(n)) else torch.tensor(index)
