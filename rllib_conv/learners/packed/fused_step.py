"""One optimizer step for every registered Adam at once: global-norm clipping per optimizer (or per replica), then torch's fused Adam.

RLlib's learner clips each optimizer's gradients by their global norm (`grad_clip_by=
"global_norm"`), zeroes non-finite gradients, then calls `step()` on every optimizer in
turn, paying Python overhead per optimizer and per parameter. `FusedAdamStep` does the same
arithmetic with a few tensor ops whatever the number of layers: each optimizer's parameters
and Adam moments live in flat buffers (the parameters' data are views into them), so a step
is one norm and one scale per optimizer (the gradients too are views into a flat buffer,
which backward accumulates into), then one
functional `adam` call per set of hyperparameters on torch's fused kernel (one pass over each
tensor; the foreach path makes a dozen: `benchmarks/adam_kernel.py`). Fused Adam is Adam's
arithmetic with other rounding: weights agree with RLlib's loop to float tolerance, not bit
for bit (`tests/learners/test_fused_step.py`, `tests/learners/test_fused_update.py`). The
optimizers' `state` (step counts, moments) reads as torch's Adam keeps it (views into the
flat buffers), so checkpoints and RLlib's own loop see ordinary optimizers; a state replaced
by a restored checkpoint is copied back into the buffers before the next step.

Segments: an optimizer over stacked parameters (`EgoStack`: tensors [K, ...] or
[K, H, ...]) stands for K (or K x H) optimizers of independent replicas; with
`segment_dims` > 0 its clip norm is taken per slice of those leading dims, so each replica's
gradients are clipped as they would be alone (Adam itself is elementwise).
"""

from __future__ import annotations

import warnings
from collections import defaultdict

import torch
from torch.optim.adam import Adam, adam
from torch.optim.optimizer import _get_scalar_dtype

# A parameter here can be a strided, non-dense view of its flat buffer, and `bind_grads` gives its gradient the same
# strides: backward accumulates into it in place all the same, but torch warns (once per process) that this layout is
# not the contiguous one it would have allocated. Expected here, so not shown.
warnings.filterwarnings("ignore", message="grad and param do not obey the gradient layout contract")

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


class _FlatGroup:
    """One optimizer's parameters, Adam moments and step count kept in flat buffers (see the module docstring).

    Each parameter's data becomes a view into `data` ([segment shape..., n]: every
    parameter's slice side by side along the last dim), and its Adam state (`exp_avg`,
    `exp_avg_sq`, `step`) views into `exp_avg`, `exp_avg_sq` and `steps`, so the optimizer's
    `state` still reads as torch's Adam keeps it (checkpoints, RLlib's own loop).
    """

    def __init__(self, optimizer: Adam, segment_dims: int) -> None:
        self.optimizer, self.segment_dims = optimizer, segment_dims
        self.params: list[torch.Tensor] = list(optimizer.param_groups[0]["params"])
        self.widths = [p[(0,) * segment_dims].numel() for p in self.params]
        self.data = self._flat([p.detach() for p in self.params])
        for p, view in zip(self.params, self.views(self.data)):
            p.data = view  # same values, now stored in the flat buffer the fused step updates in one call
        self._bind_state()
        self.grad: torch.Tensor | None = None  # the flat gradient buffer, once `bind_grads` made it
        self._grad_views: list[torch.Tensor] | None = None

    def _flat(self, tensors: list[torch.Tensor]) -> torch.Tensor:
        """`tensors` (shaped as the parameters) side by side in one [segment shape..., n] tensor."""
        d = self.segment_dims
        return torch.cat([t.reshape(*t.shape[:d], -1) if d else t.reshape(-1) for t in tensors], dim=-1)

    def views(self, flat: torch.Tensor) -> list[torch.Tensor]:
        """Each parameter's slice of `flat`, shaped as the parameter."""
        out, start = [], 0
        for p, width in zip(self.params, self.widths):
            out.append(flat[..., start : start + width].view(p.shape))
            start += width
        return out

    def _bind_state(self) -> None:
        """Flat Adam state from the optimizer's (restored from a checkpoint, or zeros as `Adam._init_group` makes them), then bound back to it as views."""
        states = [self.optimizer.state[p] for p in self.params]
        started = all(len(st) > 0 for st in states)
        self.exp_avg = self._flat([st["exp_avg"] for st in states]) if started else torch.zeros_like(self.data)
        self.exp_avg_sq = self._flat([st["exp_avg_sq"] for st in states]) if started else torch.zeros_like(self.data)
        first = float(states[0]["step"]) if started else 0.0
        self.steps = torch.full((len(self.params),), first, dtype=_get_scalar_dtype())
        for i, (st, m, v) in enumerate(zip(states, self.views(self.exp_avg), self.views(self.exp_avg_sq))):
            st.update(step=self.steps[i], exp_avg=m, exp_avg_sq=v)
        self._bound = states[0]["exp_avg"]

    def bind_grads(self) -> None:
        """Zero the flat gradient buffer and make each parameter's `grad` its view, so backward accumulates into it in place."""
        if self._grad_views is None:
            self.grad = torch.zeros_like(self.data)
            self._grad_views = self.views(self.grad)
        else:
            self.grad.zero_()
        for p, view in zip(self.params, self._grad_views):
            p.grad = view

    def flat_grad(self) -> torch.Tensor:
        """Every parameter's gradient in the flat layout (zeros for a parameter this loss did not reach).

        The bound buffer itself while every gradient is still its view (`bind_grads`), else a
        concatenation (another loop, e.g. RLlib's own, set the gradients to None or replaced them).
        """
        if self._grad_views is not None and all(p.grad is v for p, v in zip(self.params, self._grad_views)):
            return self.grad
        return self._flat([p.grad if p.grad is not None else torch.zeros_like(p) for p in self.params])

    def state_for_step(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(exp_avg, exp_avg_sq, step) to step with; rebound first if the optimizer's state was replaced (a restored checkpoint)."""
        if self.optimizer.state[self.params[0]].get("exp_avg") is not self._bound:
            self._bind_state()
        return self.exp_avg, self.exp_avg_sq, self.steps[0]

    def sync_steps(self) -> None:
        """Every parameter's step count equal to the one the fused call advanced."""
        self.steps[1:] = self.steps[0]


class FusedAdamStep:
    """Clip and step the Adam optimizers `optimizers` (each over its own parameters) in one go.

    Each optimizer's parameters and moments move into flat buffers on construction
    (`_FlatGroup`): a step is then one norm and one scale per optimizer and one fused Adam call
    per set of hyperparameters, whatever the number of layers. A parameter that a loss does
    not reach counts as a zero gradient (torch's Adam would skip it): the same weights where,
    as here, such a parameter is never reached (its moments stay 0) and there is no weight decay.
    """

    def __init__(self, optimizers: list[Adam], grad_clip: float | None, segments: list[int] | None = None) -> None:
        for opt in optimizers:
            if not isinstance(opt, Adam) or len(opt.param_groups) != 1:
                raise ValueError(f"FusedAdamStep needs single-group torch Adam optimizers, got {type(opt).__name__}")
            group = opt.param_groups[0]
            if group["amsgrad"] or group["fused"] or group["capturable"] or group["differentiable"] or group["weight_decay"]:
                raise ValueError(
                    "FusedAdamStep supports plain Adam only (no amsgrad, fused, capturable, differentiable or weight decay)"
                )
        self.optimizers = optimizers
        self.grad_clip = grad_clip
        self.segments = list(segments) if segments is not None else [0] * len(optimizers)
        self.groups = [_FlatGroup(opt, d) for opt, d in zip(optimizers, self.segments)]
        self.params = [p for g in self.groups for p in g.params]

    def zero_grad(self) -> None:
        """Zero every gradient, as views of each optimizer's flat gradient buffer (`_FlatGroup.bind_grads`)."""
        for group in self.groups:
            group.bind_grads()

    def _clipped(self, group: _FlatGroup) -> tuple[torch.Tensor, torch.Tensor | None]:
        """The group's flat gradient clipped by RLlib's rule per segment, and the norms before clipping (None without clipping)."""
        grad = group.flat_grad()
        norms = torch.linalg.vector_norm(grad, dim=-1)
        if not bool(torch.isfinite(norms).all()):  # RLlib's per-tensor rules, on views of the flat gradient
            return grad, clip_segments_per_tensor(group.views(grad), group.segment_dims, self.grad_clip)
        if self.grad_clip:
            grad.mul_(_coefficient(norms, self.grad_clip).unsqueeze(-1))
        return grad, norms if self.grad_clip else None

    @torch.no_grad()
    def step(self) -> list[torch.Tensor | None]:
        """Clip, then step; returns each optimizer's gradient norms before clipping (None without clipping)."""
        clipped = [self._clipped(g) for g in self.groups]
        by_hyper: dict[tuple, list[int]] = defaultdict(list)
        for i, opt in enumerate(self.optimizers):
            g = opt.param_groups[0]
            by_hyper[(g["lr"], g["betas"], g["eps"], g["maximize"], g["decoupled_weight_decay"])].append(i)
        for (lr, betas, eps, maximize, decoupled), idx in by_hyper.items():
            states = [self.groups[i].state_for_step() for i in idx]
            adam(
                [self.groups[i].data for i in idx],
                [clipped[i][0] for i in idx],
                [s[0] for s in states],
                [s[1] for s in states],
                [],
                [s[2] for s in states],
                fused=True,
                amsgrad=False,
                beta1=betas[0],
                beta2=betas[1],
                lr=lr,
                weight_decay=0.0,
                eps=eps,
                maximize=maximize,
                decoupled_weight_decay=decoupled,
            )
            for i in idx:
                self.groups[i].sync_steps()
        return [norms for _, norms in clipped]
