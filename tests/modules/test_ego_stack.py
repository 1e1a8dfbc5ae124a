"""`EgoStack` against what it stands for: K plain `TaskModule`s and K x H plain `PartnerHeadModule`s.

Each replica's slice of the stacked tensors must be the weights a plain module built from
the same seed starts with, and every batched forward pass must give, row for row, what
the plain modules give; a zero-weight stack is checked against outputs computed by hand.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch

from rllib_conv.modules.packed import ego_stack as ego_stack_module
from rllib_conv.modules.packed.ego_stack import EgoStack, group_runs, pad_rows, subset_linear, summed_head_state, unpad
from rllib_conv.modules.partner_head import PartnerHeadModule
from rllib_conv.modules.task_module import TaskModule

OBS_DIM, ACTIONS, HIDDEN = 5, 4, 6
OBS_SPACE = gym.spaces.Box(-1.0, 1.0, (OBS_DIM,), np.float32)
ACT_SPACE = gym.spaces.Discrete(ACTIONS)
TASK_SEEDS = [11, 12]
HEAD_SEEDS = [[21, 22, 23], [31, 32, 33]]  # K = 2 replicas, H = 3 heads each
FLOAT_MIN = torch.finfo(torch.float32).min


def stack(
    use_task_logits: bool = True, sample_seeds: tuple[int, ...] = (5, 6), members: list[list[int]] | None = None
) -> EgoStack:
    head = {"hidden": HIDDEN, "use_task_logits": use_task_logits}
    return EgoStack(
        observation_space=OBS_SPACE,
        action_space=ACT_SPACE,
        model_config={
            "replicas": len(TASK_SEEDS),
            "heads": len(members or HEAD_SEEDS[0]),
            "head_members": members,
            "task": {"hidden": HIDDEN},
            "head": head,
            "task_seeds": TASK_SEEDS,
            "head_seeds": HEAD_SEEDS,
            "sample_seeds": list(sample_seeds),
        },
    )


def plain_task(seed: int) -> TaskModule:
    return TaskModule(observation_space=OBS_SPACE, action_space=ACT_SPACE, model_config={"hidden": HIDDEN, "init_seed": seed})


def plain_head(seed: int, use_task_logits: bool = True) -> PartnerHeadModule:
    config = {"hidden": HIDDEN, "use_task_logits": use_task_logits, "init_seed": seed}
    return PartnerHeadModule(observation_space=OBS_SPACE, action_space=ACT_SPACE, model_config=config)


def rows(n: int = 7, groups: int = 2, seed: int = 0) -> torch.Tensor:
    return torch.randn(groups, n, OBS_DIM, generator=torch.Generator().manual_seed(seed))


def assert_same_state(got: dict[str, torch.Tensor], want: dict[str, torch.Tensor]) -> None:
    assert sorted(got) == sorted(want)
    for key in want:
        torch.testing.assert_close(got[key], want[key], rtol=0, atol=0, msg=key)


def test_each_replica_starts_with_the_weights_of_a_plain_module_of_its_seed() -> None:
    ego = stack()
    for r, seed in enumerate(TASK_SEEDS):
        assert_same_state(ego.task_state(r), plain_task(seed).state_dict())
        for h, head_seed in enumerate(HEAD_SEEDS[r]):
            assert_same_state(ego.head_state(r, h), plain_head(head_seed).state_dict())
    # Different seeds, different weights: the comparison above could fail.
    assert not torch.equal(ego.task_state(0)["pi_tower.0.weight"], ego.task_state(1)["pi_tower.0.weight"])


def test_parameters_are_stacked_per_replica_and_per_head() -> None:
    ego = stack()
    task, heads = ego.task_parameters(), ego.head_parameters()
    assert len(task) == 12 and all(p.shape[0] == 2 for p in task)  # 6 Linear layers x (weight, bias)
    assert len(heads) == 12 and all(p.shape[:2] == (2, 3) for p in heads)
    z_only = ego.task_parameters(z_only=True)
    assert len(z_only) == 4 and all(any(p is q for q in task) for p in z_only)  # the policy tower's two layers
    assert {id(p) for p in task + heads} == {id(p) for p in ego.parameters()}


def test_task_forward_matches_the_plain_task_modules_row_for_row() -> None:
    ego = stack()
    obs = rows()
    mask = torch.ones(2, 7, ACTIONS)
    mask[:, 0, 1] = 0.0  # one illegal action on the first row
    out = ego.task_forward(obs, mask)
    for r, seed in enumerate(TASK_SEEDS):
        plain = plain_task(seed)
        want = plain.policy(obs[r], mask[r])
        torch.testing.assert_close(out.z[r], want.z)
        torch.testing.assert_close(out.logits[r], want.logits)
        torch.testing.assert_close(out.value[r], plain.value(obs[r]))
    assert (out.logits[:, 0, 1] == FLOAT_MIN).all()


def test_task_forward_runs_the_replicas_asked_for() -> None:
    ego = stack()
    obs = rows(groups=3)
    out = ego.task_forward(obs, None, replicas=torch.tensor([1, 0, 1]))
    for g, r in enumerate([1, 0, 1]):
        torch.testing.assert_close(out.logits[g], plain_task(TASK_SEEDS[r]).policy(obs[g], None).logits)


@pytest.mark.parametrize("use_task_logits", [True, False])
def test_heads_and_policy_logits_match_the_plain_heads(use_task_logits: bool) -> None:
    ego = stack(use_task_logits)
    obs = rows()
    task = ego.task_forward(obs, None)
    head_out = ego.head_outputs(task.z)  # [K, H, N, A]
    values = ego.head_values(task.z.repeat_interleave(3, dim=0)).reshape(2, 3, -1)  # group r*H + h runs head h of replica r
    assert head_out.shape == (2, 3, 7, ACTIONS)
    for r in range(2):
        for h, seed in enumerate(HEAD_SEEDS[r]):
            plain = plain_head(seed, use_task_logits)
            torch.testing.assert_close(head_out[r, h], plain.pi(task.z[r]))
            torch.testing.assert_close(values[r, h], plain.vf(task.z[r]).squeeze(-1))
            logits = ego.policy_logits(head_out[r, h], task.logits[r], None)
            torch.testing.assert_close(logits, plain.logits(task.z[r], task.logits[r], None))
    expected = head_out + task.logits.unsqueeze(1) if use_task_logits else head_out
    torch.testing.assert_close(ego.policy_logits(head_out, task.logits.unsqueeze(1), None), expected)


def test_head_values_pick_heads_by_flat_index() -> None:
    ego = stack()
    z = ego.task_forward(rows(groups=2), None).z
    picked = ego.head_values(z, heads=torch.tensor([5, 0]))  # replica 1 head 2; replica 0 head 0
    torch.testing.assert_close(picked[0], plain_head(HEAD_SEEDS[1][2]).vf(z[0]).squeeze(-1))
    torch.testing.assert_close(picked[1], plain_head(HEAD_SEEDS[0][0]).vf(z[1]).squeeze(-1))


def test_task_forward_without_the_value_tower_gives_the_same_policy() -> None:
    ego = stack()
    obs, mask = rows(), torch.ones(2, 7, ACTIONS)
    full, lean = ego.task_forward(obs, mask), ego.task_forward(obs, mask, value=False)
    assert lean.value is None and full.value is not None
    assert torch.equal(lean.z, full.z) and torch.equal(lean.logits, full.logits)


def test_group_runs_splits_ids_into_consecutive_runs() -> None:
    assert group_runs([0, 1, 2, 5, 6, 2, 2, 3]) == [(0, 0, 3), (3, 5, 2), (5, 2, 1), (6, 2, 2)]
    assert group_runs([]) == []


@pytest.mark.parametrize("groups", [[0, 2, 4], [1, 2, 3, 4], [5, 0, 1, 1], [3]])
def test_a_subset_of_wide_layers_on_views_gives_the_products_of_the_copied_weights(groups: list[int]) -> None:
    """Layers of 256 x 256 and more run on views of the weights, one matmul per run: the very numbers of the copy."""
    gen = torch.Generator().manual_seed(0)
    weight, bias = torch.randn(6, 256, 256, generator=gen), torch.randn(6, 256, generator=gen)
    x = torch.randn(len(groups), 3, 256, generator=gen)
    picked = torch.tensor(groups)
    want = torch.baddbmm(bias[picked].unsqueeze(1), x, weight[picked].transpose(1, 2))
    assert weight[0].numel() >= ego_stack_module.VIEWS_FROM
    assert torch.equal(subset_linear(x, weight, bias, picked), want)


@pytest.mark.parametrize("views_from", [0, 10**9])
def test_acting_on_a_subset_of_heads_and_replicas_is_the_same_either_way(monkeypatch, views_from: int) -> None:
    """The stack's subset forward passes (acting) on views and on copies: the same as the plain modules."""
    monkeypatch.setattr(ego_stack_module, "VIEWS_FROM", views_from)
    ego = stack()
    obs = rows(groups=3)
    task = ego.task_forward(obs, None, replicas=torch.tensor([1, 0, 1]))
    for g, r in enumerate([1, 0, 1]):
        torch.testing.assert_close(task.logits[g], plain_task(TASK_SEEDS[r]).policy(obs[g], None).logits)
    picked = ego.head_values(task.z, heads=torch.tensor([5, 0, 4]))  # replica 1 head 2, replica 0 head 0, replica 1 head 1
    for g, seed in enumerate([HEAD_SEEDS[1][2], HEAD_SEEDS[0][0], HEAD_SEEDS[1][1]]):
        torch.testing.assert_close(picked[g], plain_head(seed).vf(task.z[g]).squeeze(-1))


# Seat heads (`model.heads: seat`): 4 team heads over the 3 weight heads, two seats each (the last repeats one).
MEMBERS = [[0, 1], [0, 2], [1, 2], [2, 2]]


@pytest.mark.parametrize("use_task_logits", [True, False])
def test_a_head_of_several_members_adds_their_outputs(use_task_logits: bool) -> None:
    ego = stack(use_task_logits, members=MEMBERS)
    obs = rows()
    task = ego.task_forward(obs, None)
    head_out = ego.head_outputs(task.z)  # [K, 4, N, A]
    values = ego.head_values(task.z.repeat_interleave(4, dim=0)).reshape(2, 4, -1)
    assert head_out.shape == (2, 4, 7, ACTIONS) and [p.shape[:2] for p in ego.head_parameters()] == [(2, 3)] * 12
    for r in range(2):
        plain = [plain_head(seed, use_task_logits) for seed in HEAD_SEEDS[r]]
        for h, (a, b) in enumerate(MEMBERS):
            torch.testing.assert_close(head_out[r, h], plain[a].pi(task.z[r]) + plain[b].pi(task.z[r]))
            torch.testing.assert_close(values[r, h], (plain[a].vf(task.z[r]) + plain[b].vf(task.z[r])).squeeze(-1))
    picked = ego.head_values(task.z, heads=torch.tensor([7, 1]))  # replica 1 head 3; replica 0 head 1
    torch.testing.assert_close(picked[0], 2 * plain_head(HEAD_SEEDS[1][2]).vf(task.z[0]).squeeze(-1))
    want = plain_head(HEAD_SEEDS[0][0]).vf(task.z[1]) + plain_head(HEAD_SEEDS[0][2]).vf(task.z[1])
    torch.testing.assert_close(picked[1], want.squeeze(-1))


def test_a_head_of_several_members_is_saved_as_one_plain_head_as_wide_as_all_of_them() -> None:
    ego = stack(members=MEMBERS)
    z = ego.task_forward(rows(), None).z
    head_out = ego.head_outputs(z)
    values = ego.head_values(z.repeat_interleave(4, dim=0)).reshape(2, 4, -1)
    for r in range(2):
        for h in range(4):
            wide = PartnerHeadModule(
                observation_space=OBS_SPACE, action_space=ACT_SPACE, model_config={"hidden": 2 * HIDDEN, "z_dim": HIDDEN}
            )
            wide.load_state_dict(ego.head_state(r, h))
            torch.testing.assert_close(wide.pi(z[r]), head_out[r, h])
            torch.testing.assert_close(wide.vf(z[r]).squeeze(-1), values[r, h])
    with pytest.raises(ValueError, match="does not split"):
        ego.load_head(0, 0, ego.head_state(0, 0))


def test_summing_one_head_state_returns_it_and_two_are_block_diagonal() -> None:
    one, two = plain_head(21).state_dict(), plain_head(22).state_dict()
    assert_same_state(summed_head_state([one]), one)
    wide = summed_head_state([one, two])
    assert wide["pi.2.weight"].shape == (2 * HIDDEN, 2 * HIDDEN)
    assert (wide["pi.2.weight"][:HIDDEN, HIDDEN:] == 0).all() and (wide["pi.2.weight"][HIDDEN:, :HIDDEN] == 0).all()
    torch.testing.assert_close(wide["vf.4.bias"], one["vf.4.bias"] + two["vf.4.bias"])


@pytest.mark.parametrize("members", [[[0, 1], [2]], [[0, 3]]])
def test_head_members_that_differ_in_size_or_name_no_weight_head_are_refused(members: list[list[int]]) -> None:
    with pytest.raises(ValueError, match="head_members"):
        stack(members=members)


def test_zero_weights_give_the_hand_computed_outputs() -> None:
    # With every weight 0 each layer outputs its bias: z = relu(b2), task logits = b_out, value = b_vf3;
    # a head's logits = its last bias, its value = its last bias, the policy = task logits + head logits.
    ego = stack()
    task = {k: torch.zeros_like(v) for k, v in ego.task_state(1).items()}
    task["pi_tower.2.bias"] = torch.tensor([1.0, -2.0, 3.0, -4.0, 5.0, -6.0])
    task["pi_out.0.bias"] = torch.tensor([0.5, 0.0, -0.5, 1.0])
    task["vf.4.bias"] = torch.tensor([2.5])
    head = {k: torch.zeros_like(v) for k, v in ego.head_state(1, 2).items()}
    head["pi.4.bias"] = torch.tensor([1.0, 2.0, 3.0, 4.0])
    head["vf.4.bias"] = torch.tensor([-1.0])
    ego.load_task(1, task)
    ego.load_head(1, 2, head)
    out = ego.task_forward(rows(n=3, groups=1), None, replicas=torch.tensor([1]))
    torch.testing.assert_close(out.z[0], torch.tensor([[1.0, 0.0, 3.0, 0.0, 5.0, 0.0]] * 3))
    torch.testing.assert_close(out.logits[0], torch.tensor([[0.5, 0.0, -0.5, 1.0]] * 3))
    torch.testing.assert_close(out.value[0], torch.tensor([2.5] * 3))
    head_out = ego.head_outputs(torch.cat([torch.zeros_like(out.z), out.z]))[1, 2]
    torch.testing.assert_close(ego.policy_logits(head_out, out.logits[0], None), torch.tensor([[1.5, 2.0, 2.5, 5.0]] * 3))
    torch.testing.assert_close(ego.head_values(out.z, heads=torch.tensor([5]))[0], torch.tensor([-1.0] * 3))


def test_load_writes_one_replica_in_place_and_reads_back() -> None:
    ego = stack()
    before = [p.detach().clone() for p in ego.parameters()]
    params = list(ego.parameters())
    other_task, other_head = plain_task(99).state_dict(), plain_head(98).state_dict()
    untouched_task, untouched_head = ego.task_state(0), ego.head_state(1, 0)
    ego.load_task(1, other_task)
    ego.load_head(1, 1, other_head)
    assert_same_state(ego.task_state(1), other_task)
    assert_same_state(ego.head_state(1, 1), other_head)
    assert_same_state(ego.task_state(0), untouched_task)
    assert_same_state(ego.head_state(1, 0), untouched_head)
    assert all(p is q for p, q in zip(params, ego.parameters()))  # same tensors: an optimizer keeps them
    assert any(not torch.equal(p, b) for p, b in zip(ego.parameters(), before))


def test_state_reads_are_copies() -> None:
    ego = stack()
    state = ego.task_state(0)
    state["pi_out.0.bias"] += 1.0
    assert not torch.equal(ego.task_state(0)["pi_out.0.bias"], state["pi_out.0.bias"])


def test_each_replica_explores_from_its_own_seeded_generator() -> None:
    ego = stack(sample_seeds=(5, 6))
    draws = [torch.rand(3, generator=g) for g in ego.samplers]
    assert torch.equal(draws[0], torch.rand(3, generator=torch.Generator().manual_seed(5)))
    assert torch.equal(draws[1], torch.rand(3, generator=torch.Generator().manual_seed(6)))


def test_gradients_reach_only_the_replica_that_produced_the_loss() -> None:
    ego = stack()
    out = ego.task_forward(rows(), None)
    head_out = ego.head_outputs(out.z)
    (ego.policy_logits(head_out[1, 2], out.logits[1], None).sum() + out.value[1].sum()).backward()
    for p in ego.task_parameters():
        assert p.grad[0].abs().sum() == 0 and p.grad[1].abs().sum() > 0
    for p in ego.head_parameters()[:6]:  # the policy layers of the heads
        assert p.grad[1, 2].abs().sum() > 0
        assert p.grad[0].abs().sum() == 0 and p.grad[1, :2].abs().sum() == 0


def test_the_stack_has_no_forward_of_its_own() -> None:
    with pytest.raises(RuntimeError, match="no agent of its own"):
        stack()._forward({})


def test_pad_rows_and_unpad_round_trip() -> None:
    parts = [torch.tensor([[1.0, 2.0]]), torch.tensor([[3.0, 4.0], [5.0, 6.0], [7.0, 8.0]]), torch.zeros(0, 2)]
    padded, sizes = pad_rows(parts)
    assert sizes == [1, 3, 0]
    assert torch.equal(
        padded, torch.tensor([[[1.0, 2.0], [0, 0], [0, 0]], [[3.0, 4.0], [5.0, 6.0], [7.0, 8.0]], [[0, 0], [0, 0], [0, 0]]])
    )
    for got, want in zip(unpad(padded, sizes), parts):
        assert torch.equal(got, want)
