"""`FusedAdamStep` against torch's own Adam: per-replica clipping by hand, then `torch.optim.Adam.step()`, step for step."""

from __future__ import annotations

import copy

import pytest
import torch

from rllib_conv.learners.packed.fused_step import FusedAdamStep, clip_segments, clip_segments_per_tensor


def _grads(shapes: list[tuple[int, ...]], step: int) -> list[torch.Tensor]:
    g = torch.Generator().manual_seed(100 + step)
    # Replica 0's gradients are large (clipped), replica 1's small (not clipped).
    return [torch.randn(s, generator=g) * torch.tensor([30.0, 0.01]).reshape(2, *([1] * (len(s) - 1))) for s in shapes]


@pytest.mark.parametrize("grad_clip", [None, 1.0])
def test_fused_step_equals_torch_adam_with_each_replica_clipped_alone(grad_clip: float | None) -> None:
    shapes = [(2, 3, 4), (2, 3), (2, 5, 2, 3)]
    start = [torch.randn(s, generator=torch.Generator().manual_seed(i)) for i, s in enumerate(shapes)]
    # Two optimizers, as the stack has (task, heads), with different learning rates.
    ours = [torch.nn.Parameter(t.clone()) for t in start]
    fused = FusedAdamStep(
        [torch.optim.Adam(ours[:2], lr=0.01, eps=1e-5), torch.optim.Adam(ours[2:], lr=0.003)], grad_clip, segments=[1, 1]
    )
    # The reference: each replica its own pair of torch Adams, clipped by RLlib's global-norm rule on its own gradients.
    ref = [[torch.nn.Parameter(t[r].clone()) for t in start] for r in range(2)]
    ref_opts = [[torch.optim.Adam(p[:2], lr=0.01, eps=1e-5), torch.optim.Adam(p[2:], lr=0.003)] for p in ref]
    for step in range(4):
        grads = _grads(shapes, step)
        for p, g in zip(ours, grads):
            p.grad = g.clone()
        norms = fused.step()
        for r in range(2):
            for offset, opt in zip((0, 2), ref_opts[r]):
                params = ref[r][offset : offset + 2]
                for i, p in enumerate(params):
                    p.grad = grads[offset + i][r].clone()
                if grad_clip is not None:
                    norm = torch.linalg.vector_norm(torch.stack([torch.linalg.vector_norm(p.grad) for p in params]))
                    for p in params:
                        p.grad.mul_(min(1.0, grad_clip / max(float(norm) + 1e-6, grad_clip)))
                opt.step()
        if grad_clip is None:
            assert norms == [None, None]
        else:
            assert norms[0].shape == (2,) and float(norms[0][0]) > grad_clip > float(norms[0][1])
        for i, p in enumerate(ours):
            for r in range(2):
                torch.testing.assert_close(
                    p.detach()[r], ref[r][i].detach(), rtol=1e-6, atol=1e-7, msg=f"param {i} replica {r} step {step}"
                )
    # The moments live in the optimizers' own state, as torch.optim.Adam keeps them (checkpoints read them).
    state = fused.optimizers[0].state[ours[0]]
    assert int(state["step"]) == 4 and state["exp_avg"].shape == shapes[0]


def test_non_finite_gradients_follow_rllibs_rules_per_tensor() -> None:
    """Hand-computed: a tensor norm that is inf is capped at 1e9, a NaN one counts 0; after clipping, non-finite entries are replaced."""
    a = torch.tensor([[float("inf"), 1.0, 1.0], [0.1, 0.1, 0.1]])
    b = torch.tensor([[1.0, 1.0], [float("nan"), 0.2]])
    norms = clip_segments([a, b], 1, 1.0)
    # Replica 0: tensor norms (inf -> 1e9, sqrt 2) -> global 1e9 -> coefficient 1e-9. Replica 1: (sqrt 0.03, NaN -> 0) -> 0.1732, not clipped.
    torch.testing.assert_close(norms, torch.tensor([1e9, 0.03**0.5]))
    big = torch.finfo(torch.float32).max
    torch.testing.assert_close(a, torch.tensor([[big, 1e-9, 1e-9], [0.1, 0.1, 0.1]]))
    torch.testing.assert_close(b, torch.tensor([[1e-9, 1e-9], [0.0, 0.2]]))


def test_one_norm_over_all_tensors_equals_rllibs_norm_of_tensor_norms() -> None:
    """The fast path's norm (one reduction over every tensor) and the per-tensor one agree to float tolerance, and both clip alike."""
    g = torch.Generator().manual_seed(0)
    grads = [torch.randn(3, *s, generator=g) * 5 for s in [(4, 5), (4,), (2, 4, 4)]]
    fast, slow = [t.clone() for t in grads], [t.clone() for t in grads]
    torch.testing.assert_close(clip_segments(fast, 1, 0.5), clip_segments_per_tensor(slow, 1, 0.5))
    for f, s in zip(fast, slow):
        torch.testing.assert_close(f, s)


def test_a_restored_optimizer_state_is_the_one_the_next_step_uses() -> None:
    """A checkpoint's Adam state loaded after steps were taken (its tensors replace the flat buffers' views) drives the next step."""
    shapes = [(2, 3, 4), (2, 3)]
    start = [torch.randn(s, generator=torch.Generator().manual_seed(i)) for i, s in enumerate(shapes)]
    ours = [torch.nn.Parameter(t.clone()) for t in start]
    opt = torch.optim.Adam(ours, lr=0.01)
    fused = FusedAdamStep([opt], 1.0, segments=[1])
    ref = [torch.nn.Parameter(t.clone()) for t in start]
    ref_opt = torch.optim.Adam(ref, lr=0.01)
    for step in range(3):
        grads = _grads(shapes, step)
        if step == 1:  # ours takes a stray step, then gets the reference's state back as a restored checkpoint would
            for p in ours:
                p.grad = torch.ones_like(p)
            fused.step()
            opt.load_state_dict(copy.deepcopy(ref_opt.state_dict()))
            with torch.no_grad():
                for p, r in zip(ours, ref):
                    p.copy_(r)
        for p, r, g in zip(ours, ref, grads):
            p.grad, r.grad = g.clone(), g.clone()
        fused.step()
        for r in range(2):  # the reference clips each replica alone
            norm = torch.linalg.vector_norm(torch.cat([p.grad[r].flatten() for p in ref]))
            for p in ref:
                p.grad[r].mul_(min(1.0, 1.0 / max(float(norm) + 1e-6, 1.0)))
        ref_opt.step()
        for p, r in zip(ours, ref):
            torch.testing.assert_close(p.detach(), r.detach(), rtol=1e-6, atol=1e-7, msg=f"step {step}")
    assert int(opt.state[ours[0]]["step"]) == int(ref_opt.state[ref[0]]["step"]) == 3


def test_backward_accumulates_into_the_flat_gradient_buffer_with_the_same_weights() -> None:
    """`zero_grad` binds each gradient to a view of a flat buffer: backward fills it in place (no concatenation per
    step), and the weights equal those of the concatenating path bit for bit, an unreached parameter counting as 0."""
    shapes = [(2, 3, 4), (2, 3), (2, 4)]  # the last one no loss reaches
    start = [torch.randn(s, generator=torch.Generator().manual_seed(i)) for i, s in enumerate(shapes)]
    x = torch.randn(2, 5, 4, generator=torch.Generator().manual_seed(9))

    def run(bound: bool) -> tuple[list[torch.Tensor], FusedAdamStep]:
        params = [torch.nn.Parameter(t.clone()) for t in start]
        fused = FusedAdamStep([torch.optim.Adam(params[:2], lr=0.01), torch.optim.Adam(params[2:], lr=0.01)], 1.0, [1, 1])
        for _ in range(5):
            fused.zero_grad()
            if not bound:  # what another loop (RLlib's own) leaves: no gradient tensors, so the step concatenates
                for p in params:
                    p.grad = None
            loss = (torch.tanh(torch.bmm(x, params[0].transpose(1, 2)) + params[1].unsqueeze(1)) ** 2).sum()
            loss.backward()
            if bound:
                assert all(group.flat_grad() is group.grad for group in fused.groups)
            fused.step()
        return params, fused

    (bound, fused), (concatenated, _) = run(True), run(False)
    for a, b in zip(bound, concatenated):
        assert torch.equal(a.detach(), b.detach())
    assert torch.equal(bound[2].detach(), start[2])  # never reached: Adam's zero gradient moves nothing
    assert fused.groups[0].grad.shape == (2, 3 * 4 + 3)
