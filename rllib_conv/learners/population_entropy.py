"""MEP's population entropy: the entropy of the population's mean policy (Zhao et al., AAAI 2023).

Maximum-Entropy Population training gives every member of a population of N self-play
pairs a bonus for the entropy of the members' mean policy on the same states,

    PE = mean_s H( (1/N) sum_i pi_i(.|s) ),   H(p) = -sum_a p(a) log p(a),

over the states s of a minibatch (every member's rows of one seat, each member's policy on
all of them). The learner subtracts `alpha * PE` from the loss, so each member's gradient
pushes the mean policy apart: members that agree on an action lower PE, members that use
different (good) actions raise it, while each member may stay deterministic. The mean is
the regulariser's (`regulariser.mean_policy`).
"""

from __future__ import annotations

import torch

from rllib_conv.learners.regulariser import mean_policy


def population_entropy(logits: torch.Tensor) -> torch.Tensor:
    """PE of N policies' `logits` [N, B, A] on the same B states: the mean over states of H(mean policy), a scalar.

    Illegal actions (logits at the float minimum) have probability 0 and add nothing; the
    log is clamped at the smallest normal float so that their gradient stays finite.
    """
    probs = mean_policy(logits, dim=0)
    per_row = -(probs * torch.log(probs.clamp(min=torch.finfo(probs.dtype).tiny))).sum(-1)
    return per_row.mean()
