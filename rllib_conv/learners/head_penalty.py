"""The head penalty H (`head_l2`; not in the paper): how much of the policy a head carries.

    H = mean_{i,s} sum_a (h_i(a|s) - mean_b h_i(b|s))^2

on every ego head's own output h_i (before the task logits are added; centred, since a
constant shift leaves the policy unchanged; illegal actions count too, their outputs never
reach the policy). Where the task module alone already plays the partners' common response
(the rules), PPO leaves heads and task module free to split the logits any way; H makes the
task module carry them, so a head holds only what differs between partners (the
conventions), and a frozen head stays out of the way when the task module is re-trained on
a new task.
"""

from __future__ import annotations

import torch

from rllib_conv.learners.regulariser import masked_mean


def head_size(head_outputs: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
    """Mean over heads and rows of sum_a (h(a) - mean_b h(b))^2: head outputs [..., H, N, A], `valid` [..., N] -> [...]."""
    centred = head_outputs - head_outputs.mean(dim=-1, keepdim=True)
    per_row = centred.pow(2).sum(dim=-1)  # [..., H, N]
    if valid is None:
        return per_row.mean((-2, -1))
    return masked_mean(per_row, valid.unsqueeze(-2).expand_as(per_row).to(per_row.dtype), 2)
