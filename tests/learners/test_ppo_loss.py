"""`ppo_loss` on tiny tensors against PPO's clipped surrogate, value and entropy terms computed by hand.

The expected numbers use `math` only (no torch), from the textbook definitions:
ratio = exp(logp - logp_old), surrogate = min(A ratio, A clip(ratio, 1 - eps, 1 + eps)),
value loss = min((v - target)^2, vf_clip), loss = mean(-surrogate + c_v vf - c_e entropy).
"""

from __future__ import annotations

import math

import pytest
import torch
from ray.rllib.core.columns import Columns
from ray.rllib.evaluation.postprocessing import Postprocessing

from rllib_conv.learners.ppo_loss import categorical_logp_entropy, ppo_loss

CLIP = 0.2


def batch(logp_old: list[float], advantages: list[float], targets: list[float]) -> dict:
    return {
        Columns.ACTION_LOGP: torch.tensor(logp_old),
        Postprocessing.ADVANTAGES: torch.tensor(advantages),
        Postprocessing.VALUE_TARGETS: torch.tensor(targets),
    }


# Three rows of a 2-action policy, chosen so that each branch of the clip shows:
#   row 0: logits [0, 0] -> pi = (1/2, 1/2), action 0, old pi 1/4: ratio 2, A = +1 -> clipped at 1.2
#   row 1: logits [ln 3, 0] -> pi = (3/4, 1/4), action 1, old pi 1/2: ratio 1/2, A = -2 -> clipped at 0.8: min(-1, -1.6) = -1.6
#   row 2: logits [0, ln 3] -> pi = (1/4, 3/4), action 1, old pi 3/4: ratio 1, A = 0.5 -> 0.5 (inside the clip)
LOGITS = [[0.0, 0.0], [math.log(3), 0.0], [0.0, math.log(3)]]
ACTIONS = [0, 1, 1]
LOGP_OLD = [math.log(0.25), math.log(0.5), math.log(0.75)]
ADVANTAGES = [1.0, -2.0, 0.5]
VALUES = [0.0, 1.0, -1.0]
TARGETS = [1.0, 4.0, -1.5]  # squared errors 1, 9, 0.25


def entropy(p: float) -> float:
    return -(p * math.log(p) + (1 - p) * math.log(1 - p))


# min(A ratio, A clip(ratio)) per row: min(2, 1.2); min(-2 * 0.5, -2 * 0.8); min(0.5, 0.5).
SURROGATES = [min(2.0, 1.0 + CLIP), min(-2.0 * 0.5, -2.0 * (1 - CLIP)), 0.5]
ENTROPIES = [math.log(2), entropy(0.75), entropy(0.75)]
SQUARED = [1.0, 9.0, 0.25]


def expected(vf_coeff: float, vf_clip: float, ent_coeff: float, rows: list[int]) -> dict[str, float]:
    vf = [min(SQUARED[i], vf_clip) for i in rows]
    per_row = [-SURROGATES[i] + vf_coeff * v - ent_coeff * ENTROPIES[i] for i, v in zip(rows, vf)]
    n = len(rows)
    return {
        "total": sum(per_row) / n,
        "policy_loss": -sum(SURROGATES[i] for i in rows) / n,
        "vf_loss": sum(vf) / n,
        "entropy": sum(ENTROPIES[i] for i in rows) / n,
    }


def terms(vf_coeff: float = 0.5, vf_clip: float = float("inf"), ent_coeff: float = 0.01, **kw):
    return ppo_loss(
        torch.tensor(LOGITS, requires_grad=True),
        torch.tensor(VALUES),
        torch.tensor(ACTIONS),
        batch(LOGP_OLD, ADVANTAGES, TARGETS),
        clip_param=CLIP,
        vf_loss_coeff=vf_coeff,
        vf_clip_param=vf_clip,
        entropy_coeff=ent_coeff,
        **kw,
    )


def as_floats(t) -> dict[str, float]:
    return {
        "total": t.total.item(),
        "policy_loss": t.policy_loss.item(),
        "vf_loss": t.vf_loss.item(),
        "entropy": t.entropy.item(),
    }


def test_the_hand_computed_clipped_surrogate_value_and_entropy() -> None:
    assert SURROGATES == pytest.approx([1.2, -1.6, 0.5])
    got = as_floats(terms())
    want = expected(0.5, float("inf"), 0.01, [0, 1, 2])
    assert got == pytest.approx(want, rel=1e-6)
    # Spelled out once: policy loss -(1.2 - 1.6 + 0.5) / 3 = -0.0333..., value loss (1 + 9 + 0.25) / 3 = 3.41666...
    assert got["policy_loss"] == pytest.approx(-0.1 / 3, rel=1e-6) and got["vf_loss"] == pytest.approx(10.25 / 3, rel=1e-6)


@pytest.mark.parametrize(("vf_coeff", "vf_clip", "ent_coeff"), [(1.0, 4.0, 0.0), (0.0, float("inf"), 0.5), (2.0, 0.5, 0.1)])
def test_the_coefficients_and_the_value_clip(vf_coeff: float, vf_clip: float, ent_coeff: float) -> None:
    assert as_floats(terms(vf_coeff, vf_clip, ent_coeff)) == pytest.approx(
        expected(vf_coeff, vf_clip, ent_coeff, [0, 1, 2]), rel=1e-6
    )


def test_a_clipped_row_passes_no_policy_gradient() -> None:
    # Rows 0 and 1 sit on the clip boundary's flat side: d(surrogate)/d(logits) is 0 there; row 2 is inside the clip.
    logits = torch.tensor(LOGITS, requires_grad=True)
    out = ppo_loss(
        logits,
        torch.tensor(VALUES),
        torch.tensor(ACTIONS),
        batch(LOGP_OLD, ADVANTAGES, TARGETS),
        clip_param=CLIP,
        vf_loss_coeff=0.5,
        vf_clip_param=float("inf"),
        entropy_coeff=0.0,
    )
    out.total.backward()
    assert torch.equal(logits.grad[0], torch.zeros(2)) and torch.equal(logits.grad[1], torch.zeros(2))
    # Row 2: d(-A ratio / 3)/d logit_1 = -(A / 3) * ratio * (1 - pi_1) = -(0.5 / 3) * 1 * 0.25; logit_0 the opposite.
    torch.testing.assert_close(logits.grad[2], torch.tensor([0.5 / 3 * 0.25, -0.5 / 3 * 0.25]))


def test_valid_rows_give_one_mean_per_module() -> None:
    # Two modules stacked [2, 3]: module 0 has rows 0, 1, 2; module 1 only rows 0 and 2 (its middle row is padding).
    stacked = lambda xs: torch.tensor([xs, xs])  # noqa: E731
    out = ppo_loss(
        stacked(LOGITS),
        stacked(VALUES),
        stacked(ACTIONS),
        batch([LOGP_OLD, LOGP_OLD], [ADVANTAGES, ADVANTAGES], [TARGETS, TARGETS]),
        clip_param=CLIP,
        vf_loss_coeff=0.5,
        vf_clip_param=float("inf"),
        entropy_coeff=0.01,
        valid=torch.tensor([[True, True, True], [True, False, True]]),
    )
    assert out.total.shape == (2,)
    for module, rows in enumerate([[0, 1, 2], [0, 2]]):
        got = {k: getattr(out, k)[module].item() for k in ("total", "policy_loss", "vf_loss", "entropy")}
        assert got == pytest.approx(expected(0.5, float("inf"), 0.01, rows), rel=1e-6)


def test_a_module_with_no_valid_row_has_zero_loss_not_nan() -> None:
    out = ppo_loss(
        torch.tensor([LOGITS]),
        torch.tensor([VALUES]),
        torch.tensor([ACTIONS]),
        batch([LOGP_OLD], [ADVANTAGES], [TARGETS]),
        clip_param=CLIP,
        vf_loss_coeff=0.5,
        vf_clip_param=float("inf"),
        entropy_coeff=0.01,
        valid=torch.zeros(1, 3, dtype=torch.bool),
    )
    assert out.total.tolist() == [0.0] and out.vf_loss.tolist() == [0.0]


def test_logp_and_entropy_are_the_categorical_ones_masked_actions_included() -> None:
    logits = torch.tensor([[1.0, -0.5, 2.0, 0.0], [0.3, torch.finfo(torch.float32).min, 0.3, -1.0]])
    actions = torch.tensor([2, 3])
    logp, ent = categorical_logp_entropy(logits, actions)
    reference = torch.distributions.Categorical(logits=logits)
    torch.testing.assert_close(logp, reference.log_prob(actions))
    torch.testing.assert_close(ent, reference.entropy())
    # By hand, row 1 (its second action masked away): probabilities e^0.3 : e^0.3 : e^-1 over three actions.
    w = [math.exp(0.3), math.exp(0.3), math.exp(-1.0)]
    p = [x / sum(w) for x in w]
    assert logp[1].item() == pytest.approx(math.log(p[2]), rel=1e-6)
    assert ent[1].item() == pytest.approx(-sum(q * math.log(q) for q in p), rel=1e-6)
    assert torch.isfinite(ent).all()
