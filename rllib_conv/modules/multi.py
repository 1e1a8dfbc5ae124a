"""`ConventionMultiRLModule`: one shared task module, one ego head per partner, fixed partners.

Module IDs: `task` (the shared task module, mapped to no agent), `ego@<partner>` (the
ego's head for that partner; `ego` alone for BaselineAgg's single head) and
`partner@<partner>` (the fixed partner). The task module is a sub-module of its own, so
its weights exist once: one optimizer steps them once per update, a checkpoint holds
them once (under `task/`), and env runners receive them once per weight sync. Heads
only hold a reference to it, re-wired whenever modules are built or added, on learners
and env runners alike.
"""

from __future__ import annotations

from typing import Any

import torch
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModule
from ray.rllib.core.rl_module.rl_module import RLModule

from rllib_conv.modules.partner_head import TASK_LOGITS, TASK_VALUE, PartnerHeadModule
from rllib_conv.modules.task_module import TaskModule, split_obs

TASK_ID = "task"
# fwd_out[TASK_ID] in training: every head's logits on every ego state of the minibatch.
ALL_HEAD_LOGITS = "all_head_logits"
# fwd_out[TASK_ID] in training: every head's own output (before the task logits are added).
ALL_HEAD_OUTPUTS = "all_head_outputs"
AGG_HEAD_ID = "ego"
EGO_PREFIX = "ego@"
PARTNER_PREFIX = "partner@"


def ego_id(partner_name: str) -> str:
    """Module ID of the ego head that plays with `partner_name`."""
    return EGO_PREFIX + partner_name


def partner_id(partner_name: str) -> str:
    """Module ID of the fixed partner `partner_name`."""
    return PARTNER_PREFIX + partner_name


class ConventionMultiRLModule(MultiRLModule):
    """MultiRLModule that wires every `PartnerHeadModule` to the shared `TaskModule`."""

    def setup(self) -> None:
        super().setup()
        self._wire()

    def add_module(self, module_id: str, module: RLModule, *, override: bool = False) -> None:
        super().add_module(module_id, module, override=override)
        self._wire()

    def _wire(self) -> None:
        task = self._rl_modules.get(TASK_ID)
        for module in self._rl_modules.values():
            if isinstance(module, PartnerHeadModule):
                module.set_task(task)

    def _forward_train(self, batch: dict[str, Any], **kwargs: Any) -> dict[str, Any]:
        """Train forward: the task module runs once on all heads' rows; every head sees every row.

        Equivalent to each head's own `forward_train`, but one task forward replaces one
        per head, and the [heads, rows, actions] logits the marginal regulariser needs
        (returned under `fwd_out[TASK_ID][ALL_HEAD_LOGITS]`, with the heads' own outputs
        under `ALL_HEAD_OUTPUTS` for the head penalty) come for free.
        """
        head_ids = [mid for mid in batch if isinstance(self._rl_modules.get(mid), PartnerHeadModule)]
        out = {mid: self._rl_modules[mid].forward_train(batch[mid], **kwargs) for mid in batch if mid in self and mid not in head_ids}
        if not head_ids:
            return out
        parts = [split_obs(batch[mid]) for mid in head_ids]
        sizes = [len(obs) for obs, _ in parts]
        obs = torch.cat([o for o, _ in parts])
        mask = None if any(m is None for _, m in parts) else torch.cat([m for _, m in parts])
        z, task_logits = self.task.policy(obs, mask)
        task_value = self.task.value(obs)
        order = self.head_ids()
        heads = [self._rl_modules[h] for h in order]
        outputs = torch.stack([h.pi(z) for h in heads])
        all_logits = torch.stack([h.combine(o, task_logits, mask) for h, o in zip(heads, outputs)])
        start = 0
        for mid, n in zip(head_ids, sizes):
            rows = slice(start, start + n)
            out[mid] = {
                Columns.ACTION_DIST_INPUTS: all_logits[order.index(mid), rows],
                Columns.EMBEDDINGS: {"z": z[rows], TASK_VALUE: task_value[rows]},
                TASK_LOGITS: task_logits[rows],
            }
            start += n
        out[TASK_ID] = {ALL_HEAD_LOGITS: all_logits, ALL_HEAD_OUTPUTS: outputs, TASK_LOGITS: task_logits}
        return out

    @property
    def task(self) -> TaskModule:
        """The shared task module."""
        return self._rl_modules[TASK_ID]

    def head_ids(self) -> list[str]:
        """IDs of all ego heads, in insertion order."""
        return [mid for mid, m in self._rl_modules.items() if isinstance(m, PartnerHeadModule)]
