"""PPO's clipped surrogate loss for one module's minibatch, the same arithmetic as RLlib's `PPOTorchLearner`.

Categorical log-probabilities and entropies are computed as `torch.distributions.Categorical`
(RLlib's `TorchCategorical`) computes them, so the loss matches RLlib's to float precision;
only RLlib's per-minibatch metric logging is left out (the learner logs once per update).
No KL term (this project trains with `use_kl_loss=False`) and no value clipping beyond
`vf_clip_param` (infinite here, as in the paper's code).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from ray.rllib.core.columns import Columns
from ray.rllib.evaluation.postprocessing import Postprocessing


@dataclass
class PPOLossTerms:
    """One module's loss and the statistics RLlib reports for it (all tensors, the loss with gradient)."""

    total: torch.Tensor
    policy_loss: torch.Tensor
    vf_loss: torch.Tensor
    entropy: torch.Tensor


def categorical_logp_entropy(logits: torch.Tensor, actions: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """log pi(actions) and the entropy of the categorical with `logits` [B, A], as `torch.distributions.Categorical`."""
    normalized = logits - logits.logsumexp(dim=-1, keepdim=True)
    logp = normalized.gather(-1, actions.long().unsqueeze(-1)).squeeze(-1)
    probs = torch.softmax(normalized, dim=-1)
    clamped = torch.clamp(normalized, min=torch.finfo(normalized.dtype).min)
    return logp, -(clamped * probs).sum(-1)


def ppo_loss(
    logits: torch.Tensor,
    values: torch.Tensor,
    actions: torch.Tensor,
    batch: dict,
    *,
    clip_param: float,
    vf_loss_coeff: float,
    vf_clip_param: float,
    entropy_coeff: float,
    valid: torch.Tensor | None = None,
) -> PPOLossTerms:
    """PPO's loss on a minibatch given the new `logits` [..., B, A] and `values` [..., B].

    `batch` holds the minibatch's action log-probabilities, advantages and value targets
    ([..., B]). Without `valid`, one module's minibatch: scalar means. With `valid` [..., B]
    (rows stacked per module, e.g. [K, H, B], padding False): one mean per module, over its
    valid rows, each [...] (RLlib's loss of every module at once).
    """
    logp, entropy = categorical_logp_entropy(logits, actions)
    ratio = torch.exp(logp - batch[Columns.ACTION_LOGP])
    advantages = batch[Postprocessing.ADVANTAGES]
    surrogate = torch.min(advantages * ratio, advantages * torch.clamp(ratio, 1 - clip_param, 1 + clip_param))
    vf_loss = torch.clamp(torch.pow(values - batch[Postprocessing.VALUE_TARGETS], 2.0), 0, vf_clip_param)
    per_row = -surrogate + vf_loss_coeff * vf_loss - entropy_coeff * entropy
    if valid is None:
        mean = torch.mean
    else:
        weight = valid.to(per_row.dtype)
        count = weight.sum(-1).clamp(min=1)

        def mean(x: torch.Tensor) -> torch.Tensor:
            return (x * weight).sum(-1) / count

    return PPOLossTerms(mean(per_row), -mean(surrogate), mean(vf_loss), mean(entropy))
