"""TrajeDi's trajectory diversity: the Jensen-Shannon divergence of several policies' trajectory distributions
(Lupu et al., ICML 2021, "Trajectory Diversity for Zero-Shot Coordination").

N members (here: one seat's policies of N self-play pairs) pi_1 .. pi_N. A trajectory's
likelihood under member j, up to the game's dynamics (the same for every member, so they
cancel), is the product of its action probabilities. TrajeDi's local action likelihood at
step t discounts the other steps by their distance, `gamma` (in log space):

    log pi_hat_j(tau, t) = sum_t' gamma^|t - t'| log pi_j(a_t' | s_t')

(gamma 1: the whole trajectory's likelihood; gamma 0: the move at t alone). With the mixture
pi_hat = (1/N) sum_j pi_hat_j, the divergence

    JSD = H(pi_hat) - (1/N) sum_j H(pi_hat_j) = (1/N) sum_i E_{tau ~ pi_i} [ (1/T) sum_t d_i(tau, t) ],
    d_i(tau, t) = log pi_hat_i(tau, t) - log pi_hat(tau, t)

is estimated on each member's own trajectories (the second form; at gamma 1 it is the exact
JSD of the trajectory distributions in expectation).

**The gradient.** Differentiating that estimate through its log-probabilities alone is no
gradient of the JSD: on a member's own samples E_{tau ~ pi_i}[grad log pi_hat_i] = 0 and the
mixture's term sums to grad sum_tau pi_hat = 0, so what moves the JSD is that each member's
samples follow its own policy. The JSD's gradient is therefore the score-function (policy
gradient) one, d_i acting as member i's reward:

    grad_i JSD = (1/N) E_{tau ~ pi_i} [ (1/T) sum_t d_i(tau, t) grad log pi_hat_i(tau, t) ]
               = (1/N) E_{tau ~ pi_i} [ sum_t grad log pi_i(a_t | s_t) w_i(tau, t) ],
    w_i(tau, t) = (1/T) sum_t' gamma^|t - t'| d_i(tau, t')

(exact at gamma 1, where pi_hat is a distribution; the same estimator on the local likelihoods
otherwise). Since E[grad log pi_i(a_t | s_t)] = 0 for every move, subtracting a constant
from every w_i leaves the estimator unbiased; `trajectory_diversity` subtracts member i's
mean w over its moves (a baseline), so that members whose trajectories no other member
plays (d = log N everywhere: the JSD at its maximum) get no gradient, rather than a noisy
push towards whatever they sampled. It returns the estimate and these per-move weights, and
`surrogate` the scalar whose gradient is the estimator: sum over moves of w (held fixed)
times log pi_i(a | s).

**Why weights per move, computed once per update, added to the advantages.** The learner's
minibatches shuffle rows, so a minibatch holds pieces of episodes. But the gradient above is
a sum over single moves, each weighted by a number that needs its whole episode only to be
*computed*. So the learner computes the weights once per update, before its minibatches, on
the update's episodes with the policies that sampled them, as PPO computes advantages, from
the batched sampler's segments (`packed/rollout.py`: per module, the episode chunks in row
order), and adds `beta x w` (times the member's row count, PPO's loss being a mean over
rows) to each move's advantage: d acts as member i's reward. At an update's
first step the gradient is exactly PPO's plus beta times the JSD's; PPO's clipping then keeps
the bonus, like the reward, inside the trust region (a separate loss term would need a
clipping of its own), and the minibatches need no extra forward.
No episode-aware minibatches and no second pass over the data.
A segment cut by the end of a sample is treated as a trajectory of its own (its local
likelihoods miss the moves beyond the cut).

**Per seat.** The members are one seat's policies of the pairs (the learner's populations,
as MEP's): the JSD is that of each seat's own action-trajectories, the moves in its own
segments. A pair's joint trajectory (both seats' moves on one time axis) is not what the
sampler's per-module segments keep.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import torch


def local_log_likelihoods(logp: torch.Tensor, lengths: Sequence[int], gamma: float) -> torch.Tensor:
    """sum_t' gamma^|t-t'| logp[..., t'] within each segment, for every row t: `logp` [..., R], segments of `lengths` end to end."""
    lengths_t = torch.as_tensor(list(lengths), dtype=torch.long)
    if int(lengths_t.sum()) != logp.shape[-1] or (lengths_t < 1).any():
        raise ValueError(f"segment lengths {list(lengths)} do not cover {logp.shape[-1]} rows with non-empty segments")
    segment = torch.repeat_interleave(torch.arange(len(lengths_t)), lengths_t)
    starts = torch.cumsum(lengths_t, 0) - lengths_t
    position = torch.arange(logp.shape[-1]) - starts[segment]
    longest = int(lengths_t.max())
    # Segments padded into [..., S, T] (zeros add nothing), times the symmetric kernel gamma^|t - t'|.
    padded = logp.new_zeros((*logp.shape[:-1], len(lengths_t), longest))
    padded[..., segment, position] = logp
    steps = torch.arange(longest, dtype=logp.dtype)
    kernel = torch.pow(torch.as_tensor(gamma, dtype=logp.dtype), (steps[:, None] - steps[None, :]).abs())
    return (padded @ kernel)[..., segment, position]


@dataclass
class TrajectoryDiversity:
    """The JSD estimate (a scalar) and, per member, the weight w of each of its moves (see the module docstring)."""

    value: torch.Tensor
    weights: list[torch.Tensor]


def trajectory_diversity(logp: Sequence[torch.Tensor], lengths: Sequence[Sequence[int]], gamma: float) -> TrajectoryDiversity:
    """TrajeDi's JSD of N members, estimated on each member's own trajectories.

    `logp[i]` [N, R_i]: log pi_j(a | s) of every member j on member i's R_i moves (its
    trajectories end to end, of `lengths[i]` moves each). The weights are detached, with the
    member's mean subtracted (the baseline): they multiply log pi_i in `surrogate`.
    """
    n = len(logp)
    if len(lengths) != n or any(lp.shape[0] != n for lp in logp):
        raise ValueError(f"{n} members need {n} x [N, R_i] log-probabilities and {n} segment layouts")
    per_member, weights = [], []
    for i, (lp, segs) in enumerate(zip(logp, lengths)):
        local = local_log_likelihoods(lp, segs, gamma)  # [N, R_i]
        d = local[i] - (torch.logsumexp(local, 0) - math.log(n))
        seg_len = torch.repeat_interleave(torch.as_tensor(list(segs), dtype=d.dtype), torch.as_tensor(list(segs)))
        # Mean over each trajectory's steps, then over the member's trajectories.
        per_member.append((d / seg_len).sum() / len(segs))
        w = local_log_likelihoods((d / seg_len).detach(), segs, gamma)
        weights.append((w - w.mean()) / (n * len(segs)))
    return TrajectoryDiversity(torch.stack(per_member).mean(), weights)


def surrogate(own_logp: Sequence[torch.Tensor], weights: Sequence[torch.Tensor]) -> torch.Tensor:
    """sum_i sum_moves w_i log pi_i(a | s): its gradient is the JSD's (`own_logp[i]` [R_i], member i's log-probabilities of its moves)."""
    return sum((w.detach() * lp).sum() for lp, w in zip(own_logp, weights))
