"""One optimizer step for every registered Adam at once: global-norm clipping per optimizer (or per replica), then torch's fused Adam.

RLlib's learner clips each optimizer's gradients by their global norm (`grad_clip_by=
"global_norm"`), zeroes non-finite gradients, then calls `step()` on every optimizer in
turn, paying Python overhead per optimizer and per parameter. `FusedAdamStep` does the same
arithmetic with a few tensor ops: one clip coefficient per optimizer, then one functional
`adam` call per group of optimizers sharing their hyperparameters, on torch's fused kernel
(one pass over each tensor; the foreach path makes a dozen: the Adam call alone takes ~2.7x
as long on the bandit's 30-unit nets, a whole learner update 1.03-1.2x,
`benchmarks/adam_kernel.py`). Fused Adam is Adam's arithmetic
with other rounding: weights agree with RLlib's loop to float tolerance, not bit for bit
(`tests/learners/test_fused_step.py`, `tests/learners/test_fused_update.py`). The optimizers' `state`
(step counts, moments) is theirs, initialised exactly as `torch.optim.Adam` does, so
checkpoints and RLlib's own loop see ordinary optimizers.

Segments: an optimizer over stacked parameters (`EgoStack`: tensors [K, ...] or
[K, H, ...]) stands for K (or K x H) optimizers of independent replicas; with
`segment_dims` > 0 its clip norm is taken per slice of those leading dims, so each replica's
gradients are clipped as they would be alone (Adam itself is elementwise).
"""

from __future__ import annotations

from collections import defaultdict

import torch
from torch.optim.adam import Adam, adam
from torch.optim.optimizer import _get_scalar_dtype

# RLlib's clip: coefficient = clip / max(norm + 1e-6, clip), and per-tensor norms capped like this.
_EPS = 1e-6
_NORM_CAP = 10e8


def segment_norms(grads: list[torch.Tensor], segment_dims: int) -> tuple[torch.Tensor, torch.Tensor]:
    """The global gradient norm of each segment (the slices of the first `segment_dims` dims), as RLlib computes it.

    Returns (norms [segment shape], each tensor's own norms [T, segment shape] before capping).
    """
    per = torch.stack([torch.linalg.vector_norm(g.flatten(segment_dims) if segment_dims else g.flatten(), dim=-1) for g in grads])
    return per.nan_to_num(neginf=-_NORM_CAP, posinf=_NORM_CAP).pow(2).sum(0).sqrt(), per


def _scale(grads: list[torch.Tensor], coeff: torch.Tensor, segment_dims: int) -> None:
    """Multiply each gradient in place by its segment's coefficient (`coeff`: [segment shape]), in one foreach op."""
    shaped = {nd: coeff.reshape(*coeff.shape, *([1] * (nd - segment_dims))) for nd in {g.dim() for g in grads}}
    torch._foreach_mul_(grads, [shaped[g.dim()] for g in grads])


def _coefficient(norms: torch.Tensor, grad_clip: float) -> torch.Tensor:
    """RLlib's clip coefficient of each segment: clip / max(norm + 1e-6, clip)."""
    return torch.clamp(grad_clip / torch.clamp(norms + _EPS, min=grad_clip), max=1.0)


@torch.no_grad()
def clip_segments(grads: list[torch.Tensor], segment_dims: int, grad_clip: float | None) -> torch.Tensor | None:
    """Clip one optimizer's `grads` in place, segment by segment (see `segment_norms`); zero non-finite ones as RLlib does.

    Returns the norms before clipping (None without clipping).
    """
    if not grads:
        return None
    # One norm over every tensor at once: a minibatch step pays per tensor op, and RLlib's
    # norm of per-tensor norms is the same number (other rounding). Its per-tensor rules
    # (capped norms, non-finite gradients) matter only when this norm is not finite.
    norms = torch.linalg.vector_norm(torch.cat([g.reshape(*g.shape[:segment_dims], -1) for g in grads], dim=-1), dim=-1)
    if not bool(torch.isfinite(norms).all()):
        return clip_segments_per_tensor(grads, segment_dims, grad_clip)
    if grad_clip:
        _scale(grads, _coefficient(norms, grad_clip), segment_dims)
    return norms if grad_clip else None


def clip_segments_per_tensor(grads: list[torch.Tensor], segment_dims: int, grad_clip: float | None) -> torch.Tensor | None:
    """`clip_segments` by RLlib's rules tensor by tensor: norms capped per tensor, non-finite gradients replaced after clipping."""
    norms, per = segment_norms(grads, segment_dims)
    if grad_clip:
        _scale(grads, _coefficient(norms, grad_clip), segment_dims)
    finite = torch.isfinite(per.flatten(1) if per.dim() > 1 else per)
    bad = ~finite.all(dim=-1) if finite.dim() > 1 else ~finite
    for i in torch.nonzero(bad).flatten().tolist():  # RLlib zeroes non-finite gradients after clipping
        grads[i].copy_(torch.nan_to_num(grads[i]))
    return norms if grad_clip else None


class FusedAdamStep:
    """Clip and step the Adam optimizers `optimizers` (each over its own parameters) in one go."""

    def __init__(self, optimizers: list[Adam], grad_clip: float | None, segments: list[int] | None = None) -> None:
        for opt in optimizers:
            if not isinstance(opt, Adam) or len(opt.param_groups) != 1:
                raise ValueError(f"FusedAdamStep needs single-group torch Adam optimizers, got {type(opt).__name__}")
            group = opt.param_groups[0]
            if group["amsgrad"] or group["fused"] or group["capturable"] or group["differentiable"]:
                raise ValueError("FusedAdamStep supports plain Adam only (no amsgrad, fused, capturable or differentiable)")
        self.optimizers = optimizers
        self.grad_clip = grad_clip
        self.segments = list(segments) if segments is not None else [0] * len(optimizers)
        self.params = [p for opt in optimizers for p in opt.param_groups[0]["params"]]
        # Which optimizer each parameter belongs to.
        self.owner = [i for i, opt in enumerate(optimizers) for _ in opt.param_groups[0]["params"]]

    def zero_grad(self) -> None:
        """Drop every gradient (as `zero_grad(set_to_none=True)`)."""
        for p in self.params:
            p.grad = None

    def _state(self, i: int) -> dict:
        """Adam's state of parameter `i`, created as `Adam._init_group` creates it on the parameter's first step.

        Looked up at every step: restoring a checkpoint replaces the state tensors.
        """
        p = self.params[i]
        state = self.optimizers[self.owner[i]].state[p]
        if len(state) == 0:
            state["step"] = torch.tensor(0.0, dtype=_get_scalar_dtype(), device="cpu")
            state["exp_avg"] = torch.zeros_like(p, memory_format=torch.preserve_format)
            state["exp_avg_sq"] = torch.zeros_like(p, memory_format=torch.preserve_format)
        return state

    def _groups(self) -> dict[tuple, list[int]]:
        """Parameter indices by Adam hyperparameters (lr, betas, eps, weight decay, maximize)."""
        out: dict[tuple, list[int]] = defaultdict(list)
        i = 0
        for opt in self.optimizers:
            g = opt.param_groups[0]
            key = (g["lr"], g["betas"], g["eps"], g["weight_decay"], g["maximize"], g["decoupled_weight_decay"])
            for _ in g["params"]:
                out[key].append(i)
                i += 1
        return out

    @torch.no_grad()
    def step(self) -> list[torch.Tensor | None]:
        """Clip, then step; returns each optimizer's gradient norms before clipping (None without clipping).

        Parameters without a gradient (not reached by this loss) are skipped, as
        `torch.optim.Adam` skips them: their moments and step counts stay as they are.
        """
        norms = []
        for opt, segment_dims in zip(self.optimizers, self.segments):
            grads = [p.grad for p in opt.param_groups[0]["params"] if p.grad is not None]
            norms.append(clip_segments(grads, segment_dims, self.grad_clip))
        live = [i for i, p in enumerate(self.params) if p.grad is not None]
        position = {i: j for j, i in enumerate(live)}
        states = [self._state(i) for i in live]
        for (lr, betas, eps, weight_decay, maximize, decoupled), idx in self._groups().items():
            idx = [position[i] for i in idx if i in position]
            if not idx:
                continue
            adam(
                [self.params[live[j]] for j in idx],
                [self.params[live[j]].grad for j in idx],
                [states[j]["exp_avg"] for j in idx],
                [states[j]["exp_avg_sq"] for j in idx],
                [],
                [states[j]["step"] for j in idx],
                fused=True,
                amsgrad=False,
                beta1=betas[0],
                beta2=betas[1],
                lr=lr,
                weight_decay=weight_decay,
                eps=eps,
                maximize=maximize,
                decoupled_weight_decay=decoupled,
            )
        return norms
