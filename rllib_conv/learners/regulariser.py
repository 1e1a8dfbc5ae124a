"""The paper's marginal regulariser D: the task module alone should play the average of the partner policies.

For one ego with task logits t(s) and heads i = 1..H (one per training partner), whose
policies are softmax(t(s) + h_i(s)),

    D = mean_s sum_a | softmax(t)(a|s) - mean_i softmax(t + h_i)(a|s) |

over the states s of the minibatch (every head's rows). The loss is PPO's plus `lam * D`,
with no gradient stopped (the paper's code): D moves both the task module and the heads,
so that the task module alone plays what the partners share (the rules) and a head keeps
what is particular to its partner (the convention). A leading batch of independent egos
(packed replicas) gives one D per ego.
"""

from __future__ import annotations

import torch


def masked_mean(x: torch.Tensor, valid: torch.Tensor, dims: int) -> torch.Tensor:
    """The mean of `x` over its last `dims` dims, counting only `valid` entries (same shape as those dims)."""
    axes = tuple(range(-dims, 0))
    return (x * valid).sum(axes) / valid.sum(axes).clamp(min=1)


def mean_policy(logits: torch.Tensor, dim: int = -3) -> torch.Tensor:
    """The mean of several policies' action probabilities: softmax of `logits` averaged over `dim` (the policies' axis).

    The regulariser's average partner policy; MEP's population policy (`population_entropy`).
    """
    return torch.softmax(logits, dim=-1).mean(dim=dim)


def marginal_distance(task_logits: torch.Tensor, head_logits: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
    """D per ego: mean over rows of sum_a |softmax(task) - mean_i softmax(head_i)|.

    `task_logits` [..., N, A], `head_logits` (the policies' logits, task logits included)
    [..., H, N, A], `valid` [..., N] (default all rows): returns [...].
    """
    per_row = (torch.softmax(task_logits, dim=-1) - mean_policy(head_logits)).abs().sum(dim=-1)
    return per_row.mean(-1) if valid is None else masked_mean(per_row, valid.to(per_row.dtype), 1)
